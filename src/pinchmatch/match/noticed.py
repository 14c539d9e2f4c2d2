"""What a choice's remaining difference is, criterion by criterion, in just-noticeable differences.

The search (:mod:`pinchmatch.match.search`) ranks choices by the run's cost; the documents and the
felt cost report each choice's difference per criterion in JND (the literature's thresholds, every
weight 1), the probability that a person notices it under the run's pooling, and how far each
virtual fingertip sits from the prop's contact along the pinch line.
"""

from __future__ import annotations

import numpy as np

from ..grasp.spread import other_order
from .candidates import Candidates, pair_terms
from .cost import CRITERIA, CostModel
from .search import Choice


def contact_offset_mm(tangible: Candidates, virtual: Candidates, choice: Choice) -> float:
    """(w_V - w_T) / 2: each virtual fingertip's offset from the tangible contact along the pinch
    line."""
    return float(virtual.features.width_mm[choice.v_pose]
                 - tangible.features.width_mm[choice.t_pose]) / 2.0


def jnd_terms(tangible: Candidates, virtual: Candidates, choice: Choice) -> np.ndarray:
    """(8,) each criterion's contribution for a choice in just-noticeable differences (JND²)."""
    v_row = virtual.table[choice.v_pose][None]
    jnd_model = CostModel(normalize="jnd", criteria=CRITERIA, weights=dict.fromkeys(CRITERIA, 1.0))
    if choice.swapped:
        v_row = v_row[:, other_order(v_row.shape[1])]
    return pair_terms(tangible, virtual, tangible.table[choice.t_pose][None], v_row,
                      jnd_model, delta=choice.mass_delta_mm[None])[0][0]


def p_noticed(tangible: Candidates, virtual: Candidates, choice: Choice, model: CostModel) -> float:
    """The probability that the choice's remaining difference is noticed: the model's criteria,
    weights and pooling, in JND (:meth:`pinchmatch.match.cost.CostModel.p_noticed`), with the hand's
    redirection where the placement is fixed."""
    jnd_model = model.as_jnd()
    return float(jnd_model.p_noticed(jnd_model.pool(jnd_terms(tangible, virtual, choice),
                                                    extra=choice.redirect_terms)))


def criterion_table(tangible: Candidates, virtual: Candidates, choice: Choice,
                    model: CostModel) -> dict:
    """Per criterion in use: weight, contribution (in the run's normalisation), the difference in
    just-noticeable differences (root mean square over the criterion's entries) and ``noticeable``
    (that criterion alone at 1 JND or more)."""
    jnd = jnd_terms(tangible, virtual, choice)
    out = {}
    for k, c in enumerate(CRITERIA):
        if c not in model.criteria:
            continue
        size = float(np.sqrt(jnd[k]))
        out[c] = {"weight": model.weights[c], "contribution": float(choice.terms[k]), "jnd": size,
                  "noticeable": bool(size >= 1.0)}
    return out
