"""The study plan the headset page runs: ``OUT/study_plan.json``, written by ``pinchmatch demo``.

The method's study rated, for each of its 18 pose pairs (3 tangible pinches x 6 virtual objects),
two algorithms' placements: its own (``paper``) and ``Ref``, the virtual object superimposed on the
prop. The 36 trials form a block, shown in a random order; each block is run three times: 108
trials. The plan keeps that design with a seeded order (a block's order is a permutation drawn by
numpy's ``default_rng(seed)``, one per repetition), and any of the three placements of the demo
(``ours``, ``paper``, ``ref``) may be chosen.

A plan holds ``pairs`` (each pose pair shown: the virtual object, where the fingers go on the prop,
the rigid transform that places the virtual object, its cost and its difference per criterion in
JND) and ``trials`` in the order to run them. The page writes one CSV row per trial (docs/study.md);
the CSV's ``<criterion>_jnd`` columns come from the pair, so ``pinchmatch calibrate`` reads it as
is.
"""

from __future__ import annotations

import numpy as np

from ..errors import ConfigError
from ..version import __version__

SCHEMA_PLAN = "pinchmatch.study-plan/1"
#: the placements a study row offers
SOURCES = ("ours", "paper", "ref")
#: the method's own design: its algorithm against Ref, three repetitions of the block
METHOD_SOURCES = ("paper", "ref")
METHOD_REPETITIONS = 3


def study_plan(rows: list, virtual_names: list[str], *, seed: int, sources: tuple = METHOD_SOURCES,
               repetitions: int = METHOD_REPETITIONS) -> dict:
    """The plan of a study's rows (``run_study``'s): every row x source a pair, each block of pairs
    shuffled with ``seed``, ``repetitions`` blocks. ``virtual_names``: the name of virtual object
    ``k`` (1-based in a row's ``virtual``) as the matches document names it, so the page finds its
    scene."""
    unknown = [s for s in sources if s not in SOURCES]
    if unknown or not sources:
        raise ConfigError(f"study sources {', '.join(unknown) or 'none'}: choose from "
                          f"{', '.join(SOURCES)}")
    if repetitions < 1:
        raise ConfigError(f"study repetitions {repetitions}: give 1 or more")
    pairs = []
    for row in rows:
        for source in sources:
            pose = row[source]
            if pose.get("transform_virtual_to_tangible") is None or pose.get("cost") is None:
                continue  # no placement (Ref's line missed the object): nothing to show
            pairs.append({
                "pair": len(pairs),
                "virtual": virtual_names[row["virtual"] - 1],
                "pose_source": source,
                "tangible_part": row["tangible_part"],
                "tangible_contacts_mm": row["tangible_contacts_mm"],
                "virtual_contacts_mm": pose["contacts_mm"],
                **({"tangible_p1_mm": row["tangible_p1_mm"],
                    "tangible_p2_mm": row["tangible_p2_mm"], "virtual_p1_mm": pose["p1_mm"],
                    "virtual_p2_mm": pose["p2_mm"]} if "p1_mm" in pose else {}),
                "finger_order_swapped": pose["finger_order_swapped"],
                "transform_virtual_to_tangible": pose["transform_virtual_to_tangible"],
                "flipped": pose["flipped"],
                "cost": pose["cost"],
                "criteria_jnd": pose["criteria_jnd"],
            })
    rng = np.random.default_rng(seed)
    trials = []
    for repetition in range(1, repetitions + 1):
        for k in rng.permutation(len(pairs)):
            pair = pairs[int(k)]
            trials.append({"trial": len(trials) + 1, "pair": pair["pair"],
                           "virtual": pair["virtual"], "pose_source": pair["pose_source"],
                           "repetition": repetition})
    return {"schema": SCHEMA_PLAN, "version": __version__, "seed": seed, "sources": list(sources),
            "repetitions": repetitions,
            "question": "How much does the tangible object correspond to the "
            "virtual one?", "scale": {"min": 1, "max": 7, "labels": ["not at all", "perfectly"]},
            "pairs": pairs, "trials": trials}
