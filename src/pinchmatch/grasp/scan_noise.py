"""How far a scanned prop's patch features can be trusted: their spread at the scan's error.

A prop made from a phone scan (``pinchmatch prop import``) carries the error its smoothing left,
``noise_mm`` RMS along the normal (the manifest's ``scan.residual_mm``). The surface kept is one
draw of that error: another scan of the same object would have given other normals and curvatures
under the same fingertip. This module measures how much, per pose, by Monte Carlo on the fit the
features come from:

- each draw moves every sample of the surface's dense sample (:class:`~pinchmatch.mesh.surface.
  SurfaceSample`, about 120 in an 8 mm patch, 1.3 mm apart) along its normal by an independent
  Gaussian of ``noise_mm``. A documented choice: the error a smoothing leaves is correlated over
  a few of the scan's vertex spacings (ten Taubin passes at a phone scan's 0.3 to 0.5 mm), about
  the sample's spacing, so a patch holds about as many independent errors as the sample has
  points;
- the patches of the pose's contacts are fitted again on each draw (:func:`~pinchmatch.grasp.
  curvature.patch_geometry`, the neighbours of the unmoved sample: a draw moves a sample by far less
  than a patch radius), and each contact moves onto the fitted surface along its own normal (the
  width a fingertip pad, pressing over the patch, feels);
- the pose's features are computed from each draw as from the prop itself.

The draws are fixed (seeded by ``seed`` alone): the same pose gets the same spread in every run.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from .curvature import patch_geometry
from .features import PinchFeatures, grasp_features
from .pinches import Pinches
from ..mesh.properties import ObjectProperties
from ..mesh.surface import SurfaceContext

#: Monte Carlo draws of the scan's noise per pose: the spread's relative error is about
#: 1 / sqrt(2 (draws - 1)), 18 % at 16
DRAWS = 16
#: the draws' seed
SEED = 0
#: a scan noise below this (mm RMS) is no scan noise: no draws, a spread of 0
NOISE_FLOOR_MM = 1e-3


class _Context:
    """A surface context whose dense sample has been moved (the unmoved tree kept)."""

    def __init__(self, context: SurfaceContext, sample):
        self.tree, self.sample, self.patch_radius_mm = context.tree, sample, context.patch_radius_mm


def noisy_features(context: SurfaceContext, grasps: Pinches, props: ObjectProperties,
                   noise_mm: float, *, draws: int = DRAWS, seed: int = SEED) -> list[PinchFeatures]:
    """The features of ``grasps`` (pinches or tripods) on ``draws`` copies of the surface, each with
    its own draw of Gaussian noise of ``noise_mm`` along the normal (module notes).

    Parameters
    ----------
    context : SurfaceContext
        The prop's surface.
    grasps : Pinches
        The poses (a :class:`~pinchmatch.grasp.tripod_rules.Tripods` for tripods).
    props : ObjectProperties
        The prop's centre of mass and axis (not redrawn: the scan's volume is in the mass
        properties, which the noise moves by far less than a JND).
    noise_mm : float
        The scan's noise, RMS along the normal.
    draws, seed : int
        How many draws, and their seed.

    Returns
    -------
    list of PinchFeatures
        One per draw, in draw order.
    """
    sample = context.sample
    rng = np.random.default_rng(seed)
    n, fingers = grasps.points.shape[:2]
    points = grasps.points.reshape(-1, 3)
    normals = grasps.normals.reshape(-1, 3)
    out = []
    for _ in range(draws):
        moved = sample.points + sample.normals * (noise_mm * rng.standard_normal(
            len(sample.points)))[:, None]
        geom = patch_geometry(_Context(context, dataclasses.replace(sample, points=moved)),
                              points, normals)
        # each contact onto the fitted surface, along its own normal
        offset = np.einsum("kd,kd->k", geom.point_mm - points, normals)
        drawn = dataclasses.replace(
            grasps, points=(points + offset[:, None] * normals).reshape(n, fingers, 3),
            normals=geom.normal.reshape(n, fingers, 3),
            kappa_max_per_m=geom.kappa_max_per_m.reshape(n, fingers),
            kappa_min_per_m=geom.kappa_min_per_m.reshape(n, fingers),
            dir_max=geom.dir_max.reshape(n, fingers, 3))
        out.append(grasp_features(drawn, props))
    return out
