"""Draw docs/images/hand_model.png: a cup, a bowl and a mug with some of their pinches and fingers.

    python tools/hand_figure.py [OUT.png]

Each panel shows the object (grey), eight of its pinches (green contacts joined by the
pinch line: the widest, across the body, and the first of the spread order; on the mug,
those on the handle first) and, for each, the two finger axes: the reported
approach leaned by the splay, away from the other finger (45 mm, orange).
"""

from __future__ import annotations

import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from mpl_toolkits.mplot3d.art3d import Poly3DCollection  # noqa: E402

from pinchmatch import PinchSettings, sample_pinches  # noqa: E402
from pinchmatch.grasp.hand import finger_directions, hand_of  # noqa: E402
from pinchmatch.mesh import vessels  # noqa: E402
from pinchmatch.mesh.surface import SurfaceContext  # noqa: E402

def _widest(pinches):
    """Four level pinches across the body (the widest of those within 5 mm of level) and four
    from the spread order."""
    width = np.linalg.norm(pinches.points[:, 1] - pinches.points[:, 0], axis=1)
    level = np.abs(pinches.points[:, 1, 2] - pinches.points[:, 0, 2]) < 5.0
    wide = np.argsort(-np.where(level, width, 0.0), kind="stable")[:4]
    return np.r_[wide, [i for i in range(len(pinches)) if i not in wide][:4]]


def _handle(pinches):
    """Up to four pinches on the handle (x > 36 mm) and the first others."""
    on = np.flatnonzero((pinches.points[..., 0] > 36.0).all(axis=1))[:4]
    return np.r_[on, [i for i in range(len(pinches)) if i not in on][: 8 - len(on)]]


PANELS = [("cup: across the cavity, and across the wall", vessels.cup, (20, -60), _widest),
          ("bowl: across its wall", vessels.bowl, (35, -60), lambda p: np.arange(8)),
          ("mug: body and handle", vessels.mug, (20, -75), _handle)]


def panel(ax, title, make, view, choose, settings):
    mesh = make()
    pinches = sample_pinches(SurfaceContext(mesh), settings=settings)
    shown = pinches.subset(choose(pinches))
    ax.add_collection3d(Poly3DCollection(mesh.triangles, facecolor=(0.7, 0.7, 0.72, 0.06),
                                         edgecolor="none"))
    tips = shown.points + settings.fingertip_radius_mm * shown.normals
    along = finger_directions(shown.points, shown.approach, hand_of(settings))
    for i in range(len(shown)):
        p = shown.points[i]
        ax.plot(*p.T, color="tab:green", linewidth=1.0)
        ax.scatter(*p.T, color="tab:green", s=14, depthshade=False)
        for k in range(2):
            axis = np.stack([tips[i, k], tips[i, k] + settings.finger_length_mm * along[i, k]])
            ax.plot(*axis.T, color="tab:orange", linewidth=4.0, alpha=0.55, solid_capstyle="round")
    lo, hi = mesh.bounds
    centre, half = (lo + hi) / 2.0, (hi - lo).max() / 2.0 + 25.0
    ax.set_xlim(centre[0] - half, centre[0] + half)
    ax.set_ylim(centre[1] - half, centre[1] + half)
    ax.set_zlim(centre[2] - half, centre[2] + half)
    ax.set_box_aspect((1, 1, 1))
    ax.view_init(*view)
    ax.set_axis_off()
    ax.set_title(f"{title}\n{len(pinches)} of {settings.count} pinches found", fontsize=9)


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    out = (Path(argv[0]) if argv else Path(__file__).resolve().parents[1] / "docs" / "images"
           / "hand_model.png")
    settings = PinchSettings(count=300, seed=0)
    fig = plt.figure(figsize=(12, 4.4), dpi=110)
    for i, (title, make, view, choose) in enumerate(PANELS, start=1):
        panel(fig.add_subplot(1, 3, i, projection="3d"), title, make, view, choose, settings)
    fig.tight_layout(rect=(0, 0.05, 1, 0.93))
    fig.text(0.5, 0.02,
             "Pinches (green) and the two fingers of each, in a V about its approach (orange, 45 "
             "mm)", ha="center", fontsize=10)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out)
    print(out)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
