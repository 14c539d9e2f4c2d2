"""Figures for people to read, written to ``OUT/figures/``.

- ``cost_matrix.png``: cost of the best pair for every virtual object (rows) and tangible (columns);
- ``criteria/<virtual>.png``: per match, each criterion's difference in JND, with the line at 1 JND;
- ``study.png`` (demo only): the paper's Table 2 layout, the tangible and the six virtual objects in
  side view with the chosen poses coloured by the tangible part they stand in for, flips marked F.

matplotlib's object API with the Agg canvas: no pyplot, no display, no global state. Each figure
has a fixed size in pixels (``FIGURE_DPI`` times the size in inches) so pages and tests can rely on
it.
"""

from __future__ import annotations

import io
import logging
from pathlib import Path

import numpy as np
from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.colors import LogNorm
from matplotlib.figure import Figure
from matplotlib.patches import Rectangle

from ..files import write_atomic
from .documents import figure_file, scene_stems

log = logging.getLogger(__name__)

FIGURE_DPI = 100
#: the colour of each tangible part's pose in the study figure
PART_COLORS = {"cylinder": "#1f77b4", "cube": "#ff7f0e", "cone": "#2ca02c"}
LOUD, QUIET = "#d1432f", "#2e9d52"
#: costs below this are drawn in the lightest colour of the log scale
COST_FLOOR = 1e-3


def png_bytes(fig: Figure) -> bytes:
    """The figure as PNG bytes, at FIGURE_DPI."""
    FigureCanvasAgg(fig)
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", dpi=FIGURE_DPI)
    return buffer.getvalue()


def cost_matrix_figure(document: dict) -> Figure:
    """Heatmap of ``cost_matrix`` in a matches document; the chosen tangible of each row is
    outlined."""
    cm = document["cost_matrix"]
    names_v, names_t = cm["rows_virtual"], cm["columns_tangible"]
    values = np.array([[np.nan if x is None else x for x in row] for row in cm["values"]],
                      dtype=float)
    chosen = {m["virtual"]: m["tangible"] for m in document["matches"]
              if m.get("tangible") is not None}

    width_in = min(4.0 + 1.3 * len(names_t), 16.0)
    height_in = min(1.8 + 0.42 * len(names_v), 30.0)
    fig = Figure(figsize=(width_in, height_in), layout="constrained")
    ax = fig.add_subplot()
    vmin, vmax = cost_color_range(values)
    image = ax.imshow(np.clip(values, vmin, None), cmap="viridis_r", aspect="auto",
                      norm=LogNorm(vmin=vmin, vmax=vmax))
    cbar = fig.colorbar(image, ax=ax, shrink=0.9)
    cbar.set_label("cost (log scale)")
    for i in range(len(names_v)):
        for j in range(len(names_t)):
            x = values[i, j]
            text = "none" if not np.isfinite(x) else f"{x:.3g}"
            dark = np.isfinite(x) and np.log(max(x, vmin)) > 0.5 * (np.log(vmin) + np.log(vmax))
            ax.text(j, i, text, ha="center", va="center", fontsize=8,
                    color="white" if dark else "black")
        if chosen.get(names_v[i]) in names_t:
            j = names_t.index(chosen[names_v[i]])
            ax.add_patch(_outline(j, i))
    ax.set_xticks(range(len(names_t)), [Path(n).stem for n in names_t], rotation=30, ha="right",
                  fontsize=8)
    ax.set_yticks(range(len(names_v)), [Path(n).stem for n in names_v], fontsize=8)
    ax.set_xlabel("tangible")
    ax.set_ylabel("virtual object")
    ax.set_title("cost of the best pinch pair (outlined: the chosen tangible)", fontsize=10)
    return fig


def coverage_figure(document: dict) -> Figure:
    """The coverage curve of a selection document: the best objective for K = 1, 2, … props
    (filled: the best subset, exhaustively; open: greedy and swaps), and the count of noticeable
    objects."""
    curve = document["coverage"]
    objective = document["settings"]["objective"]
    k = np.array([c["k"] for c in curve])
    mean = np.array([np.nan if c["mean_cost"] is None else c["mean_cost"] for c in curve],
                    dtype=float)
    loud = np.array([c["noticeable_count"] for c in curve], dtype=float)
    exact = np.array([c["exact"] for c in curve], dtype=bool)
    fig = Figure(figsize=(6.4, 3.8), layout="constrained")
    ax = fig.add_subplot()
    ax.plot(k, mean, color="#1f77b4", lw=1.5, label="mean cost")
    ax.plot(k[exact], mean[exact], "o", color="#1f77b4", label="best subset (exhaustive)")
    ax.plot(k[~exact], mean[~exact], "o", mfc="white", color="#1f77b4", label="greedy + swaps")
    if objective == "max":
        worst = np.array([np.nan if c["worst_cost"] is None else c["worst_cost"] for c in curve],
                         dtype=float)
        ax.plot(k, worst, "s--", color="#d62728", label="worst object's cost")
    ax.axvline(document["selection"]["k"], color="0.6", lw=1, ls=":")
    ax.set_xlabel("props on the table (K)")
    ax.set_ylabel("cost (1: just noticeable)")
    ax.set_xticks(k)
    right = ax.twinx()
    right.step(k, loud, where="mid", color="#ff7f0e", lw=1.2, label="noticeable objects")
    right.set_ylabel("noticeable objects", color="#ff7f0e")
    right.set_ylim(0, max(1.0, float(np.nanmax(loud)) * 1.1))
    lines = ax.get_legend_handles_labels()
    extra = right.get_legend_handles_labels()
    ax.legend(lines[0] + extra[0], lines[1] + extra[1], fontsize=8, loc="best")
    ax.set_title(f"best {objective} objective by number of props", fontsize=10)
    return fig


def cost_color_range(values: np.ndarray) -> tuple[float, float]:
    """(vmin, vmax) of the cost matrix's log colour scale: the data's least positive and greatest
    cost, so that the colours spread over the costs there are (a cost of 0 takes the lightest
    colour; one cost alone gets a factor of 2 either side). COST_FLOOR only where no cost is
    positive."""
    finite = values[np.isfinite(values)]
    positive = finite[finite > 0]
    if not positive.size:
        return COST_FLOOR, 10 * COST_FLOOR
    vmin, vmax = float(positive.min()), float(positive.max())
    return (vmin, vmax) if vmax > vmin else (vmin / 2.0, vmax * 2.0)


def _outline(x, y):
    return Rectangle((x - 0.5, y - 0.5), 1, 1, fill=False, edgecolor=LOUD, linewidth=2)


#: a bar label's width (4 characters at 8 pt on the 6.4 in figure), as a share of the axis
LABEL_WIDTH_SHARE = 0.075


def _label_x(end: float, top: float) -> float:
    """Where a bar's value label starts: just after the bar, or just after the 1-JND line where the
    label would sit on it."""
    start = end + 0.01 * top
    if start - 0.01 * top <= 1.0 <= start + LABEL_WIDTH_SHARE * top:
        start = 1.0 + 0.015 * top
    return start


def criteria_figure(match: dict) -> Figure:
    """Bars of each criterion's difference in JND for one match of a matches document, line at 1
    JND."""
    names = list(match["criteria"])
    jnd = np.array([match["criteria"][c]["jnd"] for c in names])
    fig = Figure(figsize=(6.4, 3.6), layout="constrained")
    ax = fig.add_subplot()
    y = np.arange(len(names))
    ax.barh(y, jnd, color=[LOUD if x >= 1.0 else QUIET for x in jnd], height=0.6)
    ax.axvline(1.0, color="black", linestyle="--", linewidth=1)
    top = max(2.0, float(jnd.max()) * 1.18)
    ax.set_xlim(0, top)
    ax.text(1.0, -0.9, " 1 JND: noticed half of the time", fontsize=8, va="center")
    for k, x in enumerate(jnd):
        ax.text(_label_x(min(x, top), top), k, f"{x:.2f}", va="center", fontsize=8)
    ax.set_yticks(y, names)
    ax.set_ylim(len(names) - 0.5, -1.3)
    ax.set_xlabel("difference between the tangible and the virtual pose (JND)")
    flip = ", flipped" if match.get("flipped") else ""
    noticed = (f", noticed {100 * match['p_noticed']:.0f} %" if match.get("p_noticed") is not None
               else "")
    ax.set_title(f"{Path(match['virtual']).stem} on {Path(match['tangible']).stem}: "
                 f"cost {match['cost']:.3g}{noticed}{flip}", fontsize=10)
    return fig


def _silhouette(ax, mesh) -> None:
    """The mesh's section by the plane y = 0, filled, as the object's side view (x right, z up)."""
    section = mesh.section(plane_origin=[0.0, 0.0, 0.0], plane_normal=[0.0, 1.0, 0.0])
    if section is None:
        return
    for loop in section.discrete:
        ax.fill(loop[:, 0], loop[:, 2], facecolor="#dfe3e8", edgecolor="#4b5563", linewidth=1.0)


def _pose(ax, contacts, color, *, dz=0.0, flipped=False, label_dx=0.0) -> None:
    """A grasp in the side view: a line from the first contact to the middle of the others (a
    pinch's two contacts; a tripod's thumb and its fingers' middle), a dot on every contact."""
    p = np.asarray(contacts, dtype=np.float64)
    line = np.array([p[0], p[1:].mean(axis=0)])
    x, z = line[:, 0], line[:, 2] + dz
    ax.plot(x, z, color=color, linewidth=2.2, solid_capstyle="round")
    ax.plot(p[:, 0], p[:, 2] + dz, "o", color=color, markersize=4.5)
    if flipped:
        ax.text(max(x) + 3 + label_dx, z[1], "F", color=color, fontsize=10, fontweight="bold",
                va="center")


def study_figure(tangible_mesh, tangible_points_mm: np.ndarray, virtual_meshes: list,
                 rows: list) -> Figure:
    """The study in the layout of the paper's Table 2.

    Columns: the tangible and the six virtual objects, side view (section y = 0, mm). Rows: the
    poses chosen by pinchmatch (default criteria, JND) and by the paper's algorithm (seven criteria,
    range scaling). Each of the three tangible poses has the colour of its part; on a virtual object
    the pose chosen for it has the same colour, F when the virtual object is turned upside down.
    """
    parts = list(dict.fromkeys(r["tangible_part"] for r in rows))
    fig = Figure(figsize=(14.0, 6.4), layout="constrained")
    axes = fig.subplots(2, 1 + len(virtual_meshes), sharey=True)
    titles = {r["virtual"]: "/".join(r["virtual_order"]) for r in rows}
    for row, (key, label) in enumerate((("ours", "pinchmatch"), ("paper", "paper's algorithm"))):
        ax = axes[row, 0]
        _silhouette(ax, tangible_mesh)
        for k, part in enumerate(parts):
            _pose(ax, tangible_points_mm[k], PART_COLORS.get(part, "black"))
        ax.set_ylabel(f"{label}\nheight (mm)")
        ax.set_title("tangible\n" + "/".join(parts) if row == 0 else "", fontsize=9)
        for j, mesh in enumerate(virtual_meshes, start=1):
            ax = axes[row, j]
            _silhouette(ax, mesh)
            chosen = [r for r in rows if r["virtual"] == j and r[key]["contacts_mm"] is not None]
            heights = np.array([r[key]["height_mm"] for r in chosen])
            for k, r in enumerate(chosen):
                pose = r[key]
                # a pose chosen for several tangible parts is drawn once per part, 2 mm apart, F
                # labels side by side
                same = np.flatnonzero(np.abs(heights - heights[k]) < 1.0)
                rank = int(np.searchsorted(same, k))
                _pose(ax, pose["contacts_mm"], PART_COLORS.get(r["tangible_part"], "black"),
                      dz=(rank - (len(same) - 1) / 2) * 2.5, flipped=pose["flipped"],
                      label_dx=rank * 7.0)
            ax.set_title(f"VO{j}\n{titles.get(j, '')}" if row == 0 else "", fontsize=9)
    for ax in axes.ravel():
        ax.set_aspect("equal")
        ax.set_xlim(-45, 55)
        ax.tick_params(labelsize=7)
        ax.set_xticks([])
    handles = [axes[0, 0].plot([], [], color=c, linewidth=2.2)[0] for c in PART_COLORS.values()]
    fig.legend(handles, [f"tangible pose on the {p}" for p in PART_COLORS],
               loc="outside lower center", ncol=3, fontsize=9, frameon=False)
    fig.suptitle("User study, rebuilt: where each tangible pose lands on each virtual object (F: "
                 "flipped)",
                 fontsize=11)
    return fig


def figure_count(document: dict, *, study=None, criteria: bool = True) -> int:
    """How many files ``write_figures`` writes."""
    return 1 + criteria * sum(m.get("tangible") is not None
                              for m in document["matches"]) + (study is not None)


def write_figures(out: Path, document: dict, *, study=None, progress=None,
                  criteria: bool = True) -> list[Path]:
    """Write the figures of a matches document (and of the demo's study) into ``OUT/figures``:
    the cost matrix, each match's criteria figure (unless ``criteria`` is False: a run's sink
    wrote them) and the study's.

    ``progress``, if given, is called with each path once it is written.
    """
    folder = Path(out) / "figures"
    written = []

    def save(fig: Figure, path: Path) -> None:
        write_atomic(path, png_bytes(fig))
        written.append(path)
        if progress is not None:
            progress(path)

    save(cost_matrix_figure(document), folder / "cost_matrix.png")
    # documents that name no figure file
    stems = scene_stems([m["virtual"] for m in document["matches"]])
    for stem, match in zip(stems, document["matches"]):
        if criteria and match.get("tangible") is not None:
            save(criteria_figure(match),
                 folder.parent / (match.get("figure_file") or figure_file(stem)))
    if study is not None:
        save(study_figure(study.tangible.obj.loaded.mesh, study.tangible.pinches.points,
                          [v.obj.loaded.mesh for v in study.virtuals], study.rows),
             folder / "study.png")
    log.info("wrote %d figures in %s", len(written), folder)
    return written
