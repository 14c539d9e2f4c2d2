"""What the pooling changes on real objects: probability summation against the sum of squares.

    python benchmarks/bench_pooling.py            # 5 props x 40 virtual objects (about 2 minutes)
    python benchmarks/bench_pooling.py --quick    # 5 props x 10 virtual objects
    python benchmarks/bench_pooling.py --detail   # also one line per object whose best prop changes

The scene is ``bench_scale.py``'s: pybullet_data's ``random_urdfs`` 000-039 as virtual objects and
995-999 as props (third-party meshes, about 16k faces each, read from the wheel on PyPI). Each
object is matched twice from one feature cache, so both runs see the same candidate poses: with
``--pooling quick`` (the default: Quick pooling of the criteria in JND, beta 3.5) and with
``--pooling sum`` (the sum of squared JNDs), both with the default criteria and seed; once with the
sampled search alone (``--refine off``, the exact answer over the same poses) and once by default
(refined).

Per setting it prints how many objects get another best prop and how many keep the very same pose
pair; of the objects whose best prop changes, how many get a smaller largest criterion (the
difference a hand notices first) and how many answers are at least as good as the other run's under
their own pooling (an exact search always is; refinement finds local optima); and over all objects
the mean and median largest criterion and the largest ``p_noticed`` of each pooling's answers (both
in the default's form, so that the two are comparable).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).parent))
from assets import random_objects  # noqa: E402

#: the pooling exponents: Quick pooling's beta, and the sum of squares' 2
BETAS = {"quick": 3.5, "sum": 2.0}


def match(tangibles, virtuals, pooling: str, refine: bool, cache: Path, out: Path) -> dict:
    """{virtual name: its entry of matches.json} of one ``pinchmatch match`` run."""
    argv = [sys.executable, "-m", "pinchmatch", "match", "--tangible", *map(str, tangibles),
            "--virtual", *map(str, virtuals), "--pooling", pooling, "--cache", str(cache),
            "--no-view", "--no-figures", "-q", "-o", str(out)]
    if not refine:
        argv += ["--refine", "off"]
    proc = subprocess.run(argv, capture_output=True, text=True)
    if proc.returncode not in (0, 3):
        raise SystemExit(f"match failed ({proc.returncode}): {proc.stderr.strip()}")
    return {m["virtual"]: m for m in json.loads((out / "matches.json").read_text())["matches"]}


def jnds(m: dict) -> np.ndarray:
    return np.array([c["jnd"] for c in m["criteria"].values()])


def pooled(m: dict, pooling: str) -> float:
    """The match's cost under a pooling, from its criteria in JND (weights 1), in JND."""
    beta = BETAS[pooling]
    return float((jnds(m) ** beta).sum() ** (1.0 / beta))


def noticed(m: dict) -> float:
    """The match's p_noticed in the default form (probability summation, 1 JND noticed half of the
    time)."""
    return float(1.0 - 2.0 ** -(pooled(m, "quick") ** BETAS["quick"]))


def compare(quick: dict, summed: dict, detail: bool) -> dict:
    """The row of one setting: the two runs' answers side by side."""
    changed = [k for k in quick if quick[k]["tangible"] != summed[k]["tangible"]]
    same_pair = sum(quick[k]["tangible"] == summed[k]["tangible"]
                    and quick[k]["tangible_pose"] == summed[k]["tangible_pose"]
                    and quick[k]["virtual_pose"] == summed[k]["virtual_pose"] for k in quick)
    smaller = own_q = own_s = 0
    for k in changed:
        q, s = quick[k], summed[k]
        smaller += jnds(q).max() < jnds(s).max()
        own_q += pooled(q, "quick") <= pooled(s, "quick") + 1e-12
        own_s += pooled(s, "sum") <= pooled(q, "sum") + 1e-12
        if detail:
            print(f"  {k}: sum {s['tangible']} -> quick {q['tangible']}; largest criterion "
                  f"{jnds(s).max():.3f} -> {jnds(q).max():.3f} JND; quick cost "
                  f"{pooled(s, 'quick'):.4f} -> "
                  f"{pooled(q, 'quick'):.4f}; sum cost {pooled(s, 'sum'):.4f} -> "
                  f"{pooled(q, 'sum'):.4f}")
    largest_q = np.array([jnds(m).max() for m in quick.values()])
    largest_s = np.array([jnds(m).max() for m in summed.values()])
    return {"changed": len(changed), "same_pair": same_pair, "smaller": smaller, "own_q": own_q,
            "own_s": own_s, "mean": (largest_s.mean(), largest_q.mean()),
            "median": (np.median(largest_s), np.median(largest_q)),
            "p": (max(noticed(m) for m in summed.values()),
                  max(noticed(m) for m in quick.values()))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="10 virtual objects instead of 40")
    parser.add_argument("--detail", action="store_true",
                        help="one line per object whose best prop changes")
    args = parser.parse_args()
    n = 10 if args.quick else 40
    with tempfile.TemporaryDirectory(prefix="bench_pooling_") as tmp:
        root = Path(tmp)
        virtuals = random_objects(root / "v", range(n))
        tangibles = random_objects(root / "t", range(995, 1000))
        rows = []
        for label, refine in (("sampled (--refine off)", False), ("default (refined)", True)):
            runs = {p: match(tangibles, virtuals, p, refine, root / "cache",
                             root / f"{p}-{refine}") for p in BETAS}
            if args.detail:
                print(f"{label}:")
            rows.append((label, compare(runs["quick"], runs["sum"], args.detail)))
    print(f"\n# {len(tangibles)} props x {n} virtual objects (pybullet_data random_urdfs), "
          "--pooling sum -> quick")
    print(f"{'setting':<24} {'other prop':>10} {'same pair':>9} {'smaller max':>11} "
          f"{'own best q/s':>12} "
          f"{'max JND mean':>14} {'max JND median':>15} {'largest p_noticed':>17}")
    for label, r in rows:
        print(f"{label:<24} {r['changed']:>10} {r['same_pair']:>9} {r['smaller']:>11} "
              f"{r['own_q']:>5}/{r['own_s']:<6} {r['mean'][0]:>6.3f}->{r['mean'][1]:.3f} "
              f"{r['median'][0]:>7.3f}->{r['median'][1]:.3f} {r['p'][0]:>10.3f}->{r['p'][1]:.3f}")
    print("other prop: objects whose best prop differs; same pair: the very same pose pair; "
          "smaller max: of the "
          "former, those whose largest criterion (JND) is smaller under quick; own best q/s: of "
          "the former, the quick "
          "answer's quick cost at most the sum answer's / the sum answer's sum cost at most the "
          "quick answer's")


if __name__ == "__main__":
    main()
