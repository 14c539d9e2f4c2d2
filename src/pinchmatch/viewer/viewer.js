// pinchmatch viewer: the matches of one run, each as its glTF scene (the tangible, the registered
// virtual object and the fingertip cones), plus the two poses side by side in their own frames.
// Everything it needs is inlined in the page: three.js as the global PM3, the data as JSON.
"use strict";
(function () {
  const { THREE, GLTFLoader, OrbitControls } = PM3;
  const DATA = JSON.parse(document.getElementById("pinchmatch-data").textContent);
  const CONE_HEIGHT_M = 0.02, CONE_RADIUS_M = 0.005;
  const VIEW_DIRECTION = new THREE.Vector3(0.9, 0.55, 1.3).normalize();

  // One canvas, its renderer, camera and orbit controls; renders on demand.
  class View {
    constructor(canvas) {
      this.canvas = canvas;
      this.renderer = new THREE.WebGLRenderer({ canvas, antialias: true });
      this.renderer.setPixelRatio(Math.min(window.devicePixelRatio || 1, 2));
      this.scene = new THREE.Scene();
      this.scene.background = new THREE.Color(0xeef1f5);
      this.scene.add(new THREE.HemisphereLight(0xffffff, 0x8d949e, 2.0));
      const sun = new THREE.DirectionalLight(0xffffff, 1.6);
      sun.position.set(1, 2, 1.5);
      this.scene.add(sun);
      this.content = new THREE.Group();
      this.scene.add(this.content);
      this.camera = new THREE.PerspectiveCamera(35, 1, 0.001, 100);
      this.controls = new OrbitControls(this.camera, canvas);
      this.controls.addEventListener("change", () => this.render());
      new ResizeObserver(() => this.resize()).observe(canvas);
    }

    resize() {
      if (this.renderer.xr.isPresenting) return; // the headset sizes its own views
      const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
      if (w === 0 || h === 0) return;
      this.renderer.setSize(w, h, false);
      this.camera.aspect = w / h;
      this.camera.updateProjectionMatrix();
      this.render();
    }

    // Replace the content and frame it: the camera looks at the bounding sphere from the front-right.
    show(objects) {
      this.content.clear();
      for (const o of objects) this.content.add(o);
      const box = new THREE.Box3().setFromObject(this.content);
      const sphere = box.getBoundingSphere(new THREE.Sphere());
      const grid = new THREE.GridHelper(sphere.radius * 3, 12, 0xb6bcc6, 0xd3d8df);
      grid.position.set(sphere.center.x, box.min.y, sphere.center.z);
      this.content.add(grid);
      const distance = sphere.radius / Math.sin(THREE.MathUtils.degToRad(this.camera.fov / 2)) * 1.15;
      this.camera.position.copy(sphere.center).addScaledVector(VIEW_DIRECTION, distance);
      this.camera.near = distance / 100;
      this.camera.far = distance * 10;
      this.controls.target.copy(sphere.center);
      this.controls.update();
      this.resize();
    }

    render() {
      if (this.renderer.xr.isPresenting) return; // the headset draws its own scene (immersive.js)
      this.renderer.render(this.scene, this.camera);
    }
  }

  const views = {
    main: new View(document.getElementById("canvas-main")),
    tangible: new View(document.getElementById("canvas-tangible")),
    virtual: new View(document.getElementById("canvas-virtual")),
  };

  function decodeBase64(text) {
    const bytes = Uint8Array.from(atob(text), (c) => c.charCodeAt(0));
    return bytes.buffer;
  }

  const loader = new GLTFLoader();
  const loaded = new Map();
  function loadScene(index) {
    if (!loaded.has(index)) {
      loaded.set(index, new Promise((resolve, reject) =>
        loader.parse(decodeBase64(DATA.matches[index].glb_base64), "", resolve, reject)));
    }
    return loaded.get(index);
  }

  // A fingertip cone like the scene's: tip on the contact, pointing along `toward`, body outside.
  function cone(material, contact, toward) {
    const geometry = new THREE.ConeGeometry(CONE_RADIUS_M, CONE_HEIGHT_M, 24);
    geometry.translate(0, -CONE_HEIGHT_M / 2, 0); // tip at the origin, body along -Y
    const mesh = new THREE.Mesh(geometry, material);
    mesh.quaternion.setFromUnitVectors(new THREE.Vector3(0, 1, 0), toward);
    mesh.position.copy(contact);
    return mesh;
  }

  // A cone on each contact, each closing as the scene's: the first (p1, the thumb) towards the others'
  // middle, each other towards the first.
  function fingertipCones(material, contacts) {
    const middle = contacts.slice(1).reduce((a, q) => a.add(q), new THREE.Vector3()).divideScalar(contacts.length - 1);
    return contacts.map((q, k) => cone(material, q,
      (k === 0 ? middle.clone().sub(q) : contacts[0].clone().sub(q)).normalize()));
  }

  // The scene's objects for the three views; `up`, the virtual object's up in its own file (x, y, z), stands
  // it upright in its own view whatever the prop's up (the scene's frame is the prop's, turned to glTF's +Y).
  function parts(gltf, up) {
    const root = gltf.scene;
    const get = (name) => {
      const node = root.getObjectByName(name);
      if (!node) throw new Error(`scene has no node '${name}'`);
      return node;
    };
    const tangible = get("tangible"), virtual = get("virtual");
    // a cone per fingertip: a pinch's two, a tripod's three (thumb, index, middle)
    const cones = [get("cone_p1"), get("cone_p2")];
    if (root.getObjectByName("cone_p3")) cones.push(get("cone_p3"));
    // the hand model's finger capsules, where the pose has an approach (older scenes have none)
    const fingers = cones.map((_, k) => root.getObjectByName(`finger_p${k + 1}`)).filter(Boolean);
    const C = new THREE.Matrix4().fromArray(root.userData["pinchmatch:file_mm_to_gltf_m"]).transpose();
    const p = virtual.userData["pinchmatch:virtual_contacts_mm"];
    const upright = new THREE.Matrix4();
    if (up) {
      const seen = new THREE.Vector3(...up).transformDirection(C);
      upright.makeRotationFromQuaternion(new THREE.Quaternion().setFromUnitVectors(seen, new THREE.Vector3(0, 1, 0)));
    }
    const contacts = cones.map((_, k) => new THREE.Vector3(p[3 * k], p[3 * k + 1], p[3 * k + 2])
      .applyMatrix4(C).applyMatrix4(upright));
    const ownVirtual = virtual.clone(); // in its own frame, standing on its own up, and opaque there
    ownVirtual.matrix.copy(upright);
    ownVirtual.matrix.decompose(ownVirtual.position, ownVirtual.quaternion, ownVirtual.scale);
    ownVirtual.material = virtual.material.clone();
    Object.assign(ownVirtual.material, { transparent: false, opacity: 1, depthWrite: true });
    const green = cones[0].material;
    return {
      main: [root],
      tangible: [tangible.clone(), ...cones.map((c) => c.clone()), ...fingers.map((f) => f.clone())],
      virtual: [ownVirtual, ...fingertipCones(green, contacts)],
      virtualNode: virtual, tangibleNode: tangible, cones, fingers, root, C, green,
      bestMatrix: virtual.matrix.clone(),
    };
  }

  // Numbers for people: 3 significant digits, no exponent below 0.001 but "< 0.001", 0 as 0.
  function fmt(x, digits = 3) {
    if (x === null || x === undefined) return "null";
    if (x === 0) return "0";
    if (Math.abs(x) < 0.001) return "< 0.001";
    return String(Number(Number(x).toPrecision(digits)));
  }
  const escape = (text) => String(text).replace(/[&<>"']/g, (c) => `&#${c.charCodeAt(0)};`);
  // a name that may break after _ - . / and before a capital following a lower-case letter, not mid-word
  const breakable = (text) => escape(text).replace(/([_\-./])/g, "$1<wbr>").replace(/([a-z])([A-Z])/g, "$1<wbr>$2");
  const turned = (m) => m.up_turn_deg === null || m.up_turn_deg === undefined ? (m.flipped ? "flipped" : "upright")
    : m.up_turn_deg < 1 ? "upright"
    : `turned ${m.up_turn_deg.toFixed(0)}° from upright` + (m.flipped ? " (flipped: beyond 90°)" : "");

  // where the object shown on a standing prop is against the prop's table (within 2 mm it rests)
  const rests = (gap) => Math.abs(gap) <= 2 ? `resting on the table (${gap.toFixed(1)} mm)`
    : gap < 0 ? `<b>${(-gap).toFixed(1)} mm into the table</b>` : `<b>${gap.toFixed(1)} mm above the table</b>`;

  // the landing tolerance's words (xr_core.js, which the page loads before this)
  const landingNote = (m) => PinchmatchXR.landingNote(m);

  // the pooled row's band: the chance of being noticed on target, and up to the worst landing
  function landingRow(m) {
    const landed = landingNote(m);
    if (!landed) return "";
    // the band inside the bar, at least half a percent wide, never past its end
    const lo = Math.min(100 * (m.p_noticed || 0), 99.5);
    const hi = Math.min(Math.max(100 * m.landing.p_noticed_worst, lo + 0.5), 100);
    return `<tr class="pooled"><th>landing</th><td>${landed.worst_percent} %</td>` +
      `<td><div class="jnd-bar" title="${escape(landed.text)}"><span class="${m.noticeable ? "loud" : ""}" ` +
      `style="width:${lo}%"></span><b class="band ${landed.word}" style="left:${lo}%;width:${hi - lo}%"></b>` +
      `<i style="left:50%"></i></div></td><td title="cost ${fmt(m.landing.cost_mean)} expected, ` +
      `${fmt(m.landing.cost_worst)} worst over ${fmt(m.landing.landings)} landings ${fmt(m.landing.radius_mm)} mm off">` +
      `${escape(landed.word)}</td></tr>` +
      `<tr class="felt"><th>felt</th><td colspan="3">cost ${fmt(m.landing.cost_nominal)} on target, ` +
      `${fmt(m.landing.cost_mean)} expected, ${fmt(m.landing.cost_worst)} at the worst landing</td></tr>`;
  }

  // Under --placement fixed: how the object is served. redirect: it stays in the level and the hand is led
  // to the prop (the angle seen from the hand's start, the reach gain); carousel: it is brought onto the prop.
  function placementNote(m) {
    const r = m.redirection;
    if (!r) return null;
    const costs = r.redirect_cost === null || r.redirect_cost === undefined
      ? `nothing within the redirection budget; carousel ${fmt(r.carousel_cost)}`
      : `redirect ${fmt(r.redirect_cost)}, carousel ${fmt(r.carousel_cost)}`;
    if (r.mode === "redirect") {
      return { mode: "redirect", badge: `redirect ${r.angle_deg.toFixed(1)}° ×${r.gain.toFixed(2)}`,
        title: `${m.virtual} stays in the level; the hand is led to ${m.tangible}`,
        text: `stays in the level: the hand is redirected by ${r.angle_deg.toFixed(2)}° (reach gain ${r.gain.toFixed(3)}, ` +
          `offset ${r.offset_mm.toFixed(0)} mm); ${costs}`,
        reason: r.reason || "" };
    }
    return { mode: "carousel", badge: "carousel", title: `${m.virtual} brought onto ${m.tangible} (carousel)`,
      text: `the carousel brings it onto the prop; ${costs}`, reason: r.reason || "" };
  }

  function loudCriteria(match) {
    return match.criteria.filter((c) => c.noticeable);
  }

  function listEntries() {
    const list = document.getElementById("matches");
    DATA.matches.forEach((m, index) => {
      const li = document.createElement("li");
      li.className = "match";
      li.dataset.index = index;
      const loud = loudCriteria(m);
      const badges = [`<span class="badge">cost ${fmt(m.cost)}</span>`];
      if (m.p_noticed !== null && m.p_noticed !== undefined) {
        badges.push(`<span class="badge ${m.noticeable ? "loud" : "quiet"}" title="the probability that the difference is noticed">` +
          `noticed ${(100 * m.p_noticed).toFixed(0)} %</span>`);
      }
      badges.push(loud.length
        ? loud.map((c) => `<span class="badge loud">${escape(c.name)} ${c.jnd.toFixed(1)} JND</span>`).join("")
        : (m.noticeable ? "" : `<span class="badge quiet">nothing noticeable</span>`));
      const landed = landingNote(m);
      if (landed) {
        badges.push(`<span class="badge ${landed.word === "steady" ? "quiet" : "loud"}" title="${escape(landed.text)}">` +
          `${landed.word}</span>`);
      }
      if (m.flipped) badges.push(`<span class="badge flip" title="${escape(turned(m))}">F</span>`);
      if ((m.equivalent_tangibles || []).length) {
        badges.push(`<span class="badge equivalent" title="served as well (within 0.1 JND or 5 %) by ` +
          `${escape(m.equivalent_tangibles.map((e) => `${e.tangible} (${fmt(e.cost)})`).join(", "))}">` +
          `≈ ${escape(m.equivalent_tangibles.map((e) => e.tangible).join(", "))}</span>`);
      }
      const mode = placementNote(m);
      if (mode) badges.push(`<span class="badge mode ${mode.mode}" title="${escape(mode.reason)}">${escape(mode.badge)}</span>`);
      li.innerHTML = `<div class="names">${breakable(m.virtual)} <span class="arrow">→</span> ${breakable(m.tangible)}</div>` +
        `<div class="meta">${badges.join("")}</div>`;
      li.dataset.name = `${m.virtual} ${m.tangible}`.toLowerCase();
      li.dataset.cost = m.cost;
      li.dataset.noticeable = m.noticeable ? "1" : "0";
      li.addEventListener("click", () => select(index));
      list.appendChild(li);
    });
    for (const f of DATA.failed || []) {
      const li = document.createElement("li");
      li.className = "failed";
      li.innerHTML = `<div class="names">${breakable(f.name)}</div><div class="meta">failed: ${escape(f.error)}</div>`;
      li.dataset.name = String(f.name).toLowerCase();
      li.dataset.cost = Infinity;
      li.dataset.noticeable = "0";
      list.appendChild(li);
    }
    for (const u of DATA.unmatched) {
      const li = document.createElement("li");
      li.className = "unmatched";
      li.innerHTML = `<div class="names">${breakable(u.virtual)}</div><div class="meta">no tangible: ${escape(u.reason || "")}</div>`;
      li.dataset.name = String(u.virtual).toLowerCase();
      li.dataset.cost = Infinity;
      li.dataset.noticeable = "0";
      list.appendChild(li);
    }
  }

  // Filter by name and sort; the counts say how many are shown and how many are noticeable.
  function arrange() {
    const list = document.getElementById("matches");
    const text = document.getElementById("filter").value.trim().toLowerCase();
    const order = document.getElementById("sort").value;
    const items = [...list.children];
    const key = (li) => order === "cost" ? Number(li.dataset.cost)
      : order === "-cost" ? -Number(li.dataset.cost)
      : order === "noticeable" ? -Number(li.dataset.noticeable) : 0;
    items.sort((a, b) => (key(a) - key(b)) || (Number(a.dataset.order) - Number(b.dataset.order)));
    let shown = 0, loud = 0;
    for (const li of items) {
      li.hidden = text !== "" && !li.dataset.name.includes(text);
      if (!li.hidden) { shown += 1; loud += Number(li.dataset.noticeable); }
      list.appendChild(li);
    }
    document.getElementById("counts").textContent =
      `${shown} of ${items.length} shown; ${loud} of them with a noticeable difference`;
  }

  function details(m) {
    const rows = m.criteria.map((c) => {
      const width = Math.min(c.jnd / 3, 1) * 100;
      return `<tr><th>${escape(c.name)}</th><td>${c.jnd.toFixed(2)} JND</td>` +
        `<td><div class="jnd-bar"><span class="${c.noticeable ? "loud" : ""}" style="width:${width}%"></span>` +
        `<i style="left:33.3%"></i></div></td><td>weight ${fmt(c.weight)}</td></tr>`;
    }).join("") + (m.p_noticed === null || m.p_noticed === undefined ? "" :
      `<tr class="pooled"><th>noticed</th><td>${(100 * m.p_noticed).toFixed(0)} %</td>` +
      `<td><div class="jnd-bar"><span class="${m.noticeable ? "loud" : ""}" style="width:${100 * m.p_noticed}%"></span>` +
      `<i style="left:50%"></i></div></td><td>all criteria pooled</td></tr>`) + landingRow(m);
    const mode = placementNote(m);
    const facts = [
      `<b>${escape(m.virtual)}</b> on <b>${escape(m.tangible)}</b>`,
      ...(mode ? [`<span class="mode-fact" title="${escape(mode.reason)}">${escape(mode.text)}</span>`] : []),
      ...((m.equivalent_tangibles || []).length ? [`as well served by ` +
        m.equivalent_tangibles.map((e) => `<b>${escape(e.tangible)}</b> (cost ${fmt(e.cost)})`).join(", ")] : []),
      `cost ${fmt(m.cost, 4)}`,
      m.reference_cost === null || m.reference_cost === undefined
        ? `reference: none (${escape(m.reference_reason || "no reference pose")})`
        : `reference cost ${fmt(m.reference_cost, 4)}`,
      `pinch width ${m.tangible_width_mm.toFixed(1)} mm on the tangible, ${m.virtual_width_mm.toFixed(1)} mm on the virtual object`,
      `contact offset ${m.contact_offset_mm.toFixed(2)} mm`,
      turned(m),
      ...(m.rest_gap_mm === null || m.rest_gap_mm === undefined ? [] : [rests(m.rest_gap_mm)]),
      `position ${m.position_mm.map((x) => x.toFixed(1)).join(", ")} mm`,
    ];
    const choices = [`<button data-choice="-1" class="on">best, cost ${fmt(m.cost)}</button>`].concat(
      m.alternatives.map((a, k) => a.tangible === m.tangible
        ? `<button data-choice="${k}">alternative ${k + 1}, cost ${fmt(a.cost)}</button>`
        : `<button data-choice="${k}" disabled title="on ${escape(a.tangible)}, whose scene is not this one">` +
          `alternative ${k + 1} on ${breakable(a.tangible)}, cost ${fmt(a.cost)}</button>`));
    document.getElementById("details").innerHTML =
      `<div class="facts">${facts.map((f) => `<span>${f}</span>`).join("")}</div>` +
      `<div id="choices">${choices.join("")}</div><table>${rows}</table>`;
    document.querySelectorAll("#choices button").forEach((b) =>
      b.addEventListener("click", () => choose(Number(b.dataset.choice))));
  }

  // Show the best placement (k = -1) or alternative k on the same tangible: the virtual node gets
  // C·T·C⁻¹ (docs/engines.md) and the cones move to the alternative's contacts.
  let shownParts = null, extraCones = [];
  function choose(k) {
    const m = DATA.matches[current], p = shownParts;
    if (!p) return;
    for (const c of extraCones) c.removeFromParent();
    extraCones = [];
    const alt = k >= 0 ? m.alternatives[k] : null;
    if (alt) {
      const T = new THREE.Matrix4().fromArray(alt.transform).transpose();
      const M = p.C.clone().multiply(T).multiply(p.C.clone().invert());
      p.virtualNode.matrix.copy(M);
      extraCones = fingertipCones(p.green, alt.contacts_mm.map((q) => new THREE.Vector3(...q).applyMatrix4(p.C)));
      for (const c of extraCones) p.root.add(c);
    } else {
      p.virtualNode.matrix.copy(p.bestMatrix);
    }
    p.virtualNode.matrix.decompose(p.virtualNode.position, p.virtualNode.quaternion, p.virtualNode.scale);
    for (const c of [...p.cones, ...p.fingers]) c.visible = !alt;
    document.querySelectorAll("#choices button").forEach((b) =>
      b.classList.toggle("on", Number(b.dataset.choice) === k));
    document.body.dataset.choice = alt ? `alternative ${k + 1}` : "best";
    views.main.render();
  }

  function setPropTransparent(on) {
    document.getElementById("toggle-prop-transparent").checked = on;
    if (shownParts) {
      shownParts.tangibleNode.traverse((o) => {
        if (!o.isMesh) return;
        if (!o.userData.opaqueMaterial) { o.userData.opaqueMaterial = o.material; o.material = o.material.clone(); }
        Object.assign(o.material, on ? { transparent: true, opacity: 0.3, depthWrite: false }
          : { transparent: o.userData.opaqueMaterial.transparent, opacity: o.userData.opaqueMaterial.opacity,
              depthWrite: o.userData.opaqueMaterial.depthWrite });
        o.material.needsUpdate = true;
      });
    }
    document.body.dataset.propOpacity = on ? "0.3" : "1";
    views.main.render();
  }

  let current = -1, virtualNode = null;
  async function select(index) {
    current = index;
    document.querySelectorAll("#matches li.match").forEach((li) =>
      li.classList.toggle("selected", Number(li.dataset.index) === index));
    const m = DATA.matches[index];
    details(m);
    const mode = placementNote(m);
    document.getElementById("main-title").textContent = mode ? mode.title : `${m.virtual} registered on ${m.tangible}`;
    document.getElementById("tangible-title").textContent = `tangible pose: ${m.tangible} (its frame)`;
    document.getElementById("virtual-title").textContent = `virtual pose: ${m.virtual} (its frame)`;
    const gltf = await loadScene(index);
    if (current !== index) return; // another entry was clicked meanwhile
    const p = parts(gltf, m.virtual_up);
    virtualNode = p.virtualNode;
    virtualNode.visible = document.getElementById("toggle-virtual").checked;
    shownParts = p;
    views.main.show(p.main);
    views.tangible.show(p.tangible);
    views.virtual.show(p.virtual);
    choose(-1);
    setPropTransparent(document.getElementById("toggle-prop-transparent").checked);
    history.replaceState(null, "", `#${encodeURIComponent(m.virtual)}`);
    document.body.dataset.shown = String(index);
  }

  function setVirtualVisible(visible) {
    document.getElementById("toggle-virtual").checked = visible;
    if (virtualNode) virtualNode.visible = visible;
    views.main.render();
  }

  document.getElementById("toggle-virtual").addEventListener("change", (e) => setVirtualVisible(e.target.checked));
  document.getElementById("toggle-prop-transparent").addEventListener("change", (e) => setPropTransparent(e.target.checked));
  document.getElementById("filter").addEventListener("input", arrange);
  document.getElementById("sort").addEventListener("change", arrange);
  window.addEventListener("keydown", (e) => {
    if (e.target instanceof HTMLInputElement && e.target.type === "search") return; // typing a filter
    if (e.key === "v" || e.key === "V") setVirtualVisible(!document.getElementById("toggle-virtual").checked);
    if (e.key === "t" || e.key === "T") setPropTransparent(!document.getElementById("toggle-prop-transparent").checked);
    if ((e.key === "ArrowDown" || e.key === "ArrowUp") && DATA.matches.length) {
      const step = e.key === "ArrowDown" ? 1 : -1;
      select((current + step + DATA.matches.length) % DATA.matches.length);
      e.preventDefault();
    }
  });

  // what the headset mode (immersive.js) builds on
  window.pinchmatchViewer = { DATA, view: views.main, views, loadScene, cone, fingertipCones, current: () => current,
    select };

  document.getElementById("summary").textContent = DATA.summary;
  listEntries();
  [...document.getElementById("matches").children].forEach((li, k) => { li.dataset.order = k; });
  arrange();
  if (DATA.matches.length) {
    const wanted = decodeURIComponent(location.hash.slice(1));
    const start = Math.max(0, DATA.matches.findIndex((m) => m.virtual === wanted));
    select(start).catch((error) => console.error(error));
  } else {
    document.getElementById("details").textContent = "No virtual object was matched.";
  }
})();
