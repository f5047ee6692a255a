"""Figures: structure, labelled axes, and the numbers they draw against independent references."""


import matplotlib

matplotlib.use("Agg")
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from helpers import assert_laid_out  # noqa: E402
from matplotlib.backends.backend_agg import FigureCanvasAgg  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from scipy.linalg import qr  # noqa: E402

from facemotion.errors import InputError  # noqa: E402
from facemotion.plots.error_curves import plot_error_curves, plot_trajectory  # noqa: E402
from facemotion.plots.facemap import interpolate_at, interpolate_field  # noqa: E402
from facemotion.plots.gaps import plot_gaps, runs  # noqa: E402
from facemotion.plots.markers import plot_markers  # noqa: E402
from facemotion.plots.rank import plot_r_values  # noqa: E402
from facemotion.plots.regions import (  # noqa: E402
    orthogonal_direction_coefficients,
    plot_orthogonal_directions,
    plot_region_maps,
    region_coefficients,
)
from facemotion.plots.save import figure_bytes  # noqa: E402
from facemotion.plots.selection import plot_selection_agreement, selection_counts  # noqa: E402
from facemotion.plots.sweep import plot_sentence_sweep  # noqa: E402


def face_layout(n_rings=4, per_ring=8):
    """A face-like layout: a centre marker and rings of markers on ellipses (mm)."""
    pts = [(0.0, 0.0)]
    for r in range(1, n_rings + 1):
        a = np.linspace(0, 2 * np.pi, per_ring + 2 * r, endpoint=False) + 0.3 * r
        pts += list(zip(18.0 * r * np.cos(a), 24.0 * r * np.sin(a), strict=True))
    xy = np.array(pts)
    z = 60.0 - 0.004 * (xy[:, 0] ** 2 + 0.5 * xy[:, 1] ** 2)
    neutral = np.column_stack([xy, z])
    return neutral, [str(i + 1) for i in range(len(neutral))]


@pytest.fixture(scope="module")
def face():
    return face_layout()


@pytest.fixture(scope="module")
def qr_case(face):
    neutral, labels = face
    rng = np.random.default_rng(1)
    T = 80
    # Three latent motions spread smoothly over the face, plus small noise.
    basis = np.stack([np.exp(-((neutral[:, 0] - cx) ** 2 + (neutral[:, 1] - cy) ** 2) / 900)
                      for cx, cy in ((0, -60), (40, 40), (-40, 40))])
    A = np.kron(rng.standard_normal((T, 3)), np.ones((3, 1))) @ basis
    A += 0.01 * rng.standard_normal(A.shape)
    _, R, piv = qr(A, mode="economic", pivoting=True)
    order = [labels[i] for i in piv]
    return A, R, piv, order


def _data_axes(fig):
    return [ax for ax in fig.axes if ax.get_label() != "<colorbar>" and ax.axison]


# ---------------------------------------------------------------- interpolation over the face


def test_cubic_interpolation_reproduces_a_plane_and_is_nan_outside_the_hull(face):
    neutral, _ = face
    xy = neutral[:, :2]
    plane = 2.0 * xy[:, 0] - 3.0 * xy[:, 1] + 5.0
    gx, gy, z = interpolate_field(xy, plane, grid_n=60)
    inside = np.isfinite(z)
    assert 0.4 < inside.mean() < 0.95  # an ellipse-ish hull inside its bounding box
    # Clough-Tocher reproduces linear fields; its iterative gradient estimate stops at a
    # relative tolerance of 1e-6, hence ~1e-6 mm on a field spanning ~500.
    np.testing.assert_allclose(z[inside], 2.0 * gx[inside] - 3.0 * gy[inside] + 5.0,
                               atol=1e-5)
    assert np.isnan(z[0, 0]) and np.isnan(z[-1, -1])  # bounding-box corners: outside
    assert gx.min() == xy[:, 0].min() and gy.max() == xy[:, 1].max()


def test_region_coefficients_and_field_at_main_markers(face):
    neutral, labels = face
    mains = ["1", "5", "20"]
    secondary = [s for s in labels if s not in mains]
    X = pd.DataFrame(np.linspace(-0.5, 0.9, 3 * len(secondary)).reshape(3, -1),
                     index=mains, columns=secondary)
    C = region_coefficients(labels, X)
    assert C.shape == (3, len(labels))
    for i, m in enumerate(mains):
        assert C[i, labels.index(m)] == 1.0
        for other in mains:
            if other != m:
                assert C[i, labels.index(other)] == 0.0
        for s in secondary[:5]:
            assert C[i, labels.index(s)] == X.loc[m, s]
    # The interpolated field of main marker i is 1 at its own position and 0 at the others'.
    for i, m in enumerate(mains):
        at = interpolate_at(neutral, C[i], neutral[[labels.index(x) for x in mains]])
        np.testing.assert_allclose(at, [1.0 if x == m else 0.0 for x in mains], atol=1e-9)


def test_region_maps_figure(face):
    neutral, labels = face
    mains = ["1", "5", "20", "33"]
    secondary = [s for s in labels if s not in mains]
    X = pd.DataFrame(np.cos(np.arange(4 * len(secondary))).reshape(4, -1), index=mains,
                     columns=secondary)
    fig = plot_region_maps(neutral, labels, X, grid_n=40)
    assert isinstance(fig, Figure)
    panels = [ax for ax in _data_axes(fig) if ax.get_title()]
    assert [ax.get_title() for ax in panels] == [f"main marker {m}" for m in mains]
    assert any("colorbar" in ax.get_label() for ax in fig.axes)
    assert all("mm" in ax.get_xlabel() for ax in panels if ax.get_xlabel())
    assert any("mm" in ax.get_ylabel() for ax in panels)
    # The main marker of each panel is labelled on it.
    for ax, m in zip(panels, mains, strict=True):
        assert m in [t.get_text() for t in ax.texts]
    # Deterministic rendering.
    assert figure_bytes(fig, "png") == figure_bytes(plot_region_maps(neutral, labels, X,
                                                                     grid_n=40), "png")


@pytest.mark.parametrize("k", [3, 4, 7, 10])
def test_region_maps_fixed_layout_keeps_every_text_inside_and_nothing_overlaps(face, k):
    """The region maps' layout is fixed in inches (no constrained layout): every text is
    inside the figure, no panel overlaps another, the colour bar or the suptitle, and the
    suptitle is wrapped to the figure's width."""
    neutral, labels = face
    mains = labels[:k]
    secondary = [s for s in labels if s not in mains]
    X = pd.DataFrame(np.cos(np.arange(k * len(secondary))).reshape(k, -1) - 0.3,
                     index=mains, columns=secondary)
    fig = plot_region_maps(neutral, labels, X, grid_n=30)
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    r = canvas.get_renderer()
    box = fig.bbox
    texts = [t for t in fig.findobj(matplotlib.text.Text) if t.get_visible() and t.get_text()]
    for t in texts:
        e = t.get_window_extent(r)
        assert (e.x0 >= box.x0 - 1 and e.x1 <= box.x1 + 1 and e.y0 >= box.y0 - 1
                and e.y1 <= box.y1 + 1), t.get_text()
    panels = [ax for ax in _data_axes(fig) if ax.get_title()]
    cbar = [ax for ax in fig.axes if ax.get_label() == "<colorbar>"]
    assert len(panels) == k and len(cbar) == 1
    frames = [ax.get_tightbbox(r) for ax in panels]  # the panel with its ticks and title
    for i, a in enumerate(frames):
        for b in frames[i + 1:]:
            assert not a.overlaps(b)
        assert not a.overlaps(cbar[0].get_window_extent(r))
        assert not a.overlaps(fig._suptitle.get_window_extent(r))


def test_region_maps_name_unknown_markers(face):
    neutral, labels = face
    X = pd.DataFrame([[0.5] * (len(labels) - 1)], index=["Chin"], columns=labels[1:])
    with pytest.raises(InputError, match="Chin"):
        plot_region_maps(neutral, labels, X)


def _region_case(face):
    neutral, labels = face
    mains = ["1", "5", "20"]
    secondary = [s for s in labels if s not in mains]
    # smooth coefficients with a clearly negative lobe on the talker's left (x > 0)
    xs = neutral[[labels.index(s) for s in secondary], 0]
    X = pd.DataFrame([np.sin(xs / 25.0), np.cos(xs / 30.0), -0.01 * xs], index=mains,
                     columns=secondary)
    return neutral, labels, mains, X


def test_region_map_image_is_the_interpolated_field_on_the_grid_nodes(face):
    """The field is drawn as an image whose pixel centres are the grid nodes (origin lower):
    each pixel holds the cubic interpolant at that node (independent griddata evaluation at
    the node positions the image's extent implies), clipped at 0, masked outside the hull."""
    neutral, labels, mains, X = _region_case(face)
    C = region_coefficients(labels, X)
    grid_n = 30
    fig = plot_region_maps(neutral, labels, X, grid_n=grid_n, negative_below=0.05)
    panels = [ax for ax in _data_axes(fig) if ax.get_title()]
    assert len({(ax.get_xlim(), ax.get_ylim()) for ax in panels}) == 1  # one frontal view
    for p, ax in enumerate(panels):
        (image,) = ax.get_images()
        data = image.get_array()
        assert data.shape == (grid_n, grid_n)
        x0, x1, y0, y1 = image.get_extent()
        assert image.origin == "lower"
        dx, dy = (x1 - x0) / grid_n, (y1 - y0) / grid_n
        cx = x0 + dx * (np.arange(grid_n) + 0.5)  # pixel centres, columns: x
        cy = y0 + dy * (np.arange(grid_n) + 0.5)  # rows from the bottom: y
        np.testing.assert_allclose([cx[0], cx[-1], cy[0], cy[-1]],
                                   [neutral[:, 0].min(), neutral[:, 0].max(),
                                    neutral[:, 1].min(), neutral[:, 1].max()], atol=1e-9)
        gx, gy = np.meshgrid(cx, cy)
        ref = interpolate_at(neutral, C[p], np.column_stack([gx.ravel(), gy.ravel()]))
        ref = ref.reshape(grid_n, grid_n)
        inside = np.isfinite(ref)
        assert 0.4 < inside.mean() < 0.95
        np.testing.assert_array_equal(np.ma.getmaskarray(data), ~inside)
        np.testing.assert_allclose(data[inside], np.clip(ref[inside], 0.0, None), atol=1e-9)


def test_region_map_hatches_exactly_the_negative_subregions(face):
    """Where the field is below -negative_below x the colour-scale maximum the panel has a
    blue-hatched filled contour and a blue outline; the hatched area covers the grid nodes
    below that level and none of those clearly above it."""
    from matplotlib.colors import to_rgba
    from matplotlib.contour import ContourSet

    from facemotion.plots.facemap import NEGATIVE_COLOUR, interpolate_field

    neutral, labels, mains, X = _region_case(face)
    C = region_coefficients(labels, X)
    fig = plot_region_maps(neutral, labels, X, grid_n=60, negative_below=0.05)
    panels = [ax for ax in _data_axes(fig) if ax.get_title()]
    level = -0.05 * max(1.0, float(C.max()))
    gx, gy, Z = interpolate_field(neutral, C.T, 60)
    hatched_panels = 0
    for p, ax in enumerate(panels):
        z = Z[..., p]
        sets = [c for c in ax.collections if isinstance(c, ContourSet)]
        filled = [c for c in sets if c.filled]
        if not (np.nanmin(z) < level):
            assert not sets
            continue
        hatched_panels += 1
        (cf,) = filled
        assert cf.hatches == ["////"]
        np.testing.assert_allclose(cf.get_edgecolor()[0], to_rgba(NEGATIVE_COLOUR))
        (line,) = [c for c in sets if not c.filled]
        assert list(line.levels) == [pytest.approx(level)]
        path = cf.get_paths()[0]
        pts = np.column_stack([gx.ravel(), gy.ravel()])
        inside = path.contains_points(pts).reshape(z.shape)
        below = np.isfinite(z) & (z < level - 0.02)
        above = np.isfinite(z) & (z > level + 0.02)
        assert below.any()
        assert inside[below].mean() > 0.95 and not inside[above].any()
    assert hatched_panels >= 2  # the sine and the -x panels dip below the level


def test_orthogonal_directions_match_an_unpivoted_qr(face, qr_case):
    neutral, labels = face
    A, R, piv, order = qr_case
    C = orthogonal_direction_coefficients(R, order, labels, n_pivots=4)
    # Reference: A P = Q R, so R[i, j] / R[i, i] = (q_i . a_j) / (q_i . a_pivot_i).
    Q, _ = np.linalg.qr(A[:, piv])
    for i in range(4):
        ref = (Q[:, i] @ A) / (Q[:, i] @ A[:, piv[i]])
        np.testing.assert_allclose(C[i], ref, atol=1e-8)
        assert C[i, piv[i]] == pytest.approx(1.0)
        for earlier in piv[:i]:
            assert abs(C[i, earlier]) < 1e-9
    fig = plot_orthogonal_directions(neutral, labels, R, order, n_pivots=4, grid_n=40)
    titles = [ax.get_title() for ax in _data_axes(fig) if ax.get_title()]
    assert titles == [f"q{i + 1}: pivot {order[i]}" for i in range(4)]


# ---------------------------------------------------------------- rank, sweep, errors


def _r_table(order, scale=1.0):
    n = len(order)
    r_rms = scale * np.geomspace(5.0, 0.2, n)
    return pd.DataFrame({"order": np.arange(1, n + 1), "marker": order, "r": r_rms * 10,
                         "r_rms": r_rms, "r_normalised": r_rms,
                         "r_normalisation": "per_coordinate"})


def test_r_values_figure(face):
    _, labels = face
    t1, t2 = _r_table(labels), _r_table(labels[::-1], 1.5)
    fig = plot_r_values({"S1": t1, "S2": t2}, tolerances=(0.25, 0.5, 1.0))
    (ax,) = fig.axes
    assert ax.get_yscale() == "log"
    assert "mm" in ax.get_ylabel() and "order" in ax.get_xlabel()
    assert "sqrt(3M)" in ax.get_ylabel()       # the table's normalisation names the axis
    assert len(ax.get_lines()) == 2 + 3  # two datasets and three tolerance lines
    dashed = [ln for ln in ax.get_lines() if ln.get_linestyle() == "--"]
    assert sorted(ln.get_ydata()[0] for ln in dashed) == [0.25, 0.5, 1.0]
    np.testing.assert_allclose(ax.get_lines()[0].get_ydata(), t1["r_rms"])
    texts = {t.get_text() for t in ax.texts}
    # The last three pivots below 0.5 mm of each dataset are annotated, earlier ones are not.
    for t in (t1, t2):
        below = t[t["r_rms"] < 0.5]["marker"].tolist()
        assert set(below[-3:]) <= texts
    assert len(ax.texts) == 3 + 2 * 3  # tolerance labels, three annotations per dataset
    n = len(labels)
    assert [t.get_text() for t in ax.get_legend().get_texts()] == [f"S1 ({n} markers)",
                                                                   f"S2 ({n} markers)"]


def test_sentence_sweep_figure():
    rows = [{"n_sentences": n, "order": o, "marker": f"m{o}" if n > 2 else f"x{o}",
             "r_rms": 10.0 / o + 1.0 / n} for n in range(1, 6) for o in range(1, 15)]
    fig = plot_sentence_sweep(pd.DataFrame(rows))
    (ax,) = fig.axes
    assert len(ax.get_lines()) == 12  # only the first 12 pivots
    legend = fig.legends[0]
    assert [t.get_text() for t in legend.get_texts()] == [f"{o}: m{o}" for o in range(1, 13)]
    assert "sentences" in ax.get_xlabel() and "mm" in ax.get_ylabel()
    np.testing.assert_allclose(ax.get_lines()[0].get_xdata(), [1, 2, 3, 4, 5])
    with pytest.raises(InputError, match="r_rms"):
        plot_sentence_sweep(pd.DataFrame(rows).drop(columns="r_rms"))


def test_error_curves_figure():
    k = np.arange(1, 11)
    a = pd.DataFrame({"k": k, "mean_abs_error_mm": 2.0 / k, "rel_error_per_marker": 0.5 / k,
                      "median_abs_error_mm": 1.5 / k, "max_abs_error_mm": 6.0 / k})
    b = a[["k", "mean_abs_error_mm", "rel_error_per_marker"]].assign(mean_abs_error_mm=3.0 / k)
    fig = plot_error_curves({"S1": a, "AnimFace": b})
    ax_abs, ax_rel = fig.axes
    assert "mm" in ax_abs.get_ylabel() and "k" in ax_abs.get_xlabel()
    assert "relative" in ax_rel.get_ylabel() and "k" in ax_rel.get_xlabel()
    assert len(ax_abs.get_lines()) == 4  # S1 mean, median, max; AnimFace mean
    assert len(ax_rel.get_lines()) == 2
    np.testing.assert_allclose(ax_rel.get_lines()[1].get_ydata(), 0.5 / k)
    with pytest.raises(InputError, match="AnimFace"):
        plot_error_curves({"AnimFace": b.drop(columns="rel_error_per_marker")})


def test_trajectory_figure():
    t = np.arange(50) / 120.0
    measured = np.column_stack([np.sin(t), np.cos(t), t])
    predicted = measured + 0.1
    fig = plot_trajectory(t, measured, predicted, marker="Chin", sentence="s03", k=10)
    axes = fig.axes
    assert len(axes) == 3
    for a, ax in enumerate(axes):
        meas, pred = ax.get_lines()
        np.testing.assert_allclose(meas.get_ydata(), measured[:, a])
        np.testing.assert_allclose(pred.get_ydata(), predicted[:, a])
        assert "(mm)" in ax.get_ylabel()
    assert axes[-1].get_xlabel() == "time (s)"
    assert "Chin" in fig.get_suptitle() and "s03" in fig.get_suptitle()
    assert "main markers" not in fig.get_suptitle()
    fig = plot_trajectory(t, measured, measured, marker="Chin", sentence="s03", k=10,
                          in_basis=True)
    assert "Chin is one of the 10 main markers" in fig.get_suptitle()
    with pytest.raises(InputError, match="Chin"):
        plot_trajectory(t, measured[:10], predicted, marker="Chin", sentence="s03", k=10)


# ---------------------------------------------------------------- gaps, markers, selection


def test_runs():
    assert runs(np.array([0, 1, 1, 0, 1, 0, 0, 1], bool)) == [(1, 3), (4, 5), (7, 8)]
    assert runs(np.zeros(4, bool)) == []


def _drawn_mask(ax, gid, t, dt, n_rows):
    """Samples covered by the bars of one kind, per raster row."""
    drawn = np.zeros((t.size, n_rows), bool)
    for coll in ax.collections:
        if coll.get_gid() != gid:
            continue
        for path in coll.get_paths():
            v = path.vertices
            x0, x1 = v[:, 0].min(), v[:, 0].max()
            row = int(round(v[:, 1].mean()))
            drawn[(t >= x0 - dt / 2) & (t + dt / 2 <= x1 + 1e-9), row] = True
    return drawn


@pytest.mark.parametrize("n_markers", [6, 40])
def test_gap_raster_draws_exactly_the_flagged_samples(n_markers):
    rate = 100.0
    t = np.arange(300) / rate
    labels = [f"L{i:03d}" for i in range(n_markers)]
    missing = np.zeros((300, n_markers), bool)
    filled = np.zeros((300, n_markers), bool)
    missing[10:40, 1] = True
    filled[10:30, 1] = True  # 30-39 left missing
    missing[123, 3] = True  # a single missing frame
    filled[200:205, 4] = True
    missing[299, 4] = True  # last frame
    fig = plot_gaps(t, missing, filled, labels, sentence_bounds=[0.0, 1.5])
    (ax,) = fig.axes
    shown = [tick.get_text() for tick in ax.get_yticklabels()]
    if n_markers > 30:
        assert shown == ["L001", "L003", "L004"]
        assert f"{n_markers - 3} markers with no missing samples not shown" in ax.get_title()
    else:
        assert shown == labels
        assert "not shown" not in ax.get_title()
    rows = [labels.index(s) for s in shown]
    got_missing = _drawn_mask(ax, "missing", t, 1 / rate, len(shown))
    got_filled = _drawn_mask(ax, "filled", t, 1 / rate, len(shown))
    np.testing.assert_array_equal(got_missing, (missing & ~filled)[:, rows])
    np.testing.assert_array_equal(got_filled, filled[:, rows])
    assert sum(1 for ln in ax.get_lines() if ln.get_xdata()[0] == 1.5) == 1


def test_gap_raster_of_a_dense_layout_keeps_the_most_affected_rows():
    rate, n = 30.0, 2000
    t = np.arange(200) / rate
    labels = [f"V{i:04d}" for i in range(n)]
    missing = np.zeros((200, n), bool)
    gaps = {j: 1 + (j * 7) % 50 for j in range(0, n, 20)}  # 100 markers with gaps
    for j, length in gaps.items():
        missing[50:50 + length, j] = True
    fig = plot_gaps(t, missing, np.zeros_like(missing), labels, max_rows=40)
    (ax,) = fig.axes
    shown = [tick.get_text() for tick in ax.get_yticklabels()]
    longest = sorted(gaps, key=lambda j: (-gaps[j], j))[:40]
    assert shown == [labels[j] for j in sorted(longest)]
    assert "the 40 markers with the most flagged samples are shown, of 100" in ax.get_title()
    assert fig.get_size_inches()[1] < 10
    rows = [labels.index(x) for x in shown]
    np.testing.assert_array_equal(_drawn_mask(ax, "missing", t, 1 / rate, 40), missing[:, rows])
    _assert_legible(fig, ax)


def test_gap_raster_with_nothing_missing():
    t = np.arange(10) / 10.0
    none = np.zeros((10, 50), bool)
    fig = plot_gaps(t, none, none, [str(i) for i in range(50)])
    ax = fig.axes[0]
    assert "not shown" not in ax.get_title() and "0 filled, 0 left missing" in ax.get_title()
    assert any("no missing or filled samples in any of the 50 markers" in x.get_text()
               for x in ax.texts)


def test_markers_figure(face):
    neutral, labels = face
    fig = plot_markers(neutral, labels, highlight=["1", "7"])
    front, side = fig.axes[:2]
    assert sorted(t.get_text() for t in front.texts) == sorted(labels)
    assert "mm" in front.get_xlabel() and "mm" in front.get_ylabel() and "mm" in side.get_xlabel()
    with pytest.raises(InputError, match="Nose"):
        plot_markers(neutral, labels, highlight=["Nose"])


def test_selection_agreement():
    table = pd.DataFrame({"order": [1, 2, 3, 4],
                          "S1": ["40", "12", "7", "3"],
                          "S2": ["12", "40", "9", "7"],
                          "GRID": ["40", "5", "12", ""]})
    c = selection_counts(table, k=2)
    assert c["marker"].tolist() == ["40", "12", "5"]
    assert c["count"].tolist() == [3, 2, 1]
    assert c.loc[0, "S2"] == 2 and np.isnan(c.loc[2, "S1"])
    c3 = selection_counts(table, k=3)
    assert c3.set_index("marker").loc["12", "count"] == 3
    fig = plot_selection_agreement(table, k=3)
    heat, bar = fig.axes[:2]
    assert [t.get_text() for t in heat.get_xticklabels()] == ["S1", "S2", "GRID"]
    assert [t.get_text() for t in heat.get_yticklabels()] == c3["marker"].tolist()
    assert [p.get_width() for p in bar.patches] == c3["count"].tolist()
    assert heat.get_xlabel() and heat.get_ylabel() and bar.get_xlabel()


# ---------------------------------------------------------------- legibility


def _text_boxes(fig, ax):
    """Rendered extents of an axes' tick labels and texts (an annotation's text alone)."""
    from matplotlib.text import Text

    fig.draw_without_rendering()
    r = fig._get_renderer()
    ticks = [t for t in ax.get_xticklabels() + ax.get_yticklabels()
             if t.get_visible() and t.get_text()]
    return ([t.get_window_extent(r) for t in ticks],
            [(t.get_text(), Text.get_window_extent(t, r)) for t in ax.texts])


def _assert_legible(fig, ax):
    ticks, texts = _text_boxes(fig, ax)
    boxes = ticks + [b for _, b in texts]
    for i in range(len(boxes)):
        for j in range(i + 1, len(boxes)):
            assert not boxes[i].overlaps(boxes[j]), (i, j)
    inner = ax.get_window_extent(fig._get_renderer())
    for text, b in texts:  # labels stay inside the axes, off the tick labels
        assert inner.x0 <= b.x0 and b.x1 <= inner.x1 and inner.y0 <= b.y0, text


@pytest.mark.parametrize("n_datasets,n_markers", [(1, 7), (1, 57), (7, 44), (1, 468)])
def test_r_values_labels_never_overlap(n_datasets, n_markers):
    rng = np.random.default_rng(n_markers)
    tables = {}
    for d in range(n_datasets):
        r = np.sort(np.geomspace(8, 0.03, n_markers) * np.exp(0.2 * rng.standard_normal(
            n_markers)))[::-1]
        tables[f"dataset_{d}"] = pd.DataFrame({
            "order": np.arange(1, n_markers + 1),
            "marker": [f"L{j:03d}" for j in rng.permutation(468)[:n_markers]],
            "r": r, "r_rms": r, "r_normalised": r, "r_normalisation": "none"})
    fig = plot_r_values(tables)
    (ax,) = fig.axes
    _assert_legible(fig, ax)
    labelled = {t.get_text() for t in ax.texts} - {"ε = 0.25 mm", "ε = 0.5 mm", "ε = 1 mm"}
    assert labelled  # at least the last pivot of one dataset is named
    last = {t["marker"].iloc[-1] for t in tables.values()}
    assert labelled & last


def test_error_curves_leave_out_k_equal_n():
    n = 12
    k = np.arange(1, n + 1)
    err = np.where(k < n, 2.0 / k, 0.0)
    curve = pd.DataFrame({"k": k, "mean_abs_error_mm": err, "rel_error_per_marker": err / 4,
                          "median_abs_error_mm": err, "max_abs_error_mm": 3 * err})
    for kwargs in ({}, {"n_markers": {"S1": n}}):   # from the table's contract, or given
        fig = plot_error_curves({"S1": curve}, **kwargs)
        ax_abs, ax_rel = fig.axes
        for ax in (ax_abs, ax_rel):
            for line in ax.get_lines():
                assert n not in np.asarray(line.get_xdata()).tolist()
        assert 0.0 not in ax_rel.get_lines()[0].get_ydata()
        assert f"n = {n} (S1)" in fig.get_supxlabel()
        assert "undefined" in fig.get_supxlabel()
    # a curve without a k = n row keeps all its points
    fig = plot_error_curves({"S1": curve[curve["k"] < n]})
    assert len(fig.axes[1].get_lines()[0].get_xdata()) == n - 1
    assert fig.get_supxlabel() == ""


def test_sentence_sweep_with_two_takes_has_integer_ticks():
    rows = [{"n_sentences": s, "order": o, "marker": f"m{o}", "r_rms": 1.0 / o + 0.1 * s}
            for s in (1, 2) for o in range(1, 6)]
    fig = plot_sentence_sweep(pd.DataFrame(rows))
    (ax,) = fig.axes
    fig.draw_without_rendering()
    lo, hi = ax.get_xlim()
    ticks = [t for t in ax.get_xticks() if lo <= t <= hi]
    assert ticks and all(float(t).is_integer() for t in ticks)


def _sweep_table():
    """Two marker subsets x two k on one dataset, the subsets with different epsilon-ranks."""
    rows = []
    for sub, n, rank in (("face", 44, 6), ("lips_jaw", 27, 5)):
        for k in (5, 10):
            rows.append({"dataset": "grid_t1", "marker_subset": sub, "n_markers": n,
                         "tolerance_mm": 0.5, "k": k, "train_sentences": 1,
                         "epsilon_rank": rank, "heldout_mean_abs_error_mm": n / (100 * k),
                         "sentences_to_settle": np.nan})
    return pd.DataFrame(rows)


def test_sweep_summary_shows_each_subset_and_averages_nothing():
    from facemotion.plots.cross_subject import plot_sweep_summary

    table = _sweep_table()
    fig = plot_sweep_summary(table, title="sweep grid_landmarks")
    data_axes = [ax for ax in fig.axes if ax.axison]
    drawn = {ax.get_ylabel(): np.concatenate([ln.get_ydata() for ln in ax.get_lines()])
             for ax in data_axes}
    # epsilon-rank: each subset's own value, never their mean 5.5
    ranks = drawn["epsilon-rank"]
    assert sorted(ranks.tolist()) == [5, 6] and 5.5 not in ranks
    (rank_ax,) = [ax for ax in data_axes if ax.get_ylabel() == "epsilon-rank"]
    ticks = [t.get_text() for t in rank_ax.get_xticklabels()]
    assert ticks == ["face (44 markers)", "lips_jaw (27 markers)"]
    # error against k: one line per subset, named in the legend, every point as tabulated
    (err_ax,) = [ax for ax in data_axes if "error" in ax.get_ylabel()]
    legend = [t.get_text() for t in err_ax.get_legend().get_texts()]
    assert legend == ["face (44 markers)", "lips_jaw (27 markers)"]
    for line, (_, g) in zip(err_ax.get_lines(), table.groupby("marker_subset"), strict=True):
        np.testing.assert_allclose(line.get_ydata(), g.sort_values("k")[
            "heldout_mean_abs_error_mm"])
    assert [t.get_text() for t in err_ax.get_xticklabels()] == ["5", "10"]
    assert "dataset grid_t1" in fig.get_suptitle()


def test_sweep_summary_keeps_points_apart_when_an_unused_axis_changes_the_value():
    from facemotion.plots.cross_subject import plot_sweep_summary

    table = _sweep_table()
    table.loc[table["k"] == 10, "epsilon_rank"] += 1  # rank should not depend on k: keep both
    fig = plot_sweep_summary(table)
    values = np.concatenate([ln.get_ydata() for ax in fig.axes if ax.get_ylabel() ==
                             "epsilon-rank" for ln in ax.get_lines()])
    assert sorted(values.tolist()) == [5, 6, 6, 7]


# ---------------------------------------------------------------- titles at a fixed place


def assert_titles_clear(fig):
    """Every axes title is at its fixed place (y = 1: plots.style.set_title, no automatic lift)
    and overlaps no other text of the figure (tick labels, offset texts, axis labels)."""
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    r = canvas.get_renderer()
    titled = [ax for ax in fig.axes if ax.get_title(loc="center") or ax.get_title(loc="left")]
    assert titled
    titles = [t for ax in titled for t in (ax.title, ax._left_title) if t.get_text()]
    others = [t for t in fig.findobj(matplotlib.text.Text)
              if t.get_visible() and t.get_text() and t not in titles]
    for title in titles:
        assert title.get_position()[1] == 1.0, title.get_text()
        e = title.get_window_extent(r)
        for t in others:
            assert not e.overlaps(t.get_window_extent(r)), (title.get_text(), t.get_text())


def _titled_figures(face, qr_case):
    neutral, labels = face
    A, R, piv, order = qr_case
    t = np.arange(50) / 120.0
    offset = np.column_stack([100 + 1e-3 * np.sin(t), 1e-6 * np.cos(t), t])  # offset texts
    rows = [{"n_sentences": n, "order": o, "marker": f"m{o}", "r_rms": 1e-4 / o + 1.0}
            for n in range(1, 6) for o in range(1, 15)]
    mains = labels[:4]
    X = pd.DataFrame(np.cos(np.arange(4 * (len(labels) - 4))).reshape(4, -1), index=mains,
                     columns=labels[4:])
    return {
        "regions": lambda: plot_region_maps(neutral, labels, X, grid_n=20),
        "orthogonal": lambda: plot_orthogonal_directions(neutral, labels, R, order,
                                                         n_pivots=4, grid_n=20),
        "r_values": lambda: plot_r_values({"S1": _r_table(labels)}),
        "sweep": lambda: plot_sentence_sweep(pd.DataFrame(rows)),
        "trajectory": lambda: plot_trajectory(t, offset, offset + 1e-4, marker="Chin",
                                              sentence="s03", k=10),
        "gaps": lambda: plot_gaps(t, np.eye(50, 6, dtype=bool), np.zeros((50, 6), bool),
                                  labels[:6]),
        "markers": lambda: plot_markers(neutral, labels, highlight=["1"]),
        "selection": lambda: plot_selection_agreement(pd.DataFrame(
            {"order": [1, 2, 3], "S1": ["40", "12", "7"], "S2": ["12", "40", "9"]}), k=2),
    }


@pytest.mark.parametrize("name", ["regions", "orthogonal", "r_values", "sweep", "trajectory",
                                  "gaps", "markers", "selection"])
def test_titles_sit_at_the_top_of_their_axes_clear_of_every_other_text(face, qr_case, name):
    assert_titles_clear(_titled_figures(face, qr_case)[name]())


# ---------------------------------------------------------------- fixed layouts


def _curve(k_max, scale, with_extras=True):
    k = np.arange(1, k_max + 1)
    df = pd.DataFrame({"k": k, "mean_abs_error_mm": scale / k,
                       "rel_error_per_marker": 1.2 / k, "rel_error_pooled": 1.1 / k})
    if with_extras:
        df = df.assign(median_abs_error_mm=0.8 * scale / k, rms_error_mm=1.2 * scale / k,
                       max_abs_error_mm=5 * scale / k)
    return df


def _fixed_layout_figures(face):
    _, labels = face
    t = np.arange(400) / 120.0
    big = np.column_stack([12.5 * np.sin(t), -12.5 * np.cos(t), 0.01 * t])
    zero_last = _curve(33, 0.05)
    zero_last.loc[zero_last.index[-1], [c for c in zero_last.columns if c != "k"]] = 0.0
    with_zero = _curve(20, 0.005)
    with_zero.loc[4, "mean_abs_error_mm"] = 0.0
    sweep = [{"n_sentences": n, "order": o, "marker": f"marker_{o}" if n > 3 else f"m{o}",
              "r_rms": 0.01 * (1 + 1.0 / o) + 0.001 * n} for n in range(1, 31)
             for o in range(1, 15)]
    r_zero = _r_table(labels, 0.01)
    r_zero.loc[r_zero.index[-3:], "r_normalised"] = 0.0
    t_gap = np.arange(3000) / 100.0
    gaps = np.zeros((3000, 300), dtype=bool)
    for j in range(0, 300, 3):
        gaps[10 * j:10 * j + 5 + j, j] = True
    gap_labels = [f"lm{j:03d}" for j in range(300)]
    return {
        "gaps": lambda: plot_gaps(t_gap, gaps, gaps & (t_gap[:, None] > 10), gap_labels,
                                  sentence_bounds=np.arange(0, 30, 2.5)),
        "gaps_few": lambda: plot_gaps(t_gap, gaps[:, :6], gaps[:, :6], labels[:6]),
        "gaps_none": lambda: plot_gaps(t_gap, gaps[:, 1:3], gaps[:, 1:3], labels[:2]),
        "error_curve": lambda: plot_error_curves({"S1": zero_last}, n_markers={"S1": 33}),
        "error_curves_notes": lambda: plot_error_curves(
            {f"S{i}": _curve(56, 10.0 ** (i - 2), i % 2 == 0) for i in range(5)}
            | {"zero": with_zero, "all": zero_last}),
        "trajectory": lambda: plot_trajectory(t, big, big + 0.3, marker="Chin",
                                              sentence="s03", k=10),
        "trajectory_3_lines": lambda: plot_trajectory(
            t, big, big, marker="Chin", sentence="s03", k=10, in_basis=True,
            note="marker 56 requested, not in this dataset"),
        "sweep": lambda: plot_sentence_sweep(pd.DataFrame(sweep)),
        "r_values": lambda: plot_r_values({"S1": _r_table(labels, 0.01)}),
        "r_values_zeros": lambda: plot_r_values(
            {"S1": r_zero, "S2": _r_table(labels[::-1], 100.0), "S3": _r_table(labels)}),
    }


@pytest.mark.parametrize("name", ["gaps", "gaps_few", "gaps_none", "error_curve",
                                  "error_curves_notes", "trajectory",
                                  "trajectory_3_lines", "sweep", "r_values", "r_values_zeros"])
def test_fixed_layouts_keep_every_text_inside_and_apart(face, name):
    fig = _fixed_layout_figures(face)[name]()
    assert fig.get_layout_engine() is None  # laid out once, when built
    assert_laid_out(fig)
