import json

import numpy as np
import pytest
from matplotlib.colors import to_rgb
from matplotlib.image import imread

from pinchmatch.export.figures import FIGURE_DPI, LOUD, cost_matrix_figure, criteria_figure

PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def png_size(path):
    """(width, height) from the PNG header."""
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    return int.from_bytes(data[16:20], "big"), int.from_bytes(data[20:24], "big")


def has_color(path, color, *, tol=0.02, min_pixels=50):
    image = imread(path)[..., :3]
    close = np.all(np.abs(image - np.array(to_rgb(color))) < tol, axis=-1)
    return int(close.sum()) >= min_pixels


def test_demo_writes_every_figure_at_its_size(demo_out):
    doc = json.loads((demo_out / "matches.json").read_text())
    folder = demo_out / "figures"
    assert png_size(folder / "study.png") == (1400, 640)
    w, h = cost_matrix_figure(doc).get_size_inches() * FIGURE_DPI
    assert png_size(folder / "cost_matrix.png") == (round(w), round(h))
    bars = sorted((folder / "criteria").glob("*.png"))
    assert [p.stem for p in bars] == sorted(p.stem for p in (demo_out / "scenes").glob("*.glb"))
    assert len(bars) == sum(m["tangible"] is not None for m in doc["matches"]) == 6
    for path in bars:
        assert png_size(path) == (640, 360)


def test_criteria_bars_are_red_exactly_where_a_criterion_is_noticeable(demo_out):
    doc = json.loads((demo_out / "matches.json").read_text())
    loud = {m["virtual"].removesuffix(".stl"): any(c["noticeable"] for c in m["criteria"].values())
            for m in doc["matches"]}
    assert any(loud.values()) and not all(loud.values())  # the demo has both kinds
    for stem, noticeable in loud.items():
        assert (has_color(demo_out / "figures" / "criteria" / f"{stem}.png", LOUD)
                == noticeable), stem


def test_study_figure_is_not_blank(demo_out):
    image = imread(demo_out / "figures" / "study.png")[..., :3]
    for color in ("#1f77b4", "#ff7f0e", "#2ca02c"):  # a pose of every tangible part is drawn
        assert has_color(demo_out / "figures" / "study.png", color)
    assert image.std() > 0.05


def test_cost_matrix_outlines_the_chosen_tangible():
    doc = {
        "cost_matrix": {"rows_virtual": ["a.stl", "b.stl"],
                        "columns_tangible": ["t1.stl", "t2.stl", "t3.stl"],
                        "values": [[0.5, 2.0, None], [0.0, 0.02, 7.0]]},
        "matches": [{"virtual": "a.stl", "tangible": "t1.stl"},
                    {"virtual": "b.stl", "tangible": "t1.stl"}],
    }
    fig = cost_matrix_figure(doc)
    ax = fig.axes[0]
    outlined = [(p.get_x() + 0.5, p.get_y() + 0.5) for p in ax.patches]
    assert outlined == [(0, 0), (0, 1)]
    texts = {t.get_text() for t in ax.texts}
    assert {"0.5", "2", "none", "0", "0.02", "7"} <= texts


def test_criteria_figure_draws_one_bar_per_criterion_and_the_line_at_one():
    match = {"virtual": "v.stl", "tangible": "t.stl", "cost": 4.5, "flipped": True,
             "criteria": {"width": {"jnd": 2.0}, "tilt": {"jnd": 0.5}, "kmax": {"jnd": 0.0}}}
    ax = criteria_figure(match).axes[0]
    widths = [p.get_width() for p in ax.patches]
    assert widths == pytest.approx([2.0, 0.5, 0.0])
    assert [p.get_facecolor()[:3] for p in ax.patches][:2] == [pytest.approx(to_rgb(LOUD)),
                                                               pytest.approx(to_rgb("#2e9d52"))]
    assert any(np.allclose(line.get_xdata(), 1.0) for line in ax.lines)
    assert "flipped" in ax.get_title()


def test_the_cost_colour_scale_follows_the_data():
    from pinchmatch.export.figures import cost_color_range

    # not from 1e-3
    assert cost_color_range(np.array([[500.0, 628.0], [np.nan, 551.0]])) == (500.0, 628.0)
    assert cost_color_range(np.array([[0.0, 0.02], [7.0, np.inf]])) == (0.02, 7.0)
    assert cost_color_range(np.array([[3.0, np.nan]])) == (1.5, 6.0)
    assert cost_color_range(np.array([[0.0, np.nan]])) == (pytest.approx(1e-3), pytest.approx(1e-2))
    fig = cost_matrix_figure({"cost_matrix": {"rows_virtual": ["a"],
                                              "columns_tangible": ["t1", "t2"],
                                              "values": [[500.0, 628.0]]}, "matches": []})
    norm = fig.axes[0].images[0].norm
    assert (norm.vmin, norm.vmax) == (500.0, 628.0)


@pytest.mark.parametrize("jnd", [0.93, 0.97, 1.0, 1.02])
def test_no_bar_label_sits_on_the_1_jnd_line(jnd):
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    match = {"virtual": "v.stl", "tangible": "t.stl", "cost": 1.0,
             "criteria": {"width": {"jnd": jnd}, "tilt": {"jnd": 0.2}, "kmax": {"jnd": 3.0}}}
    fig = criteria_figure(match)
    renderer = FigureCanvasAgg(fig).get_renderer()
    ax = fig.axes[0]
    line_x = ax.transData.transform((1.0, 0.0))[0]
    labels = [t for t in ax.texts if t.get_text().replace(".", "").isdigit()]
    assert len(labels) == 3
    for t in labels:
        box = t.get_window_extent(renderer)
        assert not box.x0 - 1 <= line_x <= box.x1 + 1, (t.get_text(), box, line_x)
