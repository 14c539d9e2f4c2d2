// pinchmatch in the headset: WebXR immersive mode of the viewer page, with tracked hands.
// 1. calibrate: touch the marked points of the prop with an index fingertip; a rigid fit gives its pose;
// 2. guide: the registered virtual object on the prop, the two green target cones, the fingertips as small
//    spheres; a pinch is validated as in the method's study (both fingertips within pos_mm, the direction
//    within angle_deg, held for hold_s), and the object turns green;
// 3. study: the page's study plan, trial by trial, each ended by a 7-point rating pressed with a fingertip,
//    the results downloadable as CSV (docs/study.md).
// The pure logic lives in xr_core.js (PinchmatchXR). A page without WebXR shows nothing of this.
"use strict";
(function () {
  const { THREE } = PM3;
  const XR = PinchmatchXR;
  const V = window.pinchmatchViewer;
  const DATA = V.DATA;
  const renderer = V.view.renderer;
  const TIP_RADIUS_M = 0.004, MARKER_RADIUS_M = 0.005, BUTTON_SIZE_M = 0.03, BUTTON_PRESS_M = 0.018;
  const LIFT_M = 0.08; // the dynamic task: lift this high, then put the prop back
  const NEXT_MATCH_S = 3; // outside a study, the next match is guided this long after a validation
  const GREEN = 0x2fbf4f, BLUE = 0x3f7fff;
  // where the prop is shown before it is calibrated: in front of a standing user, on a table
  const DEFAULT_PROP_POSE = new THREE.Matrix4().makeTranslation(0, 0.9, -0.4);
  const CSV_COLUMNS = ["trial", "participant", "pair", "object", "pose_source", "repetition", "rating",
    "time_to_validation_s", "thumb_error_mm", "index_error_mm", "angle_error_deg", "cost",
    ...["width", "com", "tilt", "normal", "axis", "kmax", "kmin", "mass"].map((c) => `${c}_jnd`),
    "pos_mm", "angle_deg", "hold_s", "lift"];

  const $ = (id) => document.getElementById(id);
  const query = XR.limitsFromQuery(location.search);
  const limits = { ...query.limits };
  const state = {
    phase: "idle", // idle | calibrating | guiding | lifting | rating | done
    status: "", calibration: null, marks: [], touched: [], held_s: 0, validated: false, check: null,
    trial: -1, results: [], study: false, lift: false, errors: query.errors.slice(),
  };

  function say(text) {
    state.status = text;
    $("xr-status").textContent = text;
    if (panel) panel.draw(text);
  }

  // ---- the scene drawn in the headset ----------------------------------------------------------------
  const scene = new THREE.Scene();
  scene.background = new THREE.Color(0x20242b);
  scene.add(new THREE.HemisphereLight(0xffffff, 0x50555e, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(0.5, 2, 1);
  scene.add(sun);
  const floor = new THREE.GridHelper(4, 40, 0x5a616c, 0x3a3f47);
  scene.add(floor);
  const propFrame = new THREE.Group(); // the prop's frame (the glTF scenes' frame, metres, Y up) in the room
  propFrame.matrixAutoUpdate = false;
  propFrame.matrix.copy(DEFAULT_PROP_POSE);
  scene.add(propFrame);
  const content = new THREE.Group();
  propFrame.add(content);

  const tipMaterial = new THREE.MeshStandardMaterial({ color: 0xf2d5b8, roughness: 0.6 });
  const hands = [0, 1].map((i) => {
    const hand = renderer.xr.getHand(i);
    hand.addEventListener("connected", (e) => { hand.userData.handedness = e.data && e.data.handedness; });
    scene.add(hand);
    const tips = { thumb: new THREE.Mesh(new THREE.SphereGeometry(TIP_RADIUS_M, 16, 12), tipMaterial),
                   index: new THREE.Mesh(new THREE.SphereGeometry(TIP_RADIUS_M, 16, 12), tipMaterial),
                   middle: new THREE.Mesh(new THREE.SphereGeometry(TIP_RADIUS_M, 16, 12), tipMaterial) };
    scene.add(tips.thumb, tips.index, tips.middle);
    return { hand, tips };
  });

  // A text panel floating above the prop: what to do next.
  class Panel {
    constructor() {
      this.canvas = document.createElement("canvas");
      this.canvas.width = 1024;
      this.canvas.height = 256;
      this.texture = new THREE.CanvasTexture(this.canvas);
      this.mesh = new THREE.Mesh(new THREE.PlaneGeometry(0.4, 0.1),
        new THREE.MeshBasicMaterial({ map: this.texture, transparent: true }));
      scene.add(this.mesh);
    }

    // above the prop, facing the viewer
    place(viewer) {
      this.mesh.position.setFromMatrixPosition(propFrame.matrix).add(new THREE.Vector3(0, 0.24, 0));
      this.mesh.lookAt(viewer);
    }

    draw(text) {
      const g = this.canvas.getContext("2d");
      g.clearRect(0, 0, 1024, 256);
      g.fillStyle = "rgba(20, 24, 30, 0.85)";
      g.fillRect(0, 0, 1024, 256);
      g.fillStyle = "#ffffff";
      g.font = "40px sans-serif";
      const words = String(text).split(" ");
      let line = "", y = 60;
      for (const w of words) {
        if (g.measureText(line + w).width > 960) { g.fillText(line, 32, y); line = ""; y += 52; }
        line += w + " ";
      }
      g.fillText(line, 32, y);
      this.texture.needsUpdate = true;
    }
  }
  const panel = new Panel();

  // ---- what is shown: a match of the page, or a pair of the study plan ----------------------------------
  let shown = null; // { root, virtual, cones, C, targets (a pinch's two, a tripod's three; prop frame, metres), material }

  function matrixRows(rows) {
    return new THREE.Matrix4().set(...rows.flat());
  }

  async function show(matchIndex, pair) {
    const gltf = await V.loadScene(matchIndex);
    const root = gltf.scene.clone(true);
    const C = new THREE.Matrix4().fromArray(root.userData["pinchmatch:file_mm_to_gltf_m"]).transpose();
    const get = (name) => root.getObjectByName(name);
    const virtual = get("virtual"), tangible = get("tangible");
    const cones = ["cone_p1", "cone_p2", "cone_p3"].map(get).filter(Boolean); // a tripod's three
    tangible.visible = false; // the hand feels the real prop; the eye sees the virtual object
    const material = virtual.material.clone();
    Object.assign(material, { transparent: false, opacity: 1, depthWrite: true });
    virtual.material = material;
    let targets;
    if (pair) { // the pair's placement and its fingertip targets on the prop
      virtual.matrix.copy(C.clone().multiply(matrixRows(pair.transform_virtual_to_tangible)).multiply(C.clone().invert()));
      virtual.matrix.decompose(virtual.position, virtual.quaternion, virtual.scale);
      targets = (pair.tangible_contacts_mm || [pair.tangible_p1_mm, pair.tangible_p2_mm])
        .map((q) => new THREE.Vector3(...q).applyMatrix4(C));
      const material = cones[0].material;
      cones.forEach((c) => c.removeFromParent());
      cones.splice(0, cones.length, ...V.fingertipCones(material, targets));
      cones.forEach((c) => root.add(c));
      for (const name of ["finger_p1", "finger_p2", "finger_p3"]) { const f = get(name); if (f) f.visible = false; }
    } else {
      targets = cones.map((c) => new THREE.Vector3(...contactOf(root, c.name)));
    }
    content.clear();
    content.add(root);
    shown = { root, virtual, cones, C, targets, material, baseColor: material.color.clone() };
    return shown;
  }

  // a cone node's contact point (its tip) in the scene's frame
  function contactOf(root, name) {
    const node = root.getObjectByName(name);
    const C = new THREE.Matrix4().fromArray(root.userData["pinchmatch:file_mm_to_gltf_m"]).transpose();
    const mm = node.userData["pinchmatch:contact_mm"];
    return new THREE.Vector3(mm[0], mm[1], mm[2]).applyMatrix4(C).toArray();
  }

  function targetsInRoom() {
    propFrame.updateMatrixWorld(true);
    return shown.targets.map((q) => q.clone().applyMatrix4(propFrame.matrix).toArray());
  }

  function paint(color) {
    if (!shown) return;
    if (color === null) shown.material.color.copy(shown.baseColor);
    else shown.material.color.set(color);
  }

  // ---- fingertips ---------------------------------------------------------------------------------
  function tips() {
    return hands.map(({ hand, tips: spheres }) => {
      const j = hand.joints || {};
      const thumb = j["thumb-tip"], index = j["index-finger-tip"], middle = j["middle-finger-tip"];
      const ok = thumb && index && thumb.visible && index.visible;
      spheres.thumb.visible = spheres.index.visible = Boolean(ok);
      const tripod = Boolean(ok && shown && shown.targets.length === 3 && middle && middle.visible);
      spheres.middle.visible = tripod;
      if (!ok) return null;
      spheres.thumb.position.copy(thumb.position);
      spheres.index.position.copy(index.position);
      if (tripod) spheres.middle.position.copy(middle.position);
      return { handedness: hand.userData.handedness || null, thumb: thumb.position.toArray(),
               middle: middle && middle.visible ? middle.position.toArray() : null,
               index: index.position.toArray() };
    });
  }

  // ---- calibration --------------------------------------------------------------------------------
  const storeKey = () => `pinchmatch.calibration.${DATA.matches.length ? DATA.matches[0].tangible : "prop"}`;
  let touches = [], touchPrimed = false, markers = [];

  function markedPoints(root) {
    const tangible = root.getObjectByName("tangible");
    const positions = [];
    tangible.updateMatrixWorld(true);
    root.updateMatrixWorld(true);
    const toRoot = root.matrixWorld.clone().invert().multiply(tangible.matrixWorld);
    tangible.traverse((o) => {
      if (!o.isMesh) return;
      const a = o.geometry.getAttribute("position"), v = new THREE.Vector3();
      for (let i = 0; i < a.count; i++) positions.push(...v.fromBufferAttribute(a, i).applyMatrix4(toRoot).toArray());
    });
    return XR.calibrationPoints(positions, 4);
  }

  function startCalibration() {
    const root = shown.root;
    state.marks = markedPoints(root);
    state.touched = [];
    state.phase = "calibrating";
    touches = hands.map(() => new XR.SteadyTouch({ radius_mm: 3, hold_s: 1, away_mm: 20 }));
    touchPrimed = false;
    propFrame.matrix.copy(DEFAULT_PROP_POSE);
    root.getObjectByName("tangible").visible = true; // a preview of the prop, to show where to touch
    shown.virtual.visible = false;
    shown.cones.forEach((c) => { c.visible = false; });
    markers.forEach((m) => m.removeFromParent());
    markers = state.marks.map((p) => {
      const m = new THREE.Mesh(new THREE.SphereGeometry(MARKER_RADIUS_M, 16, 12),
        new THREE.MeshBasicMaterial({ color: 0x9aa3ad }));
      m.position.set(...p);
      content.add(m);
      return m;
    });
    nextMark();
  }

  function nextMark() {
    const k = state.touched.length;
    markers.forEach((m, i) => {
      m.material.color.set(i === k ? 0xffd400 : i < k ? GREEN : 0x9aa3ad);
      m.scale.setScalar(i === k ? 1.8 : 1);
    });
    say(`Calibration: touch the yellow point (${k + 1} of ${state.marks.length}) on the real prop with an index ` +
        "fingertip and hold still for 1 s.");
  }

  // either hand's index fingertip touches; a hand resting where it was when calibration began, or
  // where it touched last, touches nothing until it moves
  function calibrationStep(t, seen) {
    if (!touchPrimed && seen.some(Boolean)) {
      seen.forEach((h, i) => { if (h) touches[i].ignoreUntilMovedFrom(h.index); });
      touchPrimed = true;
    }
    const point = seen.map((h, i) => (h ? touches[i].update(h.index, t) : null)).find(Boolean);
    if (!point) return;
    state.touched.push(point);
    if (state.touched.length < state.marks.length) return nextMark();
    const fit = XR.rigidFit(state.marks, state.touched);
    if (!XR.spreadOk(state.marks) || !(fit.rms_mm <= XR.MAX_CALIBRATION_RMS_MM)) {
      state.calibration = { refused: true, rms_mm: fit.rms_mm };
      state.touched = [];
      say(`Calibration refused: the touches are ${fit.rms_mm.toFixed(1)} mm from the prop's shape (rms; at most ` +
          `${XR.MAX_CALIBRATION_RMS_MM} mm). Touch the points again, in order.`);
      touches.forEach((touch, i) => { if (seen[i]) touch.ignoreUntilMovedFrom(seen[i].index); });
      setTimeout(nextMark, 2500);
      return;
    }
    state.calibration = { refused: false, rms_mm: fit.rms_mm, max_mm: fit.max_mm, matrix: fit.matrix,
                          date: new Date().toISOString() };
    try { localStorage.setItem(storeKey(), JSON.stringify(state.calibration)); } catch (e) { /* private mode */ }
    markers.forEach((m) => m.removeFromParent());
    markers = [];
    applyCalibration();
    say(`Calibrated: residual ${fit.rms_mm.toFixed(1)} mm rms, ${fit.max_mm.toFixed(1)} mm at most.`);
    setTimeout(() => begin(), 1500);
  }

  function applyCalibration() {
    propFrame.matrix.fromArray(state.calibration.matrix);
    if (shown) shown.root.getObjectByName("tangible").visible = false;
  }

  function storedCalibration() {
    try {
      const c = JSON.parse(localStorage.getItem(storeKey()) || "null");
      return c && !c.refused && Array.isArray(c.matrix) && c.matrix.length === 16 ? c : null;
    } catch (e) {
      return null;
    }
  }

  // ---- the level around the user (scene mode, scene_xr.js), or one match at a time ----------------
  let sceneXR = null;

  async function begin() {
    if (!sceneXR) return beginGuiding();
    if (state.calibration && !state.calibration.refused) applyCalibration();
    content.clear(); // the level shows every object; the single match's scene goes
    state.phase = "scene";
    await sceneXR.begin();
  }

  function sceneStep(t, seen) {
    const drawn = sceneXR.step(t, seen);
    drawn.forEach((h, i) => {
      if (!h) return;
      hands[i].tips.thumb.position.set(...h.thumb);
      hands[i].tips.index.position.set(...h.index);
    });
  }

  // ---- guiding, validation, lifting and rating -----------------------------------------------------
  const hold = new XR.HoldTimer(limits.hold_s);
  let trialStart = 0, validation = null, liftBase = null, liftHand = 0, lifted = false, buttons = [];
  let pressReady = false;

  async function beginGuiding() {
    if (state.study) {
      const trial = DATA.study.trials[state.trial];
      const pair = DATA.study.pairs[trial.pair];
      await show(DATA.matches.findIndex((m) => m.virtual === pair.virtual), pair);
      say(`Trial ${trial.trial} of ${trialCount()}: pinch the object where the green cones show.`);
    } else {
      await show(Math.max(V.current(), 0), null);
      const match = DATA.matches[Math.max(V.current(), 0)];
      const note = XR.landingNote(match);
      say(`Pinch ${match.virtual} where the green cones show.` + (note ? ` This match is ${note.text}.` : ""));
    }
    if (state.calibration && !state.calibration.refused) applyCalibration();
    hold.hold_s = limits.hold_s;
    hold.reset();
    state.validated = false;
    validation = null;
    state.validation = null;
    trialStart = lastTime;
    state.phase = "guiding";
  }

  function guideStep(t, seen) {
    const targets = targetsInRoom();
    const worst = (c) => Math.max(c.thumb_error_mm, c.index_error_mm, c.middle_error_mm || 0);
    let best = null;
    seen.forEach((h, i) => {
      if (!h || (targets.length === 3 && !h.middle)) return;
      const c = XR.checkGrasp(h, targets, limits);
      if (!best || worst(c) < worst(best)) {
        best = { ...c, hand: h, handIndex: i };
      }
    });
    state.check = best;
    state.held_s = hold.update(Boolean(best && best.ok), t);
    if (!hold.validated) return;
    state.validated = true;
    validation = { time_s: t - trialStart, ...best };
    state.validation = { ...validation, hand: undefined, handIndex: undefined };
    if (!state.study) { // then the page's next match, so that every object can be tried in one session
      paint(GREEN);
      const next = (Math.max(V.current(), 0) + 1) % DATA.matches.length;
      const middle = best.middle_error_mm === undefined ? "" : `, middle ${best.middle_error_mm.toFixed(1)} mm`;
      say(`Validated in ${validation.time_s.toFixed(2)} s: thumb ${best.thumb_error_mm.toFixed(1)} mm, index ` +
          `${best.index_error_mm.toFixed(1)} mm${middle} and ${best.angle_error_deg.toFixed(1)} degrees off the targets.` +
          (DATA.matches.length > 1 ? ` Next: ${DATA.matches[next].virtual}.` : ""));
      state.phase = "done";
      if (DATA.matches.length > 1) {
        setTimeout(() => {
          if (!session || state.phase !== "done") return;
          V.select(next).catch(() => {});
          beginGuiding();
        }, NEXT_MATCH_S * 1000);
      }
      return;
    }
    if (state.lift) {
      paint(BLUE);
      liftBase = best.hand.index[1];
      liftHand = best.handIndex;
      lifted = false;
      state.phase = "lifting";
      say("Validated: lift the object about 10 cm, tilt it, and put it back.");
    } else {
      paint(GREEN);
      setTimeout(askRating, 600);
      state.phase = "wait";
    }
  }

  // the hand that pinched lifts the prop LIFT_M and puts it back (within 2 cm of where it was)
  function liftStep(seen) {
    const h = seen[liftHand];
    if (!h) return;
    const rise = h.index[1] - liftBase;
    if (rise > LIFT_M) lifted = true;
    if (lifted && rise < 0.02) {
      paint(GREEN);
      askRating();
    }
  }

  function askRating() {
    state.phase = "rating";
    pressReady = false;
    buttons.forEach((b) => b.removeFromParent());
    const question = DATA.study.question;
    say(`${question} Press a number with a fingertip: 1 (${DATA.study.scale.labels[0]}) to 7 (${DATA.study.scale.labels[1]}).`);
    const targets = targetsInRoom();
    const centre = targets.reduce((a, q) => a.add(new THREE.Vector3(...q)), new THREE.Vector3()).multiplyScalar(1 / targets.length);
    buttons = [1, 2, 3, 4, 5, 6, 7].map((value, k) => {
      const canvas = document.createElement("canvas");
      canvas.width = canvas.height = 64;
      const g = canvas.getContext("2d");
      g.fillStyle = "#2b6cb0";
      g.fillRect(0, 0, 64, 64);
      g.fillStyle = "#fff";
      g.font = "bold 44px sans-serif";
      g.textAlign = "center";
      g.fillText(String(value), 32, 48);
      const b = new THREE.Mesh(new THREE.BoxGeometry(BUTTON_SIZE_M, BUTTON_SIZE_M, 0.01),
        new THREE.MeshBasicMaterial({ map: new THREE.CanvasTexture(canvas) }));
      b.position.set(centre.x + (k - 3) * (BUTTON_SIZE_M * 1.5), centre.y + 0.2, centre.z);
      b.userData.value = value;
      scene.add(b);
      return b;
    });
  }

  function ratingStep(seen) {
    const points = seen.filter(Boolean).flatMap((h) => [h.index, h.thumb]).map((p) => new THREE.Vector3(...p));
    const near = (b) => points.some((p) => p.distanceTo(b.position) < BUTTON_PRESS_M);
    if (!pressReady) { pressReady = !buttons.some(near); return; } // first, every fingertip off the buttons
    const pressed = buttons.find(near);
    if (pressed) record(pressed.userData.value);
  }

  function record(rating) {
    const trial = DATA.study.trials[state.trial];
    const pair = DATA.study.pairs[trial.pair];
    const row = {
      trial: trial.trial, participant: $("participant").value.trim() || "P1", pair: trial.pair,
      object: pair.virtual, pose_source: pair.pose_source, repetition: trial.repetition, rating,
      time_to_validation_s: validation.time_s, thumb_error_mm: validation.thumb_error_mm,
      index_error_mm: validation.index_error_mm, angle_error_deg: validation.angle_error_deg, cost: pair.cost,
      pos_mm: limits.pos_mm, angle_deg: limits.angle_deg, hold_s: limits.hold_s, lift: state.lift ? 1 : 0,
    };
    for (const [c, v] of Object.entries(pair.criteria_jnd)) row[`${c}_jnd`] = v;
    state.results.push(row);
    $("download-csv").disabled = false;
    buttons.forEach((b) => b.removeFromParent());
    buttons = [];
    state.trial += 1;
    if (state.trial >= trialCount()) {
      state.phase = "done";
      say(`Study complete: ${state.results.length} trials. Take the headset off and download the results.`);
      setTimeout(() => { if (session) session.end(); }, 3000); // back to the page, where the CSV is
      return;
    }
    beginGuiding();
  }

  // ?trials=N runs the plan's first N trials (practice, or a short session)
  function trialCount() {
    const n = Number(new URLSearchParams(location.search).get("trials"));
    return Number.isInteger(n) && n > 0 ? Math.min(n, DATA.study.trials.length) : DATA.study.trials.length;
  }

  function csv() {
    return XR.toCSV(state.results, CSV_COLUMNS);
  }

  // ---- the session --------------------------------------------------------------------------------
  let session = null, lastTime = 0;

  function frame(time) {
    lastTime = time / 1000;
    const seen = tips();
    if (state.phase === "calibrating") calibrationStep(lastTime, seen);
    else if (state.phase === "guiding") guideStep(lastTime, seen);
    else if (state.phase === "lifting") liftStep(seen);
    else if (state.phase === "rating") ratingStep(seen);
    else if (state.phase === "scene") sceneStep(lastTime, seen);
    const camera = renderer.xr.getCamera();
    panel.place(new THREE.Vector3().setFromMatrixPosition(camera.matrixWorld));
    renderer.render(scene, camera);
  }

  async function enter() {
    readSettings();
    session = await navigator.xr.requestSession("immersive-vr",
      { requiredFeatures: ["local-floor"], optionalFeatures: ["hand-tracking"] });
    renderer.xr.enabled = true;
    renderer.xr.setReferenceSpaceType("local-floor");
    await renderer.xr.setSession(session);
    document.body.dataset.xr = "presenting";
    session.addEventListener("end", () => {
      renderer.setAnimationLoop(null);
      renderer.xr.enabled = false;
      session = null;
      state.phase = "idle";
      document.body.dataset.xr = "ready";
      V.view.resize();
    });
    state.study = $("study-mode").checked && Boolean(DATA.study);
    sceneXR = !state.study && PinchmatchScene.wanted()
      ? PinchmatchScene.create({ scene, propFrame, say, limits }) : null;
    if (sceneXR) window.pinchmatchXR.scene = sceneXR.hooks;
    state.lift = $("lift").checked;
    if (state.study) { state.trial = 0; state.results = []; }
    await show(state.study ? DATA.matches.findIndex((m) => m.virtual === DATA.study.pairs[DATA.study.trials[0].pair].virtual)
      : Math.max(V.current(), 0), null);
    renderer.setAnimationLoop(frame);
    const stored = storedCalibration();
    if (stored && !forceCalibration) {
      state.calibration = stored;
      say(`Using the stored calibration (${stored.rms_mm.toFixed(1)} mm rms, ${stored.date}).`);
      begin();
    } else {
      startCalibration();
    }
  }

  let forceCalibration = false;

  function readSettings() {
    for (const [id, key] of [["pos-mm", "pos_mm"], ["angle-deg", "angle_deg"], ["hold-s", "hold_s"]]) {
      const value = Number($(id).value);
      if (Number.isFinite(value) && value > 0) limits[key] = value;
      else $(id).value = limits[key];
    }
  }

  async function setup() {
    if (!navigator.xr) return;
    let supported = false;
    try { supported = await navigator.xr.isSessionSupported("immersive-vr"); } catch (e) { supported = false; }
    if (!supported || !DATA.matches.length) return;
    $("xr").hidden = false;
    document.body.dataset.xr = "ready";
    $("pos-mm").value = limits.pos_mm;
    $("angle-deg").value = limits.angle_deg;
    $("hold-s").value = limits.hold_s;
    if (DATA.scene) {
      $("scene-row").hidden = false;
      $("scene-mode").checked = new URLSearchParams(location.search).get("mode") === "scene";
    }
    if (DATA.study) {
      $("study-row").hidden = false;
      $("study-count").textContent = String(trialCount()) + (DATA.study.left_out
        ? ` (the trials of ${DATA.study.left_out.join(", ")} left out: no match on this page)` : "");
    }
    $("enter-vr").addEventListener("click", () => enter().catch((e) => say(`Could not enter VR: ${e.message || e}`)));
    $("recalibrate").addEventListener("click", () => {
      forceCalibration = true;
      try { localStorage.removeItem(storeKey()); } catch (e) { /* private mode */ }
      if (session) startCalibration();
      say("The next session starts with a calibration.");
    });
    $("download-csv").addEventListener("click", () => {
      const a = document.createElement("a");
      a.href = URL.createObjectURL(new Blob([csv()], { type: "text/csv" }));
      a.download = `pinchmatch-study-${$("participant").value.trim() || "P1"}.csv`;
      a.click();
    });
    say(query.errors.length ? query.errors.join("; ") : "Ready: put the headset on and enter VR.");
  }

  // for tests and for scripts driving the page
  window.pinchmatchXR = {
    state: () => ({ ...state, check: state.check && { ...state.check, hand: undefined } }),
    limits, csv, targets: () => (shown ? targetsInRoom() : null), marks: () => state.marks,
    propMatrix: () => propFrame.matrix.toArray(), tips,
    buttons: () => buttons.map((b) => ({ value: b.userData.value, position: b.position.toArray() })),
  };
  setup();
  // without a headset, ?mode=scene previews the scene mode in the main view once the page has shown its entry
  if (DATA.scene && new URLSearchParams(location.search).get("mode") === "scene" && DATA.matches.length) {
    const wait = () => (document.body.dataset.shown === undefined ? setTimeout(wait, 50)
      : PinchmatchScene.preview().catch((e) => console.error(e)));
    wait();
  }
})();
