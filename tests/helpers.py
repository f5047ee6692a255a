"""What many tests share: the repository, the shared real data, and stand-ins for Snakemake's
objects (for running scripts and adapters without Snakemake).

``SHARED_DATA`` is ``../shared/data`` beside the repository, or ``FACEMOTION_SHARED_DATA``. CI
always has it, so tests on it run and never skip (the ``shared_data`` fixture fails when it is
missing).
"""

import os
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
SHARED_DATA = Path(os.environ.get("FACEMOTION_SHARED_DATA") or REPO.parent / "shared" / "data")
SCHEMAS = REPO / "workflow" / "schemas"


def require_shared_data(root: Path = SHARED_DATA, parts=("animface", "grid")) -> Path:
    """``root`` if it holds the shared data's folders ``parts``; otherwise the test fails
    (never skips) with one line saying where it looked."""
    import pytest

    if not all((root / part).is_dir() for part in parts):
        pytest.fail(f"real data not found at {root} (expected {', '.join(parts)} there); set "
                    "FACEMOTION_SHARED_DATA to the shared data folder")
    return root


class Names(list):
    """A list whose named items are also attributes, like Snakemake's namedlist."""

    def __init__(self, items=(), **named):
        super().__init__(list(items) + list(named.values()))
        self._named = named
        for k, v in named.items():
            setattr(self, k, v)

    def items(self):
        return self._named.items()

    def keys(self):
        return self._named.keys()

    def __getitem__(self, key):
        return self._named[key] if isinstance(key, str) else super().__getitem__(key)


def assert_laid_out(fig):
    """An independent geometric check of a figure's layout, from the rendered extents at the
    report's resolution: every text is inside the figure; no two texts overlap (the small data
    labels a figure leaves out of its layout, ``in_layout=False``, excepted); no text outside
    the axes (tick labels, axis labels, titles, figure texts) covers a panel's frame."""
    from unittest import mock

    import matplotlib.text
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    from facemotion.plots.save import FIGURE_DPI

    fig.set_dpi(FIGURE_DPI)
    canvas = FigureCanvasAgg(fig)
    drawn = []  # the texts a draw draws (not, e.g., the labels of ticks out of view)
    draw = matplotlib.text.Text.draw

    def record(self, renderer):
        drawn.append(self)
        return draw(self, renderer)

    with mock.patch.object(matplotlib.text.Text, "draw", record):
        canvas.draw()
    r = canvas.get_renderer()
    box = fig.bbox
    texts = [t for t in dict.fromkeys(drawn)
             if t.get_visible() and t.get_text() and t.get_in_layout()]
    extents = [matplotlib.text.Text.get_window_extent(t, r) for t in texts]  # no arrows
    for t, e in zip(texts, extents, strict=True):
        assert (e.x0 >= box.x0 - 1 and e.x1 <= box.x1 + 1 and e.y0 >= box.y0 - 1
                and e.y1 <= box.y1 + 1), f"outside the figure: {t.get_text()!r}"
    for i, (t, e) in enumerate(zip(texts, extents, strict=True)):
        for u, f in zip(texts[i + 1:], extents[i + 1:], strict=True):
            assert not e.overlaps(f), f"overlap: {t.get_text()!r} and {u.get_text()!r}"
    inside = {id(t) for ax in fig.axes for t in ax.texts}
    inside |= {id(t) for ax in fig.axes if ax.get_legend() for t in ax.get_legend().findobj(
        matplotlib.text.Text)}
    frames = [ax.get_window_extent(r) for ax in fig.axes if ax.axison]
    for t, e in zip(texts, extents, strict=True):
        if id(t) not in inside:
            for frame in frames:
                assert not e.overlaps(frame), f"covers a panel: {t.get_text()!r}"


def untitled_subject(meta: dict) -> str | None:
    """The dataset (or lip subject) a per-dataset figure's sidecar says it shows, when none of
    its recorded titles names it; None when titled (or not a per-dataset figure)."""
    if not meta["schema_id"].startswith("facemotion/figure/"):
        return None
    wc, params = meta["config"].get("wildcards", {}), meta["config"].get("params", {})
    name = (params.get("label") or wc["dataset"]) if "dataset" in wc else \
        wc.get("lip_subject") or wc.get("subject")
    if not name:
        return None
    return None if any(name in t for t in meta.get("titles", [])) else name
