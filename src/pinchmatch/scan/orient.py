"""Which way a scanned point cloud's surface faces: each normal turned toward the outside the
scanner saw it from.

A point cloud's normals are estimated from each point's neighbours, which gives their line but not
their sign. The usual way to choose the sign, propagating it from neighbour to neighbour, crosses a
thin wall: a mug's wall of 1 to 6 mm, scanned with 0.5 mm of noise, has its two sides' points in
each other's neighbourhoods, so both sides come out facing the same way, and the surface rebuilt
from them is a sheet turned inside out. Here the sign comes from where the outside is instead:

- **The outside:** the cloud's points fill the cells of a grid (``CELL_SPACINGS`` of the cloud's
  point spacing wide), grown by ``SEAL_MM`` so that the gaps a scan leaves between its points are
  sealed. The cells at and below the lowest point are closed too: the object stood there on a
  table, and a scan never sees under it, so the bottom is open (the scan's up is +Z). So are the
  cells under the object up to ``UNSEEN_MM`` above the table: a scan misses the lowest few mm of
  its sides too, and a mug's inside floor, seen from above, can be its lowest point, below where
  its outer wall was last seen. The outside is every empty cell connected to the grid's border
  (:func:`scipy.ndimage.label`): the air round the object, and a cup's inside through its mouth.
- **The sign:** along each point's normal line, both ways, probes every ``PROBE_STEP_MM`` find the
  nearest outside cell. The normal is turned toward the nearer. On a solid's skin the outside lies
  on one side only; on a thin wall it lies on both, and the nearer is the side of the wall the
  point was scanned from (a point that the noise carried past the wall's middle is turned the other
  way, as any rule from positions alone must).
- **A base scanned from below too** (the object turned over for a second pass): the hollow under
  it is closed by the table above, so its points reach no outside. Those points are probed again
  with the table left out, and the hollow opens onto the room.
- **Settled by regions:** the normals come in with signs propagated from neighbour to neighbour
  (MeshLab's), right relative to each other over a solid's skin and wrong only across thin walls.
  Neighbours (``VOTE_NEIGHBOURS``) whose given normals agree (within about 60 degrees) and whose
  probes do not contradict each other form a region. A region whose probes agree (all but
  ``SPLIT_SHARE``) is turned as most of them say, every point of it: a probe misled in a crevice
  narrower than the seal, or a point both of whose sides are as near, follows its region. A region
  whose probes disagree more is a thin wall's two sides joined: there each point keeps its own
  probe, and a point whose probes cannot tell takes the sign most of its nearest points agree
  with, round after round until no sign changes (at most ``VOTE_ROUNDS``).
- **How sure:** the share of points whose outside lies as near on both sides (within
  ``UNSURE_MM``): on a wall about as thin as the noise is wide, a point's side is a guess. The
  import refuses a cloud where too many are (:mod:`pinchmatch.scan.surface`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components
from scipy.spatial import cKDTree

#: a grid cell is this many of the cloud's point spacings wide (the median distance to the nearest
#: point), at least ``MIN_CELL_MM``, and at most ``MAX_CELLS`` cells along the longest extent
CELL_SPACINGS, MIN_CELL_MM, MAX_CELLS = 1.5, 0.5, 400
#: the occupied cells are grown by this much, sealing gaps between the scan's points of up to about
#: twice it
SEAL_MM = 1.5
#: the probes' step along the normal line, and how far past the sealed band they reach
PROBE_STEP_MM, PROBE_BEYOND_MM = 0.25, 6.0
#: the nearest points a point is joined to in a region, or votes among, and at most this many rounds
#: of votes (each carries a sign about one point spacing further)
VOTE_NEIGHBOURS, VOTE_ROUNDS = 10, 500
#: neighbours are in one region where their given normals are within about 60 degrees
REGION_COS = 0.5
#: a region whose decided points disagree more than this share is split: a thin wall's two sides
SPLIT_SHARE = 0.1
#: how high above the table a scan may have seen nothing under the object (:func:`_outside`)
UNSEEN_MM = 5.0
#: a point whose outside lies as near on both sides, within this, is on a wall too thin for its
#: noise to tell which side it was scanned from (:class:`Faced`)
UNSURE_MM = 0.5


@dataclass(frozen=True)
class Faced:
    """A cloud's normals turned to face out (n, 3; their lines kept), and the share of its points
    on walls too thin for the probes to tell their sides apart (the outside on both sides within
    ``UNSURE_MM`` of each other)."""

    normals: np.ndarray
    unsure: float


def outward_normals(points: np.ndarray, normals: np.ndarray) -> Faced:
    """``normals`` (n, 3) of the cloud ``points`` (n, 3, mm, up along +Z), each turned to face the
    outside (see the module notes), and how sure that is.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> ball = rng.normal(size=(20000, 3))
    >>> ball = 30.0 * ball / np.linalg.norm(ball, axis=1, keepdims=True)
    >>> signs = np.where(rng.random(20000) < 0.5, -1.0, 1.0)[:, None]
    >>> faced = outward_normals(ball + 100.0, signs * ball / 30.0)
    >>> bool(np.all(np.einsum("ij,ij->i", faced.normals, ball) > 0)), faced.unsure
    (True, 0.0)
    """
    points = np.asarray(points, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    tree = cKDTree(points)
    spacing = float(np.median(tree.query(points, k=2)[0][:, 1]))
    cell = max(CELL_SPACINGS * spacing, MIN_CELL_MM,
               float(np.ptp(points, axis=0).max()) / MAX_CELLS)
    grow = int(np.ceil(SEAL_MM / cell))
    reach = 2.0 * grow * cell + PROBE_BEYOND_MM
    sign, unsure = _toward_nearer(points, normals, *_outside(points, cell, grow, table=True),
                                  cell, reach)
    undecided = np.flatnonzero(sign == 0)
    if len(undecided):  # a base scanned from below too: its hollow opens onto the room
        sign[undecided] = _toward_nearer(points[undecided], normals[undecided],
                                         *_outside(points, cell, grow, table=False), cell,
                                         reach)[0]
    sign = _by_regions(tree, normals, sign)
    return Faced(normals * np.where(sign < 0, -1.0, 1.0)[:, None], float(np.mean(unsure)))


def _toward_nearer(points: np.ndarray, normals: np.ndarray, outside: np.ndarray,
                   origin: np.ndarray, cell: float, reach: float) -> tuple[np.ndarray, np.ndarray]:
    """(n,) +1 where the outside is nearer along each normal than against it, -1 where it is
    nearer against it, 0 where they are as near (or neither is within ``reach``); and (n,) whether
    the outside lies on both sides within ``UNSURE_MM`` of each other."""
    ahead = _nearest_outside(points, normals, outside, origin, cell, reach)
    behind = _nearest_outside(points, -normals, outside, origin, cell, reach)
    both = np.isfinite(ahead) & np.isfinite(behind)
    gap = np.full(len(points), np.inf)
    gap[both] = np.abs(ahead[both] - behind[both])
    unsure = gap <= UNSURE_MM
    return np.where(ahead < behind, 1.0, np.where(behind < ahead, -1.0, 0.0)), unsure


def _outside(points: np.ndarray, cell: float, grow: int, *,
             table: bool) -> tuple[np.ndarray, np.ndarray]:
    """The grid's outside cells (bool, 3-D) and the grid's origin (mm): the empty cells connected to
    the border, the cells of the points grown by ``grow`` and, with ``table``, the layers up to the
    lowest point's closed, and each column under the object up to ``UNSEEN_MM`` above them."""
    pad = grow + 2
    origin = points.min(axis=0) - pad * cell
    index = np.floor((points - origin) / cell).astype(np.int64)
    occupied = np.zeros(index.max(axis=0) + pad + 1, dtype=bool)
    occupied[tuple(index.T)] = True
    occupied = ndimage.binary_dilation(occupied, iterations=grow)
    if table:  # the table the object stood on, solid, and what it hid under the object
        floor = index[:, 2].min()
        occupied[:, :, :floor + 1] = True
        # under each column of the object, up to its lowest cell but at most UNSEEN_MM above the
        # table: the band a scan never sees (a mug's wall ends above it, its inside floor below)
        has = occupied[:, :, floor + 1:].any(axis=2)
        lowest = floor + 1 + occupied[:, :, floor + 1:].argmax(axis=2)
        top = np.where(has, np.minimum(lowest, floor + 1 + int(np.ceil(UNSEEN_MM / cell))), 0)
        occupied |= np.arange(occupied.shape[2])[None, None, :] < top[:, :, None]
    labels, _ = ndimage.label(~occupied)
    border = np.unique(np.concatenate([labels[[0, -1]].ravel(), labels[:, [0, -1]].ravel(),
                                       labels[:, :, [0, -1]].ravel()]))
    return np.isin(labels, border[border > 0]), origin


def _nearest_outside(points: np.ndarray, directions: np.ndarray, outside: np.ndarray,
                     origin: np.ndarray, cell: float, reach: float) -> np.ndarray:
    """(n,) the distance along each direction from each point to the first outside cell probed
    (inf: none within ``reach``)."""
    found = np.full(len(points), np.inf)
    top = np.array(outside.shape) - 1
    for d in np.arange(PROBE_STEP_MM, reach + 1e-9, PROBE_STEP_MM):
        open_ = np.isinf(found)
        if not open_.any():
            break
        probe = np.floor((points[open_] + d * directions[open_] - origin) / cell).astype(np.int64)
        probe = np.clip(probe, 0, top)
        hit = outside[probe[:, 0], probe[:, 1], probe[:, 2]]
        found[np.flatnonzero(open_)[hit]] = d
    return found


def _voted(tree: cKDTree, normals: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """``sign`` (n,; 0 undecided) with each undecided point given the sign most of its nearest
    neighbours agree with (their normals turned by their signs), until no sign changes."""
    undecided = np.flatnonzero(sign == 0)
    if not len(undecided):
        return sign
    _, near = tree.query(tree.data[undecided], k=min(VOTE_NEIGHBOURS + 1, len(normals)))
    for _ in range(VOTE_ROUNDS):
        agree = np.einsum("ikd,id->ik", normals[near], normals[undecided]) * sign[near]
        vote = np.sign(agree.sum(axis=1))
        if not np.any(vote != sign[undecided]):
            break
        sign[undecided] = vote
    return sign


def _by_regions(tree: cKDTree, normals: np.ndarray, sign: np.ndarray) -> np.ndarray:
    """(n,) ±1: the probes' ``sign`` (0 undecided) settled over the regions the given normals'
    signs agree on (module notes)."""
    n = len(normals)
    _, near = tree.query(tree.data, k=min(VOTE_NEIGHBOURS + 1, n))
    i = np.repeat(np.arange(n), near.shape[1] - 1)
    j = near[:, 1:].ravel()
    joined = ((np.einsum("ij,ij->i", normals[i], normals[j]) > REGION_COS)
              & (sign[i] * sign[j] >= 0))
    count, region = connected_components(
        coo_matrix((np.ones(joined.sum()), (i[joined], j[joined])), shape=(n, n)),
        directed=False)
    votes = np.bincount(region, weights=sign, minlength=count)
    decided = np.bincount(region, weights=np.abs(sign), minlength=count)
    split = ((decided - np.abs(votes)) / 2 > SPLIT_SHARE * np.maximum(decided, 1))[region]
    majority = np.where(votes[region] < 0, -1.0, 1.0)
    if not split.any():
        return majority
    own = _voted(tree, normals, sign)
    return np.where(split, np.where(own < 0, -1.0, 1.0), majority)
