// Test helper for the headset page under IWER (window.__device): move the emulated hands until the
// page, reading them back through its WebXR session, sees the fingertips where a test wants them.
"use strict";
window.drive = (function () {
  const { THREE } = PM3;
  const device = window.__device;
  const wait = (ms) => new Promise((resolve) => setTimeout(resolve, ms));
  const V3 = (a) => new THREE.Vector3(...a);

  function seen(handedness) {
    const tips = window.pinchmatchXR.tips().filter(Boolean);
    return tips.find((t) => t.handedness === handedness) || null;
  }

  async function settle() {
    await wait(120); // a few of the session's frames
  }

  // move the whole hand by a room-space offset (metres)
  async function shift(handedness, offset) {
    const hand = device.hands[handedness];
    hand.position.set(hand.position.x + offset[0], hand.position.y + offset[1], hand.position.z + offset[2]);
    await settle();
  }

  // put the index fingertip of a hand at a point (metres)
  async function touch(handedness, point) {
    for (let k = 0; k < 3; k++) {
      const t = seen(handedness);
      await shift(handedness, V3(point).sub(V3(t.index)).toArray());
    }
    return seen(handedness);
  }

  // put the thumb tip on a and the index tip on b: the pinch opens to |b - a|, turns to b - a, then moves
  async function pinch(handedness, a, b) {
    const hand = device.hands[handedness];
    const width = V3(b).distanceTo(V3(a));
    let lo = 0, hi = 1;
    for (let k = 0; k < 12; k++) { // the thumb-index distance falls as the pinch value rises
      const mid = (lo + hi) / 2;
      hand.updatePinchValue(mid);
      await settle();
      const t = seen(handedness);
      if (V3(t.index).distanceTo(V3(t.thumb)) > width) lo = mid; else hi = mid;
    }
    for (let k = 0; k < 4; k++) {
      const t = seen(handedness);
      const turn = new THREE.Quaternion().setFromUnitVectors(
        V3(t.index).sub(V3(t.thumb)).normalize(), V3(b).sub(V3(a)).normalize());
      const q = new THREE.Quaternion(hand.quaternion.x, hand.quaternion.y, hand.quaternion.z, hand.quaternion.w);
      q.premultiply(turn);
      hand.quaternion.set(q.x, q.y, q.z, q.w);
      await settle();
      const u = seen(handedness);
      await shift(handedness, V3(a).sub(V3(u.thumb)).toArray());
    }
    return seen(handedness);
  }

  // the hand pose configs (relaxed, pinch, point) the emulator interpolates a hand's joints between
  function poseConfigs(hand) {
    for (const key of Object.getOwnPropertySymbols(hand)) {
      if (hand[key] && hand[key].poses) return Object.values(hand[key].poses);
    }
    throw new Error("no hand pose configs on the emulated hand");
  }

  // a tripod: thumb tip on a and index tip on b (as pinch), then the middle fingertip moved onto c by
  // moving that joint in every pose config (the joints' offsets are in the hand's frame, the right hand's
  // mirrored in x)
  async function tripod(handedness, a, b, c) {
    await pinch(handedness, a, b);
    const hand = device.hands[handedness];
    for (let k = 0; k < 3; k++) {
      const t = seen(handedness);
      const q = new THREE.Quaternion(hand.quaternion.x, hand.quaternion.y, hand.quaternion.z, hand.quaternion.w);
      const d = V3(c).sub(V3(t.middle)).applyQuaternion(q.invert());
      if (handedness === "right") d.x = -d.x;
      for (const pose of poseConfigs(hand)) {
        const m = pose.jointTransforms["middle-finger-tip"].offsetMatrix;
        m[12] += d.x; m[13] += d.y; m[14] += d.z;
      }
      await settle();
    }
    return seen(handedness);
  }

  // turn a hand by deg about an axis through a point (metres)
  async function turnAbout(handedness, point, axis, deg) {
    const hand = device.hands[handedness];
    const turn = new THREE.Quaternion().setFromAxisAngle(V3(axis).normalize(), (deg * Math.PI) / 180);
    const q = new THREE.Quaternion(hand.quaternion.x, hand.quaternion.y, hand.quaternion.z, hand.quaternion.w);
    q.premultiply(turn);
    hand.quaternion.set(q.x, q.y, q.z, q.w);
    const p = V3([hand.position.x, hand.position.y, hand.position.z]).sub(V3(point)).applyQuaternion(turn).add(V3(point));
    hand.position.set(p.x, p.y, p.z);
    await settle();
    return seen(handedness);
  }

  // the headset's pose: where it is and the point it looks at
  function look(from, at) {
    device.position.set(...from);
    const m = new THREE.Matrix4().lookAt(V3(from), V3(at), new THREE.Vector3(0, 1, 0));
    const q = new THREE.Quaternion().setFromRotationMatrix(m);
    device.quaternion.set(q.x, q.y, q.z, q.w);
  }

  return { seen, shift, touch, pinch, tripod, turnAbout, look, wait };
})();
