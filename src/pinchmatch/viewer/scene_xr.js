// pinchmatch in the headset, scene mode (index.html?mode=scene, or the page's "scene" box): the whole
// level around the user, one prop on the real table (calibrated by touch as in the other modes).
// - `redirect` matches: the virtual object stays where the level puts it; while the hand reaches from its
//   start to the physical pinch, the rendered fingertips are offset a little more with every centimetre
//   (body warping), so that they land on the virtual pinch when the real ones land on the prop;
// - `carousel` matches: the objects wait on a carousel beside the prop; a fingertip on its button turns it,
//   and the next object comes onto the prop, registered;
// - the green cones and the validation (pos_mm, angle_deg, hold_s) are on the virtual targets, as the
//   warped fingertips see them.
// The pure logic (the warp, the level's frame, the carousel's order) lives in xr_core.js.
"use strict";
window.PinchmatchScene = (function () {
  const { THREE } = PM3;
  const XR = PinchmatchXR;
  const V = window.pinchmatchViewer;
  const DATA = V.DATA;
  const GREEN = 0x2fbf4f;
  const CAROUSEL_CENTRE_M = [0.3, 0, 0]; // beside the prop, in the prop's scene frame
  const CAROUSEL_RADIUS_M = 0.12, BUTTON_SIZE_M = 0.04, BUTTON_PRESS_M = 0.02, NEXT_TASK_S = 2;
  const CAROUSEL_GAP_M = 0.02; // between neighbours on the carousel's ring
  const TABLE_MARGIN_M = 0.15, TABLE_THICKNESS_M = 0.01; // the drawn table: beyond the prop and the ring, its slab
  const rows = (r) => new THREE.Matrix4().set(...r);
  const mm = (p) => new THREE.Vector3(...p).multiplyScalar(0.001);

  const wanted = () => Boolean(DATA.scene) && (new URLSearchParams(location.search).get("mode") === "scene" ||
    Boolean(document.getElementById("scene-mode") && document.getElementById("scene-mode").checked));

  // api: { scene, propFrame, say, limits } of the immersive page
  function create(api) {
    const level = new THREE.Group(); // the level's frame (metres, y up), inside the prop's scene frame
    level.matrixAutoUpdate = false;
    const carousel = new THREE.Group(); // the carousel, beside the prop
    carousel.position.set(...CAROUSEL_CENTRE_M);
    const onProp = new THREE.Group(); // the carousel's object on the prop, registered
    api.propFrame.add(level, carousel, onProp);
    const cones = new THREE.Group();
    const coneMaterial = new THREE.MeshStandardMaterial({ color: GREEN });
    const button = new THREE.Mesh(new THREE.BoxGeometry(BUTTON_SIZE_M, BUTTON_SIZE_M / 2, BUTTON_SIZE_M),
      new THREE.MeshStandardMaterial({ color: 0xffb020 }));
    button.position.set(CAROUSEL_CENTRE_M[0], 0.02, CAROUSEL_CENTRE_M[2] + CAROUSEL_RADIUS_M + 0.06);
    api.propFrame.add(button);
    const hold = new XR.HoldTimer(api.limits.hold_s);
    // the matches on the prop of the page's first redirected match: the one prop calibrated in the room
    const prop = (DATA.matches.find((m) => m.redirection) || {}).tangible;
    const queue = XR.carouselQueue(DATA.matches).filter((i) => DATA.matches[i].tangible === prop);
    const st = { phase: "idle", task: -1, on_prop: null, carousel_turns: 0, held_s: 0, validated: false, check: null,
                 ratio: 0, offset_mm: [0, 0, 0], rendered: [], real: [] };
    let objects = new Map(), pressReady = false, nextAt = null, ring = { radius: CAROUSEL_RADIUS_M, angles: [] };

    const tasks = () => DATA.matches.flatMap((m, i) => (m.redirection && m.tangible === prop ? [i] : []));
    const room = (local, group) => { api.propFrame.updateMatrixWorld(true); return local.clone().applyMatrix4(group.matrixWorld); };

    // every object of the level: redirected ones in place, carousel ones on the carousel
    async function build() {
      const first = await V.loadScene(tasks()[0]);
      const C = first.scene.userData["pinchmatch:file_mm_to_gltf_m"];
      const pose = DATA.matches[tasks()[0]].prop_pose || null;
      level.matrix.copy(rows(XR.levelToProp(C, pose)));
      for (const i of tasks()) {
        const root = (await V.loadScene(i)).scene.clone(true);
        const virtual = root.getObjectByName("virtual");
        const material = virtual.material.clone();
        Object.assign(material, { transparent: false, opacity: 1, depthWrite: true });
        virtual.material = material;
        const registered = virtual.matrix.clone();
        virtual.removeFromParent();
        // the scenes keep each virtual file's points turned as the prop's file is (Q); the level undoes it
        const Q = new THREE.Matrix4().fromArray(root.userData["pinchmatch:file_mm_to_gltf_m"]).transpose();
        const unturn = new THREE.Matrix4().extractRotation(Q).invert();
        const o = { index: i, virtual, registered, unturn, material, base: material.color.clone(),
                    mode: DATA.matches[i].redirection.mode, root };
        if (o.mode === "redirect") placeInLevel(o);
        objects.set(i, o);
      }
      ring = XR.carouselRing(queue.map((i) => footprint(objects.get(i))), CAROUSEL_RADIUS_M, CAROUSEL_GAP_M);
      carousel.position.set(CAROUSEL_CENTRE_M[0] + ring.radius - CAROUSEL_RADIUS_M, 0, CAROUSEL_CENTRE_M[2]);
      button.position.set(carousel.position.x, 0.02, carousel.position.z + ring.radius + 0.06);
      queue.forEach((i, k) => placeOnCarousel(objects.get(i), k));
      atPropSpot();
      addTable();
    }

    // the table the prop stands on, its top at the prop's lowest point, under the prop and the carousel's ring:
    // what the prop brings is seen resting on it, as the prop rests on the real table
    function addTable() {
      const first = objects.get(tasks()[0]);
      const tangible = first && first.root.getObjectByName("tangible");
      if (!tangible) return;
      tangible.geometry.computeBoundingBox();
      const b = tangible.geometry.boundingBox.clone().applyMatrix4(tangible.matrix);
      const low = Math.min(b.min.x, carousel.position.x - ring.radius) - TABLE_MARGIN_M;
      const high = Math.max(b.max.x, carousel.position.x + ring.radius) + TABLE_MARGIN_M;
      const back = Math.min(b.min.z, carousel.position.z - ring.radius) - TABLE_MARGIN_M;
      const front = Math.max(b.max.z, button.position.z) + TABLE_MARGIN_M;
      const top = new THREE.Mesh(new THREE.BoxGeometry(high - low, TABLE_THICKNESS_M, front - back),
        new THREE.MeshStandardMaterial({ color: 0xc8b69a, transparent: true, opacity: 0.55, depthWrite: false }));
      top.name = "pinchmatch_table";
      top.position.set((low + high) / 2, b.min.y - TABLE_THICKNESS_M / 2, (back + front) / 2);
      api.propFrame.add(top);
    }

    // an object's footprint as registered on the prop: {x, z} the middle of its box, r its half diagonal (m)
    function footprint(o) {
      o.virtual.geometry.computeBoundingBox();
      const box = o.virtual.geometry.boundingBox.clone().applyMatrix4(o.registered);
      const c = box.getCenter(new THREE.Vector3()), size = box.getSize(new THREE.Vector3());
      return { x: c.x, z: c.z, r: 0.5 * Math.hypot(size.x, size.z) };
    }

    // the level's objects standing where the prop stands: hidden while another object is on the prop
    function atPropSpot() {
      const first = objects.get(tasks()[0]);
      const tangible = first && first.root.getObjectByName("tangible");
      if (!tangible) return;
      api.propFrame.updateMatrixWorld(true);
      tangible.geometry.computeBoundingBox();
      const prop = tangible.geometry.boundingBox.clone().applyMatrix4(api.propFrame.matrixWorld);
      objects.forEach((o) => {
        if (o.mode !== "redirect") return;
        const box = new THREE.Box3().setFromObject(o.virtual);
        o.atProp = box.max.x > prop.min.x && box.min.x < prop.max.x && box.max.z > prop.min.z && box.min.z < prop.max.z;
      });
    }

    function showAtProp(shown) {
      objects.forEach((o) => { if (o.atProp) o.virtual.visible = shown; });
    }

    // the object on the prop goes back to the carousel: the level's own object there shows again
    function clearProp() {
      if (st.on_prop === null) return;
      placeOnCarousel(objects.get(st.on_prop), queue.indexOf(st.on_prop));
      st.on_prop = null;
      showAtProp(true);
    }

    function placeInLevel(o) {
      o.virtual.matrix.copy(o.unturn);
      o.virtual.matrix.decompose(o.virtual.position, o.virtual.quaternion, o.virtual.scale);
      level.add(o.virtual);
    }

    // on the ring, its footprint's middle at its place: neighbours never touch (XR.carouselRing)
    function placeOnCarousel(o, k) {
      const a = ring.angles[k] || 0, f = footprint(o);
      o.virtual.matrix.copy(o.registered);
      o.virtual.matrix.decompose(o.virtual.position, o.virtual.quaternion, o.virtual.scale);
      o.virtual.position.add(new THREE.Vector3(Math.cos(a) * ring.radius - f.x, 0, Math.sin(a) * ring.radius - f.z));
      o.virtual.visible = true;
      carousel.add(o.virtual);
    }

    // the carousel turns: its next object comes onto the prop, registered; the one there goes back
    function turnCarousel() {
      if (!queue.length) return;
      const k = st.on_prop === null ? 0 : (queue.indexOf(st.on_prop) + 1) % queue.length;
      if (st.on_prop !== null) placeOnCarousel(objects.get(st.on_prop), queue.indexOf(st.on_prop));
      const o = objects.get(queue[k]);
      o.virtual.matrix.copy(o.registered);
      o.virtual.matrix.decompose(o.virtual.position, o.virtual.quaternion, o.virtual.scale);
      onProp.add(o.virtual);
      st.on_prop = queue[k];
      st.carousel_turns += 1;
      showAtProp(false);
    }

    // the current task's targets in the room: [virtual p1, p2], [physical p1, p2] (a tripod's three each), the
    // hand's start
    function targets() {
      const m = DATA.matches[tasks()[st.task]];
      const o = objects.get(tasks()[st.task]);
      const C = new THREE.Matrix4().fromArray(o.root.userData["pinchmatch:file_mm_to_gltf_m"]).transpose();
      const physical = ["cone_p1", "cone_p2", "cone_p3"].map((n) => o.root.getObjectByName(n)).filter(Boolean).map((c) =>
        room(new THREE.Vector3(...c.userData["pinchmatch:contact_mm"]).applyMatrix4(C), api.propFrame));
      if (m.redirection.mode === "carousel") return { virtual: physical, physical, start: null };
      const virtual = (m.virtual_contacts_mm || [m.virtual_p1_mm, m.virtual_p2_mm]).map((p) => room(mm(p), level));
      return { virtual, physical, start: room(mm(m.redirection.hand_start_mm), level) };
    }

    function aim() {
      cones.clear();
      cones.removeFromParent();
      const t = targets();
      const u = t.virtual[1].clone().sub(t.virtual[0]).normalize();
      cones.add(V.cone(coneMaterial, t.virtual[0], u), V.cone(coneMaterial, t.virtual[1], u.clone().negate()));
      api.scene.add(cones); // in room coordinates
      hold.hold_s = api.limits.hold_s;
      hold.reset();
      Object.assign(st, { validated: false, held_s: 0, check: null });
    }

    async function begin() {
      if (!objects.size) await build();
      st.phase = "scene";
      go(0);
    }

    function go(k) {
      st.task = k;
      objects.forEach((o) => o.material.color.copy(o.base));
      const m = DATA.matches[tasks()[k]];
      nextAt = null;
      if (m.redirection.mode === "redirect" && objects.get(tasks()[k]).atProp) clearProp(); // it stands there itself
      if (m.redirection.mode === "carousel" && st.on_prop !== tasks()[k]) {
        cones.clear();
        api.say(onPropNote() + `${m.virtual} is on the carousel: press the orange button with a fingertip until ` +
                `it comes onto the prop (${m.tangible}).`);
      } else {
        aim();
        api.say(onPropNote() + `Pinch ${m.virtual} where the green cones show` +
                (m.redirection.mode === "redirect" ? `: it stays in place, your hand is led to the prop (${m.tangible}).`
                  : ` (the prop ${m.tangible}).`));
      }
    }

    const onPropNote = () => (st.on_prop === null ? "" : `On the prop: ${DATA.matches[st.on_prop].virtual}. `);

    // one frame: seen = the real fingertips ([{thumb, index}] per hand, room metres); returns what to draw
    function step(t, seen) {
      const m = DATA.matches[tasks()[st.task]];
      const real = seen.map((h) => (h ? { ...h } : null));
      let rendered = real;
      if (m.redirection.mode === "redirect" && cones.children.length) {
        const tg = targets();
        const start = tg.start.toArray();
        // the grasp's middle: a pinch's midpoint, a tripod's centroid (the targets' and the fingertips')
        const centroid = (ps) => ps.reduce((a, q) => a.add(q), new THREE.Vector3()).multiplyScalar(1 / ps.length).toArray();
        const physical = centroid(tg.physical), virtual = centroid(tg.virtual);
        rendered = real.map((h) => {
          if (!h) return null;
          const tips = [h.thumb, h.index, ...(tg.physical.length === 3 && h.middle ? [h.middle] : [])];
          const mid = centroid(tips.map((p) => new THREE.Vector3(...p)));
          const d = XR.warpOffset(start, physical, virtual, mid);
          st.ratio = XR.warpRatio(start, physical, mid);
          st.offset_mm = d.map((x) => x * 1000);
          const moved = (p) => (p ? p.map((x, k) => x + d[k]) : p);
          return { ...h, thumb: moved(h.thumb), index: moved(h.index), middle: moved(h.middle) };
        });
      }
      st.real = real;
      st.rendered = rendered;
      pressStep(real);
      if (cones.children.length && !st.validated) validateStep(t, rendered);
      if (nextAt !== null && t >= nextAt) go((st.task + 1) % tasks().length);
      return rendered;
    }

    function pressStep(real) {
      const b = room(new THREE.Vector3(), button);
      const near = real.some((h) => h && [h.index, h.thumb].some((p) => new THREE.Vector3(...p).distanceTo(b) < BUTTON_PRESS_M));
      if (!near) { pressReady = true; return; }
      if (!pressReady) return;
      pressReady = false;
      turnCarousel();
      const m = DATA.matches[tasks()[st.task]];
      if (m.redirection.mode === "carousel" && st.on_prop === tasks()[st.task]) go(st.task);
      else api.say(onPropNote() + `Turn on until ${m.virtual} comes onto the prop.`);
    }

    function validateStep(t, rendered) {
      const tg = targets();
      let best = null;
      const worst = (c) => Math.max(c.thumb_error_mm, c.index_error_mm, c.middle_error_mm || 0);
      rendered.forEach((h) => {
        if (!h || (tg.virtual.length === 3 && !h.middle)) return;
        const c = XR.checkGrasp(h, tg.virtual.map((q) => q.toArray()), api.limits);
        if (!best || worst(c) < worst(best)) best = c;
      });
      st.check = best;
      st.held_s = hold.update(Boolean(best && best.ok), t);
      if (!hold.validated) return;
      st.validated = true;
      const o = objects.get(tasks()[st.task]);
      o.material.color.set(GREEN);
      api.say(`Validated: ${DATA.matches[o.index].virtual}, ${best.thumb_error_mm.toFixed(1)} and ` +
              `${best.index_error_mm.toFixed(1)} mm off the targets. Next in ${NEXT_TASK_S} s.`);
      nextAt = t + NEXT_TASK_S;
    }

    const hooks = {
      state: () => ({ ...st, tasks: tasks(), queue }),
      go: (k) => go(k),
      targets: () => { const t = targets(); return { virtual: t.virtual.map((v) => v.toArray()),
        physical: t.physical.map((v) => v.toArray()), start: t.start && t.start.toArray() }; },
      button: () => room(new THREE.Vector3(), button).toArray(),
      turn: () => turnCarousel(),
      visible: (i) => objects.get(i).virtual.visible,
      atProp: (i) => Boolean(objects.get(i).atProp),
      table: () => { const t = api.propFrame.getObjectByName("pinchmatch_table"); if (!t) return null;
        t.updateMatrixWorld(true); const b = new THREE.Box3().setFromObject(t); return [b.min.toArray(), b.max.toArray()]; },
      boxInRoom: (i) => { const b = new THREE.Box3().setFromObject(objects.get(i).virtual); return [b.min.toArray(), b.max.toArray()]; },
      objectInRoom: (i) => { const o = objects.get(i); o.virtual.updateMatrixWorld(true); return o.virtual.matrixWorld.toArray(); },
      registeredInRoom: (i) => { const o = objects.get(i); api.propFrame.updateMatrixWorld(true);
        return api.propFrame.matrixWorld.clone().multiply(o.registered).toArray(); },
    };
    return { begin, step, hooks };
  }

  // On a desktop (index.html?mode=scene, no headset needed): the scene mode's level in the main view, as the
  // headset shows it around the prop (the prop at the room's origin, unturned): the redirected objects in
  // place, the carousel's on their ring, the first task's cones. Its hooks: pinchmatchXR.preview.
  async function preview() {
    const root = new THREE.Group();
    const frame = new THREE.Group();
    frame.matrixAutoUpdate = false;
    root.add(frame);
    const title = document.getElementById("main-title");
    const api = { scene: root, propFrame: frame, limits: XR.DEFAULT_LIMITS,
                  say: (text) => { title.textContent = `scene preview (as the headset shows it): ${text}`; } };
    const s = create(api);
    await s.begin();
    const first = await V.loadScene(s.hooks.state().tasks[0]);
    const tangible = first.scene.getObjectByName("tangible");
    if (tangible) frame.add(tangible.clone());
    V.view.show([root]);
    window.pinchmatchXR = Object.assign(window.pinchmatchXR || {}, { preview: s.hooks });
    document.body.dataset.preview = "scene";
    return s;
  }

  return { wanted, create, preview };
})();
