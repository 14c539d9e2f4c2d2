// The immersive page's pure logic, as the page runs it: node --test tests/js/
import { test } from "node:test";
import assert from "node:assert/strict";
import { createRequire } from "node:module";

const require = createRequire(import.meta.url);
const XR = require("../../src/pinchmatch/viewer/xr_core.js");

const mm = (v) => v.map((x) => x / 1000);
const P1 = mm([10, 50, 0]), P2 = mm([-30, 50, 0]); // a 40 mm pinch along -x

// a point `d_mm` from p, moved along the unit vector u
const off = (p, u, d_mm) => p.map((x, k) => x + (u[k] * d_mm) / 1000);
// rotate v about z by deg
const turnZ = (v, deg) => {
  const a = (deg * Math.PI) / 180;
  return [v[0] * Math.cos(a) - v[1] * Math.sin(a), v[0] * Math.sin(a) + v[1] * Math.cos(a), v[2]];
};

test("on target: both fingertips on their targets, in either order", () => {
  assert.equal(XR.checkPinch(P1, P2, P1, P2).ok, true);
  const swapped = XR.checkPinch(P2, P1, P1, P2);
  assert.equal(swapped.ok, true);
  assert.equal(swapped.order, "thumb on p2");
  assert.ok(swapped.angle_error_deg < 1e-6);
});

test("a fingertip 4.9 mm off passes, 5.1 mm or 6 mm off fails", () => {
  const up = [0, 0, 1];
  assert.equal(XR.checkPinch(off(P1, up, 4.9), off(P2, up, 4.9), P1, P2).ok, true);
  assert.equal(XR.checkPinch(off(P1, up, 5.1), P2, P1, P2).ok, false);
  const six = XR.checkPinch(P1, off(P2, up, 6), P1, P2);
  assert.equal(six.ok, false);
  assert.ok(Math.abs(six.index_error_mm - 6) < 1e-9);
});

test("the direction: 13 degrees passes, 15 degrees fails, with the fingertips kept near the targets", () => {
  // the pinch turned about its midpoint; a 15 degree turn moves each fingertip more than 5 mm, so the
  // position limit is loosened here and the angle alone decides
  const mid = P1.map((x, k) => (x + P2[k]) / 2);
  const half = P1.map((x, k) => x - mid[k]);
  for (const [deg, ok] of [[13, true], [15, false]]) {
    const h = turnZ(half, deg);
    const thumb = mid.map((x, k) => x + h[k]), index = mid.map((x, k) => x - h[k]);
    const r = XR.checkPinch(thumb, index, P1, P2, { pos_mm: 50, angle_deg: 14, hold_s: 1 });
    assert.ok(Math.abs(r.angle_error_deg - deg) < 1e-6, r.angle_error_deg);
    assert.equal(r.ok, ok, `${deg} degrees`);
  }
});

test("a tripod: thumb on the first target, index and middle on the others in either order, each within 5 mm", () => {
  const T = [[0.1, 1.0, -0.3], [0.16, 1.01, -0.31], [0.155, 0.99, -0.28]];
  const on = XR.checkGrasp({ thumb: T[0], index: T[1], middle: T[2] }, T);
  assert.equal(on.ok, true);
  const crossed = XR.checkGrasp({ thumb: T[0], index: T[2], middle: T[1] }, T);
  assert.equal(crossed.ok, true);
  assert.equal(crossed.order, "index on the third target");
  const up = [0, 0, 1];
  assert.equal(XR.checkGrasp({ thumb: T[0], index: T[1], middle: off(T[2], up, 4.9) }, T).ok, true);
  const six = XR.checkGrasp({ thumb: T[0], index: T[1], middle: off(T[2], up, 6) }, T);
  assert.equal(six.ok, false);
  assert.ok(Math.abs(six.middle_error_mm - 6) < 1e-9);
  // the thumb where a finger belongs: no order puts every fingertip on a target
  assert.equal(XR.checkGrasp({ thumb: T[1], index: T[0], middle: T[2] }, T).ok, false);
  // two targets are a pinch, judged as checkPinch judges it
  assert.deepEqual(XR.checkGrasp({ thumb: T[1], index: T[0] }, T.slice(0, 2)), XR.checkPinch(T[1], T[0], T[0], T[1]));
});

test("the hold: validated after 1 s on target without a break, not before", () => {
  const h = new XR.HoldTimer(1);
  assert.equal(h.update(true, 10.0), 0);
  h.update(true, 10.5);
  assert.equal(h.validated, false);
  h.update(false, 10.6); // a break restarts the count
  h.update(true, 10.7);
  h.update(true, 11.69);
  assert.equal(h.validated, false);
  h.update(true, 11.7);
  assert.equal(h.validated, true);
  assert.equal(h.validatedAt, 11.7);
  h.update(false, 12); // stays validated until reset
  assert.equal(h.validated, true);
  h.reset();
  assert.equal(h.validated, false);
});

test("thresholds from the URL: numbers taken, bad values reported and ignored", () => {
  const { limits, errors } = XR.limitsFromQuery("?pos_mm=3&angle_deg=abc&hold_s=0.5");
  assert.deepEqual(limits, { pos_mm: 3, angle_deg: 14, hold_s: 0.5 });
  assert.equal(errors.length, 1);
  assert.match(errors[0], /angle_deg=abc/);
  assert.deepEqual(XR.limitsFromQuery("").limits, XR.DEFAULT_LIMITS);
  assert.equal(XR.limitsFromQuery("?hold_s=-1").errors.length, 1);
});

test("the rigid fit recovers a known motion, with the residual of noisy touches", () => {
  const P = [[0, 0.12, 0], [0.02, 0, 0.02], [-0.02, 0, 0.02], [0.02, 0.04, -0.02], [-0.03, 0.08, -0.01]];
  const axis = [1, 2, 3].map((x) => x / Math.sqrt(14)), angle = 1.1;
  const c = Math.cos(angle), s = Math.sin(angle), [x, y, z] = axis;
  const R = [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
             [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
             [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]];
  const t = [0.4, 0.9, -0.3];
  const move = (p) => [0, 1, 2].map((r) => R[r][0] * p[0] + R[r][1] * p[1] + R[r][2] * p[2] + t[r]);
  const Q = P.map(move);
  const fit = XR.rigidFit(P, Q);
  assert.ok(fit.rms_mm < 1e-6, fit.rms_mm);
  const m = fit.matrix; // column-major
  for (let r = 0; r < 3; r++) {
    for (let k = 0; k < 3; k++) assert.ok(Math.abs(m[4 * k + r] - R[r][k]) < 1e-9);
    assert.ok(Math.abs(m[12 + r] - t[r]) < 1e-9);
  }
  // touches 2 mm off in alternating directions: an rms near 2 mm, below the refusal limit
  const noisy = Q.map((q, i) => q.map((v, k) => v + (k === i % 3 ? (i % 2 ? 0.002 : -0.002) : 0)));
  const rough = XR.rigidFit(P, noisy);
  assert.ok(rough.rms_mm > 0.5 && rough.rms_mm < XR.MAX_CALIBRATION_RMS_MM, rough.rms_mm);
  // a touch on the wrong point: far above it
  const wrong = Q.slice();
  wrong[0] = Q[1];
  assert.ok(XR.rigidFit(P, wrong).rms_mm > XR.MAX_CALIBRATION_RMS_MM);
});

test("marked points: the highest vertex first, then spread out, and collinear points refused", () => {
  // a 40 mm box, its base on y = 0
  const v = [];
  for (const x of [-0.02, 0.02]) for (const y of [0, 0.04]) for (const z of [-0.02, 0.02]) v.push(x, y, z);
  const pts = XR.calibrationPoints(new Float64Array(v), 4);
  assert.equal(pts.length, 4);
  assert.equal(pts[0][1], 0.04);
  assert.ok(XR.spreadOk(pts));
  assert.equal(XR.spreadOk([[0, 0, 0], [0, 0.05, 0], [0, 0.1, 0]]), false);
});

test("CSV: a header, quoted fields where needed, numbers to 4 decimals", () => {
  const text = XR.toCSV([{ a: 1, b: "x,y", c: 0.123456 }, { a: 2, b: 'say "hi"', c: null }], ["a", "b", "c"]);
  assert.equal(text, 'a,b,c\r\n1,"x,y",0.1235\r\n2,"say ""hi""",\r\n');
});

test("CSV: text that a spreadsheet would run as a formula is neutralised, numbers are not", () => {
  const rows = [{ who: "=HYPERLINK(\"http://x\")", obj: "+cmd", note: "-2+3", at: "@SUM(A1)", tab: "\tx", n: -0.5 },
                { who: "ada", obj: "mug=1", note: "a-b", at: "x@y", tab: "t", n: -3 }];
  const text = XR.toCSV(rows, ["who", "obj", "note", "at", "tab", "n"]);
  assert.equal(text, 'who,obj,note,at,tab,n\r\n"\'=HYPERLINK(""http://x"")",\'+cmd,\'-2+3,\'@SUM(A1),\'\tx,-0.5000\r\n' +
    "ada,mug=1,a-b,x@y,t,-3\r\n");
});

test("a steady touch: one point after 1 s within 3 mm, none while moving, none again until moved away", () => {
  const touch = new XR.SteadyTouch({ radius_mm: 3, hold_s: 1, away_mm: 20 });
  const at = (x_mm) => [x_mm / 1000, 0.9, -0.4];
  let got = null;
  for (let k = 0; k <= 20; k++) got = touch.update(at(k * 5), k * 0.1) || got; // sliding: 5 mm per step
  assert.equal(got, null);
  const wobble = [0, 1, -1, 2, -2, 1, 0, -1, 1, 0, 2, -1];
  const found = wobble.map((d, k) => touch.update(at(100 + d), 3 + k * 0.1)).filter(Boolean);
  assert.equal(found.length, 1);
  assert.ok(Math.abs(found[0][0] * 1000 - 100) < 1.5);
  assert.equal(touch.update(at(100), 5), null); // still there: not a second point
  touch.update(at(130), 5.1); // moved away
  assert.equal(touch.update(at(130), 5.2), null);
  assert.ok(touch.update(at(130), 6.25));
});

test("landing notes: steady, fragile, noticed, none", () => {
  const landing = (p) => ({ radius_mm: 5, axis_deg: 14, p_noticed_worst: p, noticeable_worst: p >= 0.5 });
  assert.equal(XR.landingNote({ noticeable: false, landing: landing(0.2) }).word, "steady");
  const fragile = XR.landingNote({ noticeable: false, landing: landing(0.93) });
  assert.equal(fragile.word, "fragile");
  assert.equal(fragile.worst_percent, 93);
  assert.match(fragile.text, /within 5 mm/);
  assert.equal(XR.landingNote({ noticeable: true, landing: landing(0.99) }).word, "noticed");
  assert.equal(XR.landingNote({ noticeable: false }), null);
  assert.equal(XR.landingNote({ noticeable: false, landing: null }), null);
});

test("the study's numbers, as literals: 5 mm, 14 degrees, held 1 s; calibrations above 6 mm refused", () => {
  assert.deepEqual({ ...XR.DEFAULT_LIMITS }, { pos_mm: 5, angle_deg: 14, hold_s: 1 });
  assert.equal(XR.MAX_CALIBRATION_RMS_MM, 6);
});

// ---- scene mode: the warp, the level's frame, the carousel --------------------------------------------
const close = (a, b, tol = 1e-9) => a.every((x, k) => Math.abs(x - b[k]) <= tol);

test("the warp: no offset at the start, the full offset at the physical target, linear on the way", () => {
  const start = [0, 1.05, -0.1], physical = [0.05, 0.95, -0.4], virtual = [0.07, 0.955, -0.41];
  const full = [0.02, 0.005, -0.01];
  assert.ok(close(XR.warpOffset(start, physical, virtual, start), [0, 0, 0]));
  assert.ok(close(XR.warpOffset(start, physical, virtual, physical), full, 1e-12));
  const mid = start.map((x, k) => (x + physical[k]) / 2);
  assert.ok(close(XR.warpOffset(start, physical, virtual, mid), full.map((x) => x / 2), 1e-12));
  assert.equal(XR.warpRatio(start, physical, [start[0], start[1] + 0.1, start[2] + 0.2]), 0); // back: none
  assert.equal(XR.warpRatio(start, physical, [0.1, 0.9, -0.6]), 1); // past the target: the full offset
  // along the way the offset never jumps: 100 steps of 3 mm move it at most |full| / 100 each
  let last = XR.warpOffset(start, physical, virtual, start), biggest = 0;
  for (let k = 1; k <= 100; k++) {
    const h = start.map((x, i) => x + ((physical[i] - x) * k) / 100);
    const now = XR.warpOffset(start, physical, virtual, h);
    biggest = Math.max(biggest, Math.hypot(...now.map((x, i) => x - last[i])));
    last = now;
  }
  assert.ok(biggest <= Math.hypot(...full) / 100 + 1e-12);
});

test("the level in the prop's scene frame: a pose's inverse, then the scene's turn of the prop file", () => {
  // a z-up prop file, shown y up: Q = [[1,0,0],[0,0,1],[0,-1,0]] / 1000 as the scenes store it
  const C = [0.001, 0, 0, 0, 0, 0, 0.001, 0, 0, -0.001, 0, 0, 0, 0, 0, 1];
  const s = Math.sqrt(0.5);
  const pose = { position_mm: [100, 0, -50], quaternion_xyzw: [-s, 0, 0, s] }; // the file's +z up in the level
  const M = XR.levelToProp(C, pose);
  // a prop file point (mm) -> the level by the pose -> back into the scene frame: Q x / 1000
  const x = [10, 20, 30];
  const R = XR.quaternionRows(pose.quaternion_xyzw);
  const w = R.map((row, i) => (row[0] * x[0] + row[1] * x[1] + row[2] * x[2] + pose.position_mm[i]) / 1000);
  const got = [0, 1, 2].map((i) => M[4 * i] * w[0] + M[4 * i + 1] * w[1] + M[4 * i + 2] * w[2] + M[4 * i + 3]);
  assert.ok(close(got, [0.01, 0.03, -0.02], 1e-12), String(got));
  // with no pose the level's origin is the prop file's
  const I = XR.levelToProp(C, null);
  assert.ok(close([I[3], I[7], I[11]], [0, 0, 0]));
});

test("the carousel serves the carousel matches in the page's order", () => {
  const matches = [{ redirection: { mode: "redirect" } }, { redirection: { mode: "carousel" } }, {},
                   { redirection: { mode: "carousel" } }];
  assert.deepEqual(XR.carouselQueue(matches), [1, 3]);
});

// a rotation by `deg` about the unit axis `a`, by Rodrigues' formula: an oracle that does not use quaternions
const rodrigues = (a, deg) => {
  const t = (deg * Math.PI) / 180, c = Math.cos(t), s = Math.sin(t), [x, y, z] = a;
  return [[c + x * x * (1 - c), x * y * (1 - c) - z * s, x * z * (1 - c) + y * s],
          [y * x * (1 - c) + z * s, c + y * y * (1 - c), y * z * (1 - c) - x * s],
          [z * x * (1 - c) - y * s, z * y * (1 - c) + x * s, c + z * z * (1 - c)]];
};
const matmul = (A, B) => A.map((row) => [0, 1, 2].map((j) => row[0] * B[0][j] + row[1] * B[1][j] + row[2] * B[2][j]));
const apply = (R, v) => R.map((row) => row[0] * v[0] + row[1] * v[1] + row[2] * v[2]);

test("a quaternion's rows are the rotation about its axis, for a generic axis and angle", () => {
  const n = Math.hypot(1, -2, 3), axis = [1 / n, -2 / n, 3 / n], deg = 71;
  const h = (deg * Math.PI) / 360;
  const q = [...axis.map((c) => c * Math.sin(h)), Math.cos(h)];
  const R = XR.quaternionRows(q), O = rodrigues(axis, deg);
  for (let i = 0; i < 3; i++) assert.ok(close(R[i], O[i], 1e-12), `${R[i]} vs ${O[i]}`);
});

test("the level in the prop's frame, the prop standing at (120, 0, -80) mm turned 35 degrees about the level's up", () => {
  // the prop file is z up; in the level (y up) it stands: a quarter turn about x, then 35 degrees about y
  const stand = matmul(rodrigues([0, 1, 0], 35), rodrigues([1, 0, 0], -90));
  // its quaternion, from the matrix (w large here): the page reads the pose as the manifest gives it
  const w = Math.sqrt(1 + stand[0][0] + stand[1][1] + stand[2][2]) / 2;
  const q = [(stand[2][1] - stand[1][2]) / (4 * w), (stand[0][2] - stand[2][0]) / (4 * w),
             (stand[1][0] - stand[0][1]) / (4 * w), w];
  const pose = { position_mm: [120, 0, -80], quaternion_xyzw: q };
  const C = [0.001, 0, 0, 0, 0, 0, 0.001, 0, 0, -0.001, 0, 0, 0, 0, 0, 1]; // the scene's turn of the z-up file
  const M = XR.levelToProp(C, pose);
  // points of the prop file (mm): into the level by the oracle's matrix, then back by the page's map must give
  // the scene frame's point C x: the prop's own place in its scene, whatever its pose
  for (const x of [[10, 20, 30], [-27, 0, 66], [0, 0, 0]]) {
    const level = apply(stand, x).map((c, i) => (c + pose.position_mm[i]) / 1000);
    const got = [0, 1, 2].map((i) => M[4 * i] * level[0] + M[4 * i + 1] * level[1] + M[4 * i + 2] * level[2] + M[4 * i + 3]);
    assert.ok(close(got, [x[0] / 1000, x[2] / 1000, -x[1] / 1000], 1e-12), `${x}: ${got}`);
  }
  // the level's up, seen in the prop's scene frame, is the scene's up: the prop stands
  const up = [0, 1, 2].map((i) => M[4 * i + 1]);
  assert.ok(close(up.map((c) => c / Math.hypot(...up)), [0, 1, 0], 1e-12), String(up));
});

test("the carousel's ring holds its objects apart, however many and however large", () => {
  for (const radii of [[0.05], [0.03, 0.03], [0.06, 0.02, 0.09, 0.04, 0.05, 0.05, 0.07, 0.03, 0.1, 0.02, 0.06],
                       Array(30).fill(0.045)]) {
    const gap = 0.02;
    const ring = XR.carouselRing(radii.map((r) => ({ r })), 0.12, gap);
    assert.ok(ring.radius >= 0.12 && ring.radius > Math.max(...radii));
    assert.equal(ring.angles.length, radii.length);
    const at = ring.angles.map((a) => [ring.radius * Math.cos(a), ring.radius * Math.sin(a)]);
    for (let i = 0; i < radii.length; i++) {
      for (let j = i + 1; j < radii.length; j++) {
        const d = Math.hypot(at[i][0] - at[j][0], at[i][1] - at[j][1]);
        assert.ok(d >= radii[i] + radii[j] + gap - 1e-9, `${radii.length} objects: ${i} and ${j} ${d} apart`);
      }
    }
  }
});
