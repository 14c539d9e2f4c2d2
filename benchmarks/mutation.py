"""Mutation check of the core: plant small bugs, one at a time, and see whether the tests notice.

Run from the repository root (a few minutes per module and worker; prints a table)::

    python benchmarks/mutation.py                  # every core module, 30 mutants each, 2 workers
    python benchmarks/mutation.py --sample 0       # every mutant (hours)
    python benchmarks/mutation.py --modules cost,register --sample 50

A mutant is one change of the syntax tree of one module: an arithmetic operator swapped
(``+``/``-``, ``*``/``/``, ``**``→``*``), a comparison loosened or flipped, a number
changed (``n``→``n+1``, ``x``→``2x``, ``0.0``→``1.0``), ``True``/``False``, ``and``/``or``
swapped, a unary minus or ``not`` dropped, an augmented assignment inverted, a wrapping call
dropped (``abs(x)``→``x``, ``f(x, r)``→``x``), two index literals of one expression swapped
(``a[:, 1] - b[0]``→``a[:, 0] - b[1]``). Docstrings,
strings, annotations and lines marked ``# pragma: no mutate`` are left alone. The mutants of a
module are enumerated in source order and a fixed sample of them is drawn (``--seed``), so a
run is reproducible.

Each mutant is written into a private copy of the repository (one per worker) and that
module's tests run there with ``pytest -x``; a failure or a time-out (five times the clean
run) kills it. A mutant that survives is listed with its line, so it can be killed by a new
test or recorded as equivalent (``EQUIVALENT`` below, with the reason).

Why not mutmut or cosmic-ray: mutmut 3 rewrites every function into a trampoline, which numba
cannot compile (``jets.py``, ``spread_kernel.py``) and which breaks the pickling of the worker
tasks; cosmic-ray enumerates every mutant with no sampling, so one module takes hours with
tests that fit patches and search reach. The operators here are the usual ones of both tools.
"""

from __future__ import annotations

import argparse
import ast
import concurrent.futures as cf
import os
import random
import shutil
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGE = ROOT / "src" / "pinchmatch"

#: module (relative to src/pinchmatch) -> the test files that own it
CORE = {
    "grasp/curvature.py": ["test_curvature.py", "test_jets.py"],
    "grasp/jets.py": ["test_jets.py", "test_curvature.py"],
    "grasp/pinches.py": ["test_pinches.py", "test_contract.py"],
    "grasp/hand.py": ["test_hand.py", "test_pinches.py"],
    "grasp/finger_spheres.py": ["test_hand_queries.py", "test_distance_field.py", "test_hand.py"],
    "grasp/features.py": ["test_features.py"],
    "match/cost.py": ["test_cost.py"],
    "match/search.py": ["test_match.py", "test_cost.py", "test_redirect.py"],
    "match/noticed.py": ["test_match.py", "test_landing.py"],
    "match/choice.py": ["test_match.py", "test_pairs.py"],
    "match/pairs.py": ["test_pairs.py", "test_match.py"],
    "match/register.py": ["test_register.py"],
    "match/rest.py": ["test_rest.py", "test_rest_floor.py", "test_cost.py"],
    "mesh/lowest.py": ["test_lowest.py", "test_rest.py"],
    "mesh/frames.py": ["test_register.py", "test_load.py"],
    "mesh/properties.py": ["test_properties.py"],
    "match/redirect.py": ["test_redirect.py"],
    "match/select.py": ["test_select.py"],
    "match/calibrate.py": ["test_calibrate.py"],
    "match/ratings.py": ["test_calibrate.py", "test_fuzz_readers.py"],
    "match/candidates.py": ["test_match.py", "test_refine.py"],
    "match/refine.py": ["test_refine.py"],
    "mesh/regions.py": ["test_manifest.py"],
    "mesh/level.py": ["test_manifest.py", "test_gltf_check.py"],
    "export/folder.py": ["test_publish.py", "test_option_extremes.py"],
    "runner/design.py": ["test_design.py"],
    "config.py": ["test_config.py", "test_pinches.py", "test_cost.py", "test_redirect.py",
                  "test_match.py"],
    "options.py": ["test_config.py", "test_cache.py", "test_result_cache.py"],
    "match/ranking.py": ["test_ranking.py", "test_steady.py"],
    "scan/clean.py": ["test_prop_import.py"],
    "scan/read.py": ["test_prop_import.py"],
    "scan/orient.py": ["test_scan_orient.py"],
    "match/scene.py": ["test_match.py", "test_redirect.py", "test_landing.py", "test_select.py"],
    "match/reference.py": ["test_match.py", "test_cache.py"],
    "match/felt.py": ["test_landing.py", "test_tripod_landing.py"],
    "mesh/support.py": ["test_pinches.py", "test_redirect.py", "test_manifest.py",
                        "test_furniture.py"],
    "memory.py": ["test_memory_limits.py"],
    "mesh/gltf_apply.py": ["test_gltf_sparse.py", "test_gltf_check.py"],
    "mesh/facing.py": ["test_load.py"],
    "mesh/furniture.py": ["test_furniture.py"],
    "mesh/neighbours.py": ["test_neighbours.py"],
    "mesh/distance_field_kernel.py": ["test_distance_field.py"],
    "export/seal.py": ["test_received_folders.py"],
    "export/level.py": ["test_level_glb.py", "test_level_fidelity.py"],
    "export/gltf_document.py": ["test_level_fidelity.py"],
    "match/steady.py": ["test_steady.py"],
    "grasp/tripod_rules.py": ["test_tripods.py"],
    "grasp/strata.py": ["test_strata.py"],
    "runner/cache.py": ["test_cache.py", "test_result_cache.py", "test_keys.py"],
    "match/targeted.py": ["test_targeted.py"],
    "grasp/tripods.py": ["test_tripods.py"],
    "grasp/rounds.py": ["test_rounds.py", "test_spread.py", "test_coverage.py"],
    "match/trust.py": ["test_trust.py", "test_prop_import.py"],
    "grasp/scan_noise.py": ["test_trust.py"],
}

#: surviving mutants judged equivalent: (module, source line stripped, description) -> reason
_HELPER = ("any helper direction not along the normal gives a tangent frame, and a patch's "
           "curvature "
           "and principal directions do not depend on how its frame turns in the tangent plane")
_SCALED = ("the helper is only crossed with the normal and the result normalised: a longer helper "
           "is the same frame")
_GUARD = ("a guard against round-off near a degenerate case (opposite or parallel unit vectors); "
          "doubling it moves "
          "the switch by a few ulps of inputs no geometry lands on")
_INFER = "numpy takes any negative size as the one to infer: reshape(-2, k) is reshape(-1, k)"
_APPLIED = ("applying a document with no sparse accessor and no morph weights rewrites it to the "
            "same geometry: "
            "the test only saves the rewriting")
_GUARD_WIDE = ("the round-off guard is 1e-9 mm per mm of the largest coordinate: which points set "
               "it, or its "
               "constant, moves the bounds by a billionth of a millimetre; they stay true, and the "
               "exact distance "
               "decides any point they leave open (the loop over the points' bounds, the same "
               "line, is killed)")
_PADDED = ("the grid is padded two layers past the grown cells: its last two layers are the same "
           "air, joined to the border")
EQUIVALENT: dict[tuple[str, str, str], str] = {
    ("scan/orient.py", "directed=False)", "False -> True"):
        "the graph holds each neighbour pair one way; scipy joins a directed graph's components "
        "weakly by default, as the undirected graph's",
    ("scan/orient.py", "border = np.unique(np.concatenate([labels[[0, -1]].ravel(), labels[:, [0, "
     "-1]].ravel(),", "drop -1"):
        "the padded grid's air is one piece touching every face of the border, so any face finds "
        "it",
    ("scan/orient.py", "border = np.unique(np.concatenate([labels[[0, -1]].ravel(), labels[:, [0, "
     "-1]].ravel(),", "1 -> 2"): _PADDED,
    ("scan/orient.py", "undecided = np.flatnonzero(sign == 0)", "drop .flatnonzero(...)"):
        "a mask indexes as its indices do; with none undecided the second probing changes nothing",
    ("scan/orient.py", "top = np.array(outside.shape) - 1", "1 -> 2"): _PADDED,
    ("scan/orient.py", "split = ((decided - np.abs(votes)) / 2 > SPLIT_SHARE * np.maximum(decided, "
     "1))[region]", "1 -> 2"):
        "a region with fewer than two decided points has no minority, so it is split by neither",
    ("grasp/curvature.py", "(np.abs(normal[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), "
     "np.array([0.0, 1.0, 0.0])", "< -> <="): _HELPER,
    ("grasp/curvature.py", "(np.abs(normal[:, 0]) < 0.9)[:, None], np.array([1.0, 0.0, 0.0]), "
     "np.array([0.0, 1.0, 0.0])", "1.0 -> 2.0"): _SCALED,
    ("grasp/jets.py", "hx, hy, hz = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)",
     "< -> <="): _HELPER,
    ("grasp/jets.py", "hx, hy, hz = (1.0, 0.0, 0.0) if abs(n[0]) < 0.9 else (0.0, 1.0, 0.0)",
     "1.0 -> 2.0"): _SCALED,
    ("match/cost.py",
     "pose = np.stack([features.width_mm, features.com_distance_mm, features.tilt_deg], "
     "axis=-1)", "drop -1"): "np.stack of 1-D arrays: axis 1 is the last axis, as -1 is",
    ("match/cost.py", "stacked = table.reshape(-1, N_COLUMNS)", "1 -> 2"): _INFER,
    ("grasp/curvature.py", "points_mm = np.asarray(points_mm, dtype=np.float64).reshape(-1, 3)",
     "1 -> 2"): _INFER,
    ("grasp/curvature.py", "normal = np.asarray(normals, dtype=np.float64).reshape(-1, 3)",
     "1 -> 2"): _INFER,
    ("grasp/pinches.py", "raw = np.stack([p1_mm, p2_mm], axis=1).reshape(-1, 3)", "1 -> 2"): _INFER,
    ("grasp/pinches.py", "dtype=np.int64).reshape(-1)", "1 -> 2"): _INFER,
    ("match/search.py",
     "return int(np.clip(n_tangible * n_virtual // POOL_PAIRS_PER_KEPT, MIN_POOL, MAX_POOL))",
     "// -> /"): "int() truncates the positive quotient as // does",
    ("match/search.py", "below = np.flatnonzero(result.cost < tau)", "< -> <="):
        "the greedy pick keeps only pairs costing less than tau again, so a pooled pair costing "
        "exactly tau is "
        "never picked either way",
    ("match/pairs.py", "below = value < rest", "< -> <="):
        "a pair whose value equals the rest may be listed or not: every pair left out is still at "
        "least the "
        "rest, and a pool cut at it takes the rest as its bound either way",
    ("match/noticed.py", "size = float(np.sqrt(jnd[k]))", "drop float(...)"):
        "np.float64 is a subclass of float: it compares, formats and serialises (json) as the "
        "float does",
    ("match/cost.py", "block_rows: int = 2048):", "2048 -> 2049"):
        "the block size splits the tangible rows into blocks, each row's costs are computed alike "
        "in any block",
    ("match/cost.py", "s = (model.scales(tangible_rows) if scales is None else scales)[:, 0, 7]",
     "0 -> 1"):
        "the mass columns' scale is of the offset's length, the same in every contact's row (a "
        "pinch's second row "
        "holds the offset along the line negated)",
    ("match/cost.py",
     "buffers = np.empty((2, rows, nv))  # allocated once: no page faults per block", "2 -> 3"):
        "a third buffer is allocated and never written or read: the two orders use the first two",
    ("match/register.py",
     "return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)", "drop -1"):
        "every caller passes (k, 3) vectors, whose last axis is axis 1",
    ("grasp/features.py", "u = seg / np.maximum(width, 1e-300)[:, None]", "1e-300 -> 2e-300"):
        "the floor only keeps a zero-width pinch from dividing by zero: any tiny floor gives the "
        "same zero vector",
    ("match/cost.py", "s[..., 7:9] = np.maximum(fraction * np.hypot(t[..., 7], t[..., 8]),",
     "9 -> 10"): "the table has 9 columns: the slice 7:10 is the slice 7:9",
    ("match/register.py", "has_mass = (np.linalg.norm(perp(dm_v), axis=1) > 1e-9) & "
     "(np.linalg.norm(perp(dm_t), axis=1)", "1e-09 -> 2e-09"): _GUARD,
    ("match/register.py", "> 1e-9)", "1e-09 -> 2e-09"): _GUARD,
    ("mesh/properties.py", "if not np.isfinite(norm) or norm < 1e-12:", "1e-12 -> 2e-12"): _GUARD,
    ("mesh/frames.py", "opposite = c < -1.0 + 1e-12", "1e-12 -> 2e-12"): _GUARD,
    ("mesh/frames.py", "small = np.linalg.norm(perp, axis=1) < 1e-6", "1e-06 -> 2e-06"): _GUARD,
    ("mesh/properties.py", "if abs(along) > 1e-9:", "1e-09 -> 2e-09"): _GUARD,
    ("mesh/properties.py", "return axis if along > 0 else -axis", "> -> >="):
        "the line before returns only where |along| > 1e-9, so along is never 0 here",
    ("grasp/curvature.py", "if workers > 1:", "1 -> 2"):
        "with two workers the chunks run one after another instead of on two threads, and results "
        "do not "
        "depend on the threads (tests/test_jets.py)",
    ("grasp/curvature.py", "CHUNK = 256", "256 -> 257"):
        "the chunk size only splits the work; tests/test_jets.py checks that results do not depend "
        "on it",
    ("mesh/frames.py", "perp = np.cross(ao, [1.0, 0.0, 0.0])", "0.0 -> 1.0"):
        "a half turn about any axis perpendicular to a takes a onto -a, and all are smallest; a "
        "helper along "
        "a itself is caught by the fallback on the next line",
}

_THREADS = ("a thread count only: results do not depend on how many threads share the work "
            "(tests/test_jets.py)")
_BOUNDARY = ("the two sides differ only at exact equality of two floats no input lands on (a "
             "measure-zero "
             "boundary of a continuous quantity)")
_SAME_TYPE = ("every caller passes the type the call converts to, so the call returns its argument "
              "unchanged")
EQUIVALENT.update({
    ("grasp/curvature.py", "radius = float(patch_radius_mm or context.patch_radius_mm)",
     "drop float(...)"):
        _SAME_TYPE,
    ("grasp/curvature.py", "workers = min(len(starts), thread_budget())",
     "drop min(...)"): _THREADS,
    ("grasp/pinches.py",
     "return (_angle_deg(u, -normals[:, 0]) > cone_deg) | (_angle_deg(-u, -normals[:, 1]) > "
     "cone_deg)", "> -> >="): _BOUNDARY,
    ("config.py", "return isinstance(other, Mapping) and dict(self) == dict(other)",
     "drop dict(...)"):
        "self == dict(other) calls this method again with a dict, which compares dict(self) with "
        "it: the same answer",
    ("match/register.py",
     "return v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-300)",
     "1e-300 -> 2e-300"): _GUARD,
    ("mesh/frames.py", "K = np.zeros(v.shape[:-1] + (3, 3))", "drop -1"):
        "every caller passes (k, 3) vectors, whose shape[:1] is their shape[:-1]",
    ("mesh/properties.py", 'parts = [p for p in str(text).replace(" ", "").split(",") if p != ""]',
     "drop str(...)"): _SAME_TYPE,
    ("match/select.py", "score = _scores(cost, noticeable, np.array([chosen]), objective)[0]",
     "drop .array(...)"):
        "numpy indexes with the list [chosen] as with the array made from it",
    ("match/ratings.py",
     "if (np.abs(values[:, 0]) > MAX_RATING).any() or (values[:, 1:] > MAX_JND).any():",
     "> -> >="): _BOUNDARY,
    ("mesh/regions.py",
     'return Region("sphere", tuple(float(c) for c in center_mm), float(radius_mm))',
     "drop float(...)"): "an int radius compares and squares as the float would",
    ("mesh/level.py", "faces = np.asarray(mesh.faces, dtype=np.int64)",
     "drop .asarray(...)"): _SAME_TYPE,
    ("mesh/level.py",
     "if np.linalg.det(transform[:3, :3]) < 0:  # a mirroring transform turns the winding inside "
     "out",
     "< -> <="): "a node whose transform has determinant 0 flattens its mesh to no volume, which "
                 "the load "
                        "refuses either way",
    ("runner/design.py", "if first_s > s.budget_s and s.evaluations is None:",
     "> -> >="): _BOUNDARY,
    ("grasp/features.py", "mass_along_mm=np.stack([along, -along], axis=-1),", "drop -1"):
        "np.stack of 1-D arrays: axis 1 is the last axis, as -1 is",
    ("match/redirect.py", "(turn / redirect.axis_threshold_deg) ** 2], axis=-1)",
     "drop -1"): "np.stack of 1-D arrays: axis 1 is the last axis, as -1 is",
    ("match/candidates.py", "keep = np.asarray(keep)", "drop .asarray(...)"):
        "numpy indexes with a list of positions as with the array made from it",
    ("runner/design.py", "total = s.evaluations or max(1, int(s.budget_s / max(first_s, 1e-3)))",
     "1 -> 2"):
        "the total only labels the progress bar; the search stops by time, not by it",
    ("match/search.py", "pick_b = b.cost < a.cost", "< -> <="): _BOUNDARY,
    ("mesh/support.py", 'return SupportPlane(normal, float(rests_on), "furniture top")',
     "drop float(...)"):
        "the furniture survey gives the top's height as a float already (a median of heights)",
    ("mesh/support.py", "LEVEL_UP = np.array([0.0, 1.0, 0.0])", "drop .array(...)"):
        "a rotation matrix times a list of three numbers is the same vector",
    ("mesh/support.py",
     "return np.asarray(points, dtype=np.float64) @ self.normal - self.height_mm",
     "drop .asarray(...)"): "every caller passes a float array of points",
    ("mesh/support.py", "normal = Rotation.from_quat(np.asarray(pose[1],",
     "drop .asarray(...)"): "scipy takes the pose's tuple of four floats as it takes their array",
    ("mesh/support.py",
     "return SupportPlane(normal, float(np.min(np.asarray(vertices, dtype=np.float64) "
     "@ normal)),",
     "drop float(...)"): "numpy's float64 is a subclass of Python's float: the same height",
    ("match/felt.py", "back = radius_mm * math.tan(math.radians(axis_deg)) + radius_mm + 1.0",
     "drop .tan(...)"):
        "tan(14 deg) and 14 deg in radians differ by 2 %: a start 0.02 mm nearer on a margin of "
        "several mm",
    ("match/search.py", "if len(picks) >= count or not np.isfinite(tau):", ">= -> >"):
        "a pool grown past the picks adds only pairs costlier than they are: the same picks, found "
        "later",
    ("match/scene.py", "list(search.tangibles), virtual, landed)", "drop list(...)"):
        "the search's list of tangibles is never changed after the search: the match may hold it "
        "itself",
    ("match/ranking.py", "best = search.choices(0, [t], 1)[0]", "1 -> 2"):
        "the first of the two best choices is the best choice",
    ("match/scene.py", "big = (np.abs(cost_matrix[finite]).sum() + 1.0) * (min(m, n) + 1)",
     "drop .abs(...)"):
        "costs are never negative",
    ("match/cost.py", "for item in str(text or \"\").split(\",\"):", "drop str(...)"):
        "the command line gives the weights as text or not at all: str of a string is the string",
    ("match/search.py", "return float(pool.result.cost.min()) if len(pool.it) else np.inf",
     "drop float(...)"):
        "numpy's float64 is a subclass of Python's float: every caller reads the same number",
    ("match/reference.py",
     "reach = (np.linalg.norm(bounds[1] - bounds[0]) + np.linalg.norm(point - "
     "bounds.mean(axis=0))",
     "+ -> -"): "the fingers start outside the object either way: the bounds' diagonal plus the "
                "point's "
                          "distance from their centre already reach past the surface; 1 mm is a "
                          "margin",
    ("match/reference.py", "face, dist = obj.context.first_hit(origins, np.array([u, -u]))",
     "drop .array(...)"):
        "the ray engine makes an array of the list of two directions, as np.array does",
    ("match/reference.py",
     "data = np.concatenate([np.asarray(x, np.float64).ravel() for x in parts])",
     "drop .asarray(...)"): "every part is already a float64 array (a contact, a direction)",
    ("match/scene.py", "big = (np.abs(cost_matrix[finite]).sum() + 1.0) * (min(m, n) + 1)",
     "drop min(...)"):
        "any factor of at least min(m, n) + 1 makes a forbidden pair cost more than every full "
        "assignment",
    ("export/folder.py", "control = Path(out) / CONTROL", "drop Path(...)"):
        "every caller passes a Path (the supervisor's output, the next run's OutputFolder)",
    ("export/folder.py",
     "manifest = unsealed(\"manifest\", (Path(out) / CONTROL / \"manifest.json\").read_bytes())",
     "drop Path(...)"): "every caller passes a Path",
    ("export/folder.py", "out = Path(out)", "drop Path(...)"): "every caller passes a Path",
    ("export/seal.py", "value = os.read(fd, KEY_BYTES + 1)", "1 -> 2"):
        "reading one byte past the key or two, a longer file is refused all the same (its length "
        "is not KEY_BYTES)",
    ("mesh/gltf_apply.py",
     'return any(isinstance(a, dict) and "sparse" in a for a in accessors) or any(',
     "drop any(...)"): _APPLIED,
    ("mesh/gltf_apply.py", 'isinstance(m, dict) and any(m.get("weights") or []) for m in meshes)',
     "and -> or"):
        _APPLIED,
    ("mesh/gltf_apply.py", 'blob.extend(data + b"\\0" * (-len(data) % 4))', "4 -> 5"):
        "the applied document is read by trimesh in memory, which takes arrays at any offset: the "
        "padding only "
        "keeps the views 4-byte aligned as the specification asks of files",
    ("grasp/tripods.py",
     "offset = 0.5 * spacing[:, None] * (np.cos(phi)[:, None] * t1 + np.sin(phi)[:, None] * t2)",
     "+ -> -"): "phi is uniform over the whole turn: (cos phi, -sin phi) is the direction of -phi, "
                "as uniform; "
                "the fingers' directions are drawn from the same distribution",
    ("export/level.py", 'return {"translation": [float(c) for c in t],', "drop float(...)"):
        "numpy's float64 is a subclass of float: json writes the same numbers",
    ("export/level.py", '"rotation": [float(c) for c in Rotation.from_matrix(R).as_quat()]}',
     "drop float(...)"):
        "numpy's float64 is a subclass of float: json writes the same numbers",
    ("mesh/neighbours.py", "CUBE_SHARE = 1.0", "1.0 -> 2.0"):
        "the cubes' side is a speed setting: each cube's ball query covers every ball of its "
        "points at any side, "
        "and the kernel keeps the samples within the radius exactly",
    ("mesh/neighbours.py", "count=int(lengths.sum()))",
     "drop int(...)"): "np.fromiter takes numpy's integer as its count",
    ("mesh/distance_field_kernel.py", "for i in range(points.shape[0]):", "0 -> 1"): _GUARD_WIDE,
    ("mesh/distance_field_kernel.py",
     "constant = voxel * math.sqrt(3.0) / 2.0 + guard * (1.0 + largest)",
     "1.0 -> 2.0"): _GUARD_WIDE,
    ("mesh/distance_field_kernel.py", "e = np.float64(flat[index])", "drop .float64(...)"):
        "numba computes e - slack and e + slack in float64 either way: the float32 value is "
        "promoted exactly",
    ("match/felt.py", "key = pose_key(candidates.pinches, int(pose))", "drop int(...)"):
        "a numpy integer indexes the contacts as an int does: the key's bytes are the same",
    ("grasp/tripods.py", "phi = rng.random(len(ray)) * 2.0 * np.pi", "2.0 -> 4.0"):
        "an angle uniform over two turns is uniform over one: its cosine and sine take the same "
        "distribution",
    ("mesh/support.py", 'return SupportPlane(normal, float(support), "support_mm")',
     "drop float(...)"):
        "a whole-number height computes as its float does, and the plane's record writes "
        "float(...) of it",
    ("match/trust.py", "var = draws_variance(np.stack([feature_table(f) for f in noisy_features(",
     "drop .stack(...)"):
        "numpy takes the list of the draws' tables as the array they stack into",
    ("match/trust.py", "return spread_terms(least(tangible.table[poses], var), var, "
     "np.zeros_like(var), 1.0, model)", "1.0 -> 2.0"):
        "the virtual variance is 0 here: the mass ratio scales nothing",
    ("match/trust.py", "return separable_terms(t_rows, t_rows + spread, model)", "+ -> -"):
        "a difference of -spread squares as +spread does, and the scales are the tangible rows'",
    ("grasp/scan_noise.py", "DRAWS = 16", "16 -> 17"):
        "the count of draws sets how precise the spread's estimate is, not what it estimates: one "
        "more draw moves it within the tests' tolerances",
    ("grasp/scan_noise.py", "points = grasps.points.reshape(-1, 3)", "1 -> 2"):
        "numpy infers a negative size whatever its value: reshape(-2, 3) is reshape(-1, 3)",
    ("grasp/strata.py", "return int(STRATUM_SHARE * count // max(strata, 1))", "// -> /"):
        "int() of a positive quotient is its floor: dividing and flooring first gives the same "
        "whole number",
    ("mesh/furniture.py",
     "tops[other] = max(tops.get(other, -np.inf), float(np.median(closest[on] @ up)))",
     "drop float(...)"): "numpy's float64 is a Python float: the same number, written to JSON the "
                         "same way",
    ("mesh/facing.py", "parts = int(labels.max()) + 1 if len(labels) else 0", "0 -> 1"):
        "a mesh with no faces never comes here: the loader refuses it first",
    ("match/rest.py", "c = centroids[start:start + GAP_CHUNK // 16]", "16 -> 17"):
        "a chunk size only: each centroid's reach is computed alike in any chunk",
    ("match/rest.py", "transforms = np.asarray(transforms, dtype=np.float64)",
     "drop .asarray(...)"): _SAME_TYPE,
    ("match/pairs.py", "return np.full(len(asked), -1)", "1 -> 2"):
        "callers read any negative position as not found (< 0, >= 0): -2 is read as -1 is",
})

BINOPS = {ast.Add: ast.Sub, ast.Sub: ast.Add, ast.Mult: ast.Div, ast.Div: ast.Mult,
          ast.Pow: ast.Mult, ast.FloorDiv: ast.Div, ast.Mod: ast.FloorDiv}
COMPARES = {ast.Lt: ast.LtE, ast.LtE: ast.Lt, ast.Gt: ast.GtE, ast.GtE: ast.Gt, ast.Eq: ast.NotEq,
            ast.NotEq: ast.Eq, ast.Is: ast.IsNot, ast.IsNot: ast.Is, ast.In: ast.NotIn,
            ast.NotIn: ast.In}
SYMBOL = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "**",
          ast.FloorDiv: "//", ast.Mod: "%", ast.Lt: "<", ast.LtE: "<=", ast.Gt: ">", ast.GtE: ">=",
          ast.Eq: "==", ast.NotEq: "!=", ast.Is: "is", ast.IsNot: "is not", ast.In: "in",
          ast.NotIn: "not in", ast.And: "and", ast.Or: "or"}


@dataclass(frozen=True)
class Mutant:
    module: str
    index: int  # among the module's mutation sites, in source order
    line: int
    description: str

    def label(self) -> str:
        return f"{self.module}:{self.line} {self.description}"


def _skipped_nodes(tree: ast.AST) -> set[int]:
    """ids of nodes never mutated: docstrings, annotations, decorators, and what lies inside
    them."""
    skip: set[int] = set()

    def cover(node):
        if node is not None:
            skip.update(id(n) for n in ast.walk(node))

    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            body = node.body
            if body and isinstance(body[0], ast.Expr) and isinstance(body[0].value, ast.Constant):
                cover(body[0])
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            cover(node.returns)
            for d in node.decorator_list:
                cover(d)
            for a in node.args.args + node.args.kwonlyargs + node.args.posonlyargs:
                cover(a.annotation)
        if isinstance(node, ast.ClassDef):
            for d in node.decorator_list:
                cover(d)
        if isinstance(node, ast.AnnAssign):
            cover(node.annotation)
        if isinstance(node, ast.JoinedStr):
            cover(node)
    return skip


def _sites(tree: ast.AST, source_lines: list[str]):
    """Every (node, kind, description) that can be mutated, in source order."""
    skip = _skipped_nodes(tree)
    found = []
    for node in ast.walk(tree):
        if id(node) in skip or not hasattr(node, "lineno"):
            continue
        if "pragma: no mutate" in source_lines[node.lineno - 1]:
            continue
        if isinstance(node, ast.BinOp) and type(node.op) in BINOPS:
            found.append((node, "binop",
                          f"{SYMBOL[type(node.op)]} -> {SYMBOL[BINOPS[type(node.op)]]}"))
        elif isinstance(node, ast.AugAssign) and type(node.op) in BINOPS:
            found.append((node, "augassign",
                          f"{SYMBOL[type(node.op)]}= -> {SYMBOL[BINOPS[type(node.op)]]}="))
        elif isinstance(node, ast.Compare):
            for k, op in enumerate(node.ops):
                if type(op) in COMPARES:
                    found.append((node, f"compare{k}",
                                  f"{SYMBOL[type(op)]} -> {SYMBOL[COMPARES[type(op)]]}"))
        elif isinstance(node, ast.BoolOp):
            other = "or" if isinstance(node.op, ast.And) else "and"
            found.append((node, "boolop", f"{SYMBOL[type(node.op)]} -> {other}"))
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.Not)):
            operand = ast.unparse(node.operand)  # which minus, where a line has several
            found.append((node, "unary",
                          "drop " + ("-" if isinstance(node.op, ast.USub) else "not ")
                          + operand[:40]))
        elif isinstance(node, ast.Call) and _wraps(node):
            name = node.func.id if isinstance(node.func, ast.Name) else "." + node.func.attr
            found.append((node, "call", f"drop {name}(...)"))
        elif isinstance(node, ast.Constant):
            v = node.value
            if isinstance(v, bool):
                found.append((node, "const", f"{v} -> {not v}"))
            elif isinstance(v, (int, float)) and not isinstance(v, complex):
                found.append((node, "const", f"{v!r} -> {_new_number(v)!r}"))
        if isinstance(node, ast.BinOp) and _index_pair(node) is not None:
            a, b = _index_pair(node)
            found.append((node, "swapindex", f"swap [{a.value}] and [{b.value}]"))
    found.sort(key=lambda s: (s[0].lineno, s[0].col_offset, s[1]))
    return found


def _wraps(node: ast.Call) -> bool:
    """A call that wraps a value: its first argument positional and not starred (``abs(x)``, ``f(x,
    r)``)."""
    return (isinstance(node.func, (ast.Name, ast.Attribute)) and bool(node.args)
            and not isinstance(node.args[0], ast.Starred))


def _index_literals(node: ast.AST) -> list[ast.Constant]:
    """The integer literals that index a subscript within ``node`` (``a[1]``, ``a[:, 1]``), in
    source order."""
    found = []
    for sub in ast.walk(node):
        if isinstance(sub, ast.Subscript):
            parts = sub.slice.elts if isinstance(sub.slice, ast.Tuple) else [sub.slice]
            found += [p for p in parts if isinstance(p, ast.Constant) and type(p.value) is int]
    return sorted(found, key=lambda c: (c.lineno, c.col_offset))


def _index_pair(node: ast.BinOp):
    """The first index literal of each side of a binary operation, where the two differ."""
    left, right = _index_literals(node.left), _index_literals(node.right)
    if left and right and left[0].value != right[0].value:
        return left[0], right[0]
    return None


def _new_number(v):
    if isinstance(v, int):
        return v + 1
    return 1.0 if v == 0.0 else v * 2.0


def _apply(node: ast.AST, kind: str) -> None:
    if kind in ("binop", "augassign"):
        node.op = BINOPS[type(node.op)]()
    elif kind.startswith("compare"):
        k = int(kind[len("compare"):])
        node.ops[k] = COMPARES[type(node.ops[k])]()
    elif kind == "boolop":
        node.op = ast.Or() if isinstance(node.op, ast.And) else ast.And()
    elif kind == "const":
        node.value = (not node.value) if isinstance(node.value, bool) else _new_number(node.value)
    elif kind == "swapindex":
        a, b = _index_pair(node)
        a.value, b.value = b.value, a.value


class _Drop(ast.NodeTransformer):
    """Replaces one node by its operand (a unary operation) or its first argument (a call)."""

    def __init__(self, target):
        self.target = target

    def visit_UnaryOp(self, node):
        if node is self.target:
            return self.generic_visit(node).operand
        return self.generic_visit(node)

    def visit_Call(self, node):
        if node is self.target:
            return self.generic_visit(node).args[0]
        return self.generic_visit(node)


def enumerate_mutants(module: str, package: Path = PACKAGE) -> list[Mutant]:
    source = (package / module).read_text()
    sites = _sites(ast.parse(source), source.splitlines())
    return [Mutant(module, i, node.lineno, desc) for i, (node, _, desc) in enumerate(sites)]


def mutated_source(mutant: Mutant, package: Path = PACKAGE) -> str:
    source = (package / mutant.module).read_text()
    tree = ast.parse(source)
    node, kind, _ = _sites(tree, source.splitlines())[mutant.index]
    if kind in ("unary", "call"):
        tree = _Drop(node).visit(tree)
    else:
        _apply(node, kind)
    return ast.unparse(ast.fix_missing_locations(tree))


def _copy_repository(target: Path) -> None:
    ignore = shutil.ignore_patterns(".git", ".venv", "__pycache__", "*.egg-info", ".pytest_cache",
                                    ".hypothesis")
    for name in ("src", "tests", "docs", "benchmarks", "README.md", "pyproject.toml"):
        # tests read the docs and
        # import the benchmarks' asset readers
        src = ROOT / name
        if src.is_dir():
            shutil.copytree(src, target / name, ignore=ignore)
        else:
            shutil.copy2(src, target / name)


def _pytest(workdir: Path, tests: list[str], timeout_s: float | None) -> tuple[str, float]:
    env = dict(os.environ, PYTHONPATH=str(workdir / "src"), PINCHMATCH_FUZZ_EXAMPLES="10",
               PYTHONDONTWRITEBYTECODE="1")
    cmd = [sys.executable, "-m", "pytest", "-x", "-q", "-p", "no:cacheprovider", "-o", "addopts=",
           *[str(workdir / "tests" / t) for t in tests]]
    start = time.perf_counter()
    try:
        done = subprocess.run(cmd, cwd=workdir, env=env, capture_output=True, timeout=timeout_s)
    except subprocess.TimeoutExpired:
        return "timeout", time.perf_counter() - start
    return ("passed" if done.returncode == 0 else "failed"), time.perf_counter() - start


class Worker:
    """A private copy of the repository in which one mutant at a time is planted."""

    def __init__(self, base: Path, k: int):
        self.dir = base / f"worker{k}"
        _copy_repository(self.dir)

    def run(self, mutant: Mutant, tests: list[str], timeout_s: float) -> str:
        path = self.dir / "src" / "pinchmatch" / mutant.module
        original = path.read_text()
        try:
            path.write_text(mutated_source(mutant, self.dir / "src" / "pinchmatch"))
            outcome, _ = _pytest(self.dir, tests, timeout_s)
        finally:
            path.write_text(original)
        return "survived" if outcome == "passed" else "killed"


def _clean_times(worker: Worker, modules: list[str]) -> dict[str, float]:
    times = {}
    for module in modules:
        outcome, seconds = _pytest(worker.dir, CORE[module], None)
        if outcome != "passed":
            raise SystemExit(f"mutation: the tests of {module} fail without any mutant; fix them "
                             "first")
        times[module] = seconds
    return times


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--modules", help="comma-separated modules (default: every core module)")
    parser.add_argument("--sample", type=int, default=30,
                        help="mutants per module, 0 for all (default 30)")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--fail-under", type=float, default=0.0, metavar="PCT",
                        help="exit 1 when fewer than PCT %% of the non-equivalent mutants are "
                             "killed")
    args = parser.parse_args(argv)
    modules = args.modules.split(",") if args.modules else list(CORE)
    unknown = [m for m in modules if m not in CORE]
    if unknown:
        parser.error(f"unknown module(s) {', '.join(unknown)}; choose from {', '.join(CORE)}")

    with tempfile.TemporaryDirectory(prefix="pinchmatch-mutation-") as tmp:
        # the copies are the source of the mutants: the working tree may change while the run goes
        # on
        workers = [Worker(Path(tmp), k) for k in range(max(1, args.workers))]
        package = workers[0].dir / "src" / "pinchmatch"
        plan: list[Mutant] = []
        totals = {}
        for module in modules:
            every = enumerate_mutants(module, package)
            totals[module] = len(every)
            chosen = every if args.sample <= 0 or args.sample >= len(every) else sorted(
                random.Random(f"{args.seed}:{module}").sample(every, args.sample),
                key=lambda m: m.index)
            plan.extend(chosen)
        sources = {module: (package / module).read_text().splitlines() for module in modules}
        clean = _clean_times(workers[0], modules)
        free = list(workers)
        results: dict[Mutant, str] = {}
        with cf.ThreadPoolExecutor(len(workers)) as pool:
            pending = {}
            queue = list(plan)
            while queue or pending:
                while queue and free:
                    m, w = queue.pop(0), free.pop()
                    timeout = 5.0 * clean[m.module] + 10.0
                    pending[pool.submit(w.run, m, CORE[m.module], timeout)] = (m, w)
                done, _ = cf.wait(pending, return_when=cf.FIRST_COMPLETED)
                for f in done:
                    m, w = pending.pop(f)
                    results[m] = f.result()
                    free.append(w)
                    print(f"  {results[m]:8s} {m.label()}", file=sys.stderr, flush=True)

    print("\n| module | mutants | sampled | equivalent | killed | survived | killed % |\n"
          "|---|---:|---:|---:|---:|---:|---:|")
    all_killed = all_run = 0
    survivors = []
    for module in modules:
        mine = [m for m in plan if m.module == module]
        lines = sources[module]
        equivalent = [m for m in mine if results[m] == "survived"
                      and (module, lines[m.line - 1].strip(), m.description) in EQUIVALENT]
        killed = sum(results[m] == "killed" for m in mine)
        run = len(mine) - len(equivalent)
        all_killed, all_run = all_killed + killed, all_run + run
        survivors += [m for m in mine if results[m] == "survived" and m not in equivalent]
        share = 100.0 * killed / run if run else 100.0
        print(f"| {module} | {totals[module]} | {len(mine)} | {len(equivalent)} | {killed} | "
              f"{run - killed} "
              f"| {share:.0f} |")
    share = 100.0 * all_killed / max(all_run, 1)
    print(f"| **all** | {sum(totals.values())} | {len(plan)} | {len(plan) - all_run} | "
          f"{all_killed} | "
          f"{all_run - all_killed} | {share:.0f} |")
    if survivors:
        print("\nsurvivors:")
        for m in survivors:
            print(f"  {m.label()}    {sources[m.module][m.line - 1].strip()}")
    if share < args.fail_under:
        print(f"\nmutation: {share:.0f} % killed, under the --fail-under {args.fail_under:g} %",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
