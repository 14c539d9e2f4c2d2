// pinchmatch in the headset: the pure logic of the immersive page, without three.js or WebXR, so that
// node's test runner checks it as it runs in the page (tests/js/xr_core.test.mjs).
// Positions are [x, y, z] arrays in metres (WebXR's unit); reports are in millimetres and degrees.
"use strict";
(function (root, factory) {
  if (typeof module === "object" && module.exports) module.exports = factory();
  else root.PinchmatchXR = factory();
})(typeof self !== "undefined" ? self : this, function () {
  // The method's study: both fingertips within 5 mm of their targets, the thumb-index direction within
  // 14 degrees of the target's, held for 1 s.
  const DEFAULT_LIMITS = Object.freeze({ pos_mm: 5, angle_deg: 14, hold_s: 1 });
  // a calibration whose root-mean-square residual is above this is refused
  const MAX_CALIBRATION_RMS_MM = 6;

  const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
  const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
  const norm = (a) => Math.sqrt(dot(a, a));

  function angleDeg(a, b) {
    const c = dot(a, b) / (norm(a) * norm(b));
    return (Math.acos(Math.max(-1, Math.min(1, c))) * 180) / Math.PI;
  }

  // Is the pinch (thumb and index fingertips) on the targets (p1, p2)? Either finger may go to either
  // target: the order with the smaller worst fingertip error is judged. The direction compared is
  // thumb -> index against the target's, in that order.
  function checkPinch(thumb, index, p1, p2, limits = DEFAULT_LIMITS) {
    const orders = [[p1, p2, "thumb on p1"], [p2, p1, "thumb on p2"]].map(([a, b, name]) => {
      const thumbErr = norm(sub(thumb, a)) * 1000, indexErr = norm(sub(index, b)) * 1000;
      return { name, thumbErr, indexErr, angle: angleDeg(sub(index, thumb), sub(b, a)) };
    });
    const best = Math.max(orders[0].thumbErr, orders[0].indexErr) <= Math.max(orders[1].thumbErr, orders[1].indexErr)
      ? orders[0] : orders[1];
    const ok = best.thumbErr <= limits.pos_mm && best.indexErr <= limits.pos_mm && best.angle <= limits.angle_deg;
    return { ok, order: best.name, thumb_error_mm: best.thumbErr, index_error_mm: best.indexErr,
             angle_error_deg: best.angle };
  }

  // Is the grasp on its targets? A pinch (two targets) as checkPinch; a tripod (three: the thumb's, the
  // index's, the middle finger's) with the thumb on the first and index and middle on the other two in
  // either order (the order with the smaller worst error is judged), every fingertip within pos_mm and the
  // direction from the thumb to the fingers' middle within angle_deg of the targets'. hand: { thumb, index,
  // middle } fingertip positions.
  function checkGrasp(hand, targets, limits = DEFAULT_LIMITS) {
    if (targets.length === 2) return checkPinch(hand.thumb, hand.index, targets[0], targets[1], limits);
    const mid = (a, b) => [(a[0] + b[0]) / 2, (a[1] + b[1]) / 2, (a[2] + b[2]) / 2];
    const [t0, t1, t2] = targets;
    const orders = [[t1, t2, "index on the second target"], [t2, t1, "index on the third target"]].map(([a, b, name]) => {
      const errors = [norm(sub(hand.thumb, t0)), norm(sub(hand.index, a)), norm(sub(hand.middle, b))].map((e) => e * 1000);
      return { name, errors, angle: angleDeg(sub(mid(hand.index, hand.middle), hand.thumb), sub(mid(a, b), t0)) };
    });
    const best = Math.max(...orders[0].errors) <= Math.max(...orders[1].errors) ? orders[0] : orders[1];
    const ok = best.errors.every((e) => e <= limits.pos_mm) && best.angle <= limits.angle_deg;
    return { ok, order: best.name, thumb_error_mm: best.errors[0], index_error_mm: best.errors[1],
             middle_error_mm: best.errors[2], angle_error_deg: best.angle };
  }

  // A pinch is validated once it has been on target for hold_s without a break; it stays validated
  // until reset.
  class HoldTimer {
    constructor(hold_s = DEFAULT_LIMITS.hold_s) {
      this.hold_s = hold_s;
      this.reset();
    }

    reset() {
      this.since = null;
      this.validated = false;
      this.validatedAt = null;
    }

    // ok: on target at time t_s (seconds, increasing); returns the seconds held so far
    update(ok, t_s) {
      if (this.validated) return this.hold_s;
      if (!ok) {
        this.since = null;
        return 0;
      }
      if (this.since === null) this.since = t_s;
      const held = t_s - this.since;
      if (held >= this.hold_s) {
        this.validated = true;
        this.validatedAt = t_s;
      }
      return held;
    }
  }

  // A fingertip held still on a point: update(p, t_s) returns the mean position once the tip has stayed
  // within radius_mm of where it settled for hold_s, then nothing until it has moved away_mm off it
  // (so that one touch is one point).
  class SteadyTouch {
    constructor({ radius_mm = 3, hold_s = 1, away_mm = 20 } = {}) {
      Object.assign(this, { radius_mm, hold_s, away_mm });
      this.anchor = null;
      this.samples = [];
      this.last = null;
    }

    // nothing is touched until the tip has moved away_mm from p (a hand resting where it already was)
    ignoreUntilMovedFrom(p) {
      this.last = p;
      this.anchor = null;
      this.samples = [];
    }

    update(p, t_s) {
      if (this.last) {
        if (norm(sub(p, this.last)) * 1000 < this.away_mm) return null;
        this.last = null;
      }
      if (!this.anchor || norm(sub(p, this.anchor.p)) * 1000 > this.radius_mm) {
        this.anchor = { p, t: t_s };
        this.samples = [];
      }
      this.samples.push(p);
      if (t_s - this.anchor.t < this.hold_s) return null;
      const n = this.samples.length;
      const mean = [0, 1, 2].map((k) => this.samples.reduce((s, q) => s + q[k], 0) / n);
      this.last = mean;
      this.anchor = null;
      this.samples = [];
      return mean;
    }
  }

  // Thresholds from a URL's query (?pos_mm=5&angle_deg=14&hold_s=1); anything else keeps its default.
  // A value that is not a positive number is an error, reported, never silently used.
  function limitsFromQuery(search, defaults = DEFAULT_LIMITS) {
    const params = new URLSearchParams(search);
    const limits = { ...defaults }, errors = [];
    for (const key of Object.keys(defaults)) {
      if (!params.has(key)) continue;
      const value = Number(params.get(key));
      if (Number.isFinite(value) && value > 0) limits[key] = value;
      else errors.push(`${key}=${params.get(key)} is not a positive number; using ${defaults[key]}`);
    }
    return { limits, errors };
  }

  // The eigenvector of the largest eigenvalue of a symmetric 4x4 matrix (Jacobi rotations).
  function topEigenvector4(S) {
    const a = S.map((row) => row.slice());
    const v = [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]];
    for (let sweep = 0; sweep < 50; sweep++) {
      let off = 0;
      for (let p = 0; p < 4; p++) for (let q = p + 1; q < 4; q++) off += a[p][q] * a[p][q];
      if (off < 1e-30) break;
      for (let p = 0; p < 4; p++) {
        for (let q = p + 1; q < 4; q++) {
          if (Math.abs(a[p][q]) < 1e-300) continue;
          const theta = (a[q][q] - a[p][p]) / (2 * a[p][q]);
          const t = Math.sign(theta || 1) / (Math.abs(theta) + Math.sqrt(theta * theta + 1));
          const c = 1 / Math.sqrt(t * t + 1), s = t * c;
          for (let k = 0; k < 4; k++) {
            const akp = a[k][p], akq = a[k][q];
            a[k][p] = c * akp - s * akq;
            a[k][q] = s * akp + c * akq;
          }
          for (let k = 0; k < 4; k++) {
            const apk = a[p][k], aqk = a[q][k];
            a[p][k] = c * apk - s * aqk;
            a[q][k] = s * apk + c * aqk;
          }
          for (let k = 0; k < 4; k++) {
            const vkp = v[k][p], vkq = v[k][q];
            v[k][p] = c * vkp - s * vkq;
            v[k][q] = s * vkp + c * vkq;
          }
        }
      }
    }
    let best = 0;
    for (let k = 1; k < 4; k++) if (a[k][k] > a[best][best]) best = k;
    return [v[0][best], v[1][best], v[2][best], v[3][best]];
  }

  // The rigid motion (rotation R, translation t) that best maps the points P onto Q in the least-squares
  // sense (Horn's quaternion method), and its residual. P, Q: arrays of at least 3 [x, y, z] (metres).
  // Returns { matrix: column-major 4x4 (three.js's Matrix4.fromArray), rms_mm, max_mm, residuals_mm }.
  function rigidFit(P, Q) {
    if (P.length !== Q.length || P.length < 3) throw new Error("rigidFit needs 3 or more pairs of points");
    const n = P.length;
    const mean = (X) => [0, 1, 2].map((k) => X.reduce((s, x) => s + x[k], 0) / n);
    const cp = mean(P), cq = mean(Q);
    const M = [[0, 0, 0], [0, 0, 0], [0, 0, 0]];
    for (let i = 0; i < n; i++) {
      const a = sub(P[i], cp), b = sub(Q[i], cq);
      for (let r = 0; r < 3; r++) for (let c = 0; c < 3; c++) M[r][c] += a[r] * b[c];
    }
    const [[xx, xy, xz], [yx, yy, yz], [zx, zy, zz]] = M;
    const N = [
      [xx + yy + zz, yz - zy, zx - xz, xy - yx],
      [yz - zy, xx - yy - zz, xy + yx, zx + xz],
      [zx - xz, xy + yx, -xx + yy - zz, yz + zy],
      [xy - yx, zx + xz, yz + zy, -xx - yy + zz],
    ];
    const [w, x, y, z] = topEigenvector4(N);
    const R = [
      [w * w + x * x - y * y - z * z, 2 * (x * y - w * z), 2 * (x * z + w * y)],
      [2 * (x * y + w * z), w * w - x * x + y * y - z * z, 2 * (y * z - w * x)],
      [2 * (x * z - w * y), 2 * (y * z + w * x), w * w - x * x - y * y + z * z],
    ];
    const t = [0, 1, 2].map((r) => cq[r] - (R[r][0] * cp[0] + R[r][1] * cp[1] + R[r][2] * cp[2]));
    const apply = (p) => [0, 1, 2].map((r) => R[r][0] * p[0] + R[r][1] * p[1] + R[r][2] * p[2] + t[r]);
    const residuals_mm = P.map((p, i) => norm(sub(apply(p), Q[i])) * 1000);
    const rms_mm = Math.sqrt(residuals_mm.reduce((s, e) => s + e * e, 0) / n);
    const matrix = [R[0][0], R[1][0], R[2][0], 0, R[0][1], R[1][1], R[2][1], 0,
                    R[0][2], R[1][2], R[2][2], 0, t[0], t[1], t[2], 1];
    return { matrix, rms_mm, max_mm: Math.max(...residuals_mm), residuals_mm, apply };
  }

  // Are the marked points spread enough to fix a pose? The smallest singular direction of their spread
  // must not be degenerate in two directions (points on a line fix no rotation about it).
  function spreadOk(P, min_mm = 10) {
    const n = P.length, c = [0, 1, 2].map((k) => P.reduce((s, x) => s + x[k], 0) / n);
    let best = 0;
    for (let i = 0; i < n; i++) {
      for (let j = 0; j < n; j++) {
        const a = sub(P[i], c), b = sub(P[j], c);
        const cross = [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
        best = Math.max(best, norm(cross) / Math.max(norm(b), 1e-12));
      }
    }
    return best * 1000 >= min_mm;
  }

  // Points to touch for the calibration, from the prop's vertices (flat [x, y, z, ...], metres, Y up):
  // the highest vertex, then each next the vertex farthest from those chosen (deterministic).
  function calibrationPoints(positions, count = 4) {
    const n = positions.length / 3;
    if (n < count) throw new Error("too few vertices to mark");
    let first = 0;
    for (let i = 1; i < n; i++) if (positions[3 * i + 1] > positions[3 * first + 1] + 1e-9) first = i;
    const chosen = [first], far = new Float64Array(n).fill(Infinity);
    while (chosen.length < count) {
      const c = chosen[chosen.length - 1];
      let pick = -1;
      for (let i = 0; i < n; i++) {
        const dx = positions[3 * i] - positions[3 * c], dy = positions[3 * i + 1] - positions[3 * c + 1];
        const dz = positions[3 * i + 2] - positions[3 * c + 2];
        far[i] = Math.min(far[i], dx * dx + dy * dy + dz * dz);
        if (pick < 0 || far[i] > far[pick] + 1e-12) pick = i;
      }
      chosen.push(pick);
    }
    return chosen.map((i) => [positions[3 * i], positions[3 * i + 1], positions[3 * i + 2]]);
  }

  // RFC 4180 CSV: a header from `columns`, one line per row, fields quoted where they need it.
  function toCSV(rows, columns) {
    const cell = (v) => {
      if (v === null || v === undefined) return "";
      let text = typeof v === "number" ? (Number.isInteger(v) ? String(v) : v.toFixed(4)) : String(v);
      // a text cell that a spreadsheet would read as a formula is neutralised with a leading quote
      if (typeof v !== "number" && /^[=+\-@\t\r]/.test(text)) text = `'${text}`;
      return /[",\r\n]/.test(text) ? `"${text.replace(/"/g, '""')}"` : text;
    };
    return [columns.join(","), ...rows.map((r) => columns.map((c) => cell(r[c])).join(","))].join("\r\n") + "\r\n";
  }

  // How a match holds when the fingers land off target (matches.json's "landing"): "steady" when even
  // its worst landing is noticed less than half the time, "fragile" when a landing within the tolerance
  // is noticed though the match on target is not, "noticed" when the match is noticed on target too;
  // null without a landing. The words and the worst chance, for the page and the headset.
  function landingNote(match) {
    const landing = match && match.landing;
    if (!landing || landing.p_noticed_worst === null || landing.p_noticed_worst === undefined) return null;
    const worst = Math.round(100 * landing.p_noticed_worst);
    const word = !landing.noticeable_worst ? "steady" : match.noticeable ? "noticed" : "fragile";
    return { word, worst_percent: worst,
             text: `${word}: within ${Number(landing.radius_mm)} mm of the targets it is noticed at most ${worst} % of the time` };
  }

  // ---- scene mode: hand redirection (docs/redirection.md) ----------------------------------------------

  // Body warping after Azmandian et al. 2016: how far the hand h has come from the warp's origin w0
  // toward the physical target wT, projected on the line between them and clamped to [0, 1]: 0 at the
  // start (and whenever the hand is back behind it), 1 at the target.
  function warpRatio(w0, wT, h) {
    const path = sub(wT, w0), length2 = dot(path, path);
    if (!(length2 > 0)) return 1;
    return Math.max(0, Math.min(1, dot(path, sub(h, w0)) / length2));
  }

  // The virtual hand's offset from the real one at h: the ratio times (virtual - physical target), so
  // that the virtual fingers reach the virtual pinch exactly when the real ones reach the prop.
  function warpOffset(w0, physical, virtual, h) {
    const a = warpRatio(w0, physical, h), d = sub(virtual, physical);
    return [a * d[0], a * d[1], a * d[2]];
  }

  // The rotation matrix (rows) of a unit quaternion [x, y, z, w].
  function quaternionRows([x, y, z, w]) {
    return [[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]];
  }

  // The level's frame (metres, y up) in the prop's scene frame, the frame of the match scenes that the
  // calibration places in the room: a 4x4 matrix, 16 numbers row by row. C: the scenes'
  // "pinchmatch:file_mm_to_gltf_m" (16 numbers row by row: the prop file's mm to the scene's metres);
  // pose: the prop's pose in the level ({position_mm, quaternion_xyzw}; null: at the origin, unturned).
  // A level point w maps to Q R^T (w - p), Q the scene's turn of the prop file, R and p the pose's.
  function levelToProp(C, pose) {
    const Q = [0, 1, 2].map((i) => [0, 1, 2].map((j) => C[4 * i + j] * 1000));
    const R = quaternionRows(pose ? pose.quaternion_xyzw : [0, 0, 0, 1]);
    const p = (pose ? pose.position_mm : [0, 0, 0]).map((x) => x / 1000);
    const M = [0, 1, 2].map((i) => [0, 1, 2].map((j) => Q[i][0] * R[j][0] + Q[i][1] * R[j][1] + Q[i][2] * R[j][2]));
    const t = M.map((row) => -dot(row, p));
    return [...M[0], t[0], ...M[1], t[1], ...M[2], t[2], 0, 0, 0, 1];
  }

  // The carousel's order: the matches (indices into `matches`) that it serves, in the page's order.
  function carouselQueue(matches) {
    return matches.flatMap((m, i) => (m.redirection && m.redirection.mode === "carousel" ? [i] : []));
  }

  // The carousel's ring: objects of footprint radii r_k (m) side by side around the whole ring, each its
  // share of the turn in proportion to 2 r_k + gap, the radius the least (never below `least`) at which
  // every two neighbours' middles are at least r_i + r_j + gap apart (the chord, not the arc), so that none
  // touch. `angles` (rad): the footprints' middles, the first at 0.
  function carouselRing(footprints, least, gap) {
    const n = footprints.length;
    const arcs = footprints.map((f) => 2 * f.r + gap);
    const total = arcs.reduce((a, b) => a + b, 0) || 1;
    const step = arcs.map((a, i) => (Math.PI * (a + arcs[(i + 1) % n])) / total); // middle i to middle i + 1
    let radius = least;
    for (let i = 0; i < n && n > 1; i++) {
      const need = footprints[i].r + footprints[(i + 1) % n].r + gap;
      radius = Math.max(radius, need / (2 * Math.sin(Math.min(step[i], Math.PI) / 2)));
    }
    radius = Math.max(radius, n ? Math.max(...footprints.map((f) => f.r)) + gap : 0);
    const angles = [0];
    for (let i = 1; i < n; i++) angles.push(angles[i - 1] + step[i - 1]);
    return { radius, angles };
  }

  return { DEFAULT_LIMITS, MAX_CALIBRATION_RMS_MM, checkPinch, checkGrasp, HoldTimer, SteadyTouch, limitsFromQuery, rigidFit, spreadOk,
           calibrationPoints, toCSV, angleDeg, landingNote, warpRatio, warpOffset, quaternionRows, levelToProp,
           carouselQueue, carouselRing };
});
