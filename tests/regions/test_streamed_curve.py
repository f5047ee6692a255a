"""The held-out error curve from blocks of rows against the whole-matrix curve, and its median
against numpy's median of the residual distances computed directly (an independent route:
least squares for X, no R^-1 update)."""

import numpy as np
import pytest

from facemotion.ranking.routes import rank_markers
from facemotion.regions import streamed_curve as sc
from facemotion.regions.prediction import error_curve
from facemotion.regions.streamed_curve import streamed_error_curve


def _data(frames_held: int):
    rng = np.random.default_rng(frames_held)
    n = 30
    S = rng.normal(size=(3 * (2000 + frames_held), 5))
    A = S @ rng.normal(size=(5, n)) + 0.05 * rng.normal(size=(S.shape[0], n))
    labels = [f"M{j:02d}" for j in range(n)]
    return A[:6000], A[6000:], labels


@pytest.mark.parametrize("tile", [None, 16])
@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("frames_held,block", [(401, 37), (400, 400), (250, 1)])
def test_streamed_curve_equals_the_whole_matrix_curve(monkeypatch, frames_held, block,
                                                      threads, tile):
    """Tiles of 256 frames (marker-major) and of 16 (one matrix per axis)."""
    monkeypatch.setattr(sc, "TILE_FRAMES", tile)
    train, held, labels = _data(frames_held)
    rk = rank_markers(train, labels, method="gram")
    whole = error_curve(rk, held, labels, k_max=8)
    blocks = lambda: (held[a:a + 3 * block] for a in range(0, held.shape[0], 3 * block))  # noqa: E731
    streamed = streamed_error_curve(rk, blocks, labels, k_max=8, threads=threads)
    assert list(streamed["main_markers"]) == list(whole["main_markers"])
    # the residuals of a block agree with the whole matrix's to round-off (BLAS blocks its
    # sums by the rows it is given); the selections (median, max) are exact on them
    for col in ("mean_abs_error_mm", "rms_error_mm", "rel_error_per_marker", "rel_error_pooled",
                "max_abs_error_mm", "median_abs_error_mm"):
        np.testing.assert_allclose(streamed[col], whole[col], rtol=1e-12)
    if block == frames_held:  # one block: the very same arithmetic, the very same numbers
        assert list(streamed["median_abs_error_mm"]) == list(whole["median_abs_error_mm"])
    # the median at k = 3 from the residuals of an independent least-squares fit
    order = [labels.index(m) for m in rk.labels_in_order]
    main, sec = order[:3], order[3:]
    X = np.linalg.lstsq(train[:, main], train[:, sec], rcond=None)[0]
    E = held[:, sec] - held[:, main] @ X
    dist = np.sqrt((E.reshape(-1, 3, len(sec)) ** 2).sum(axis=1))
    np.testing.assert_allclose(streamed["median_abs_error_mm"][2], np.median(dist), rtol=1e-9)
    assert streamed["median_abs_error_mm"][2] != pytest.approx(np.mean(dist), rel=1e-3)


def _counted(held, block):
    """blocks() over ``held`` in blocks of ``block`` frames, and the count of passes made."""
    passes = []

    def blocks():
        passes.append(1)
        return (held[a:a + 3 * block] for a in range(0, held.shape[0], 3 * block))
    return blocks, passes


def test_one_pass_after_the_pilot_when_its_sample_holds_the_median():
    """The pilot pass (every 8th frame) and the main pass: two calls of blocks()."""
    train, held, labels = _data(401)
    rk = rank_markers(train, labels, method="gram")
    blocks, passes = _counted(held, 50)
    streamed_error_curve(rk, blocks, labels, k_max=8)
    assert len(passes) == 2


@pytest.mark.parametrize("threads", [1, 2])
@pytest.mark.parametrize("where", ["below", "above", "everything"])
def test_the_median_is_exact_when_the_first_interval_misses_or_overflows(monkeypatch, where,
                                                                        threads):
    """The first interval below or above the middle values, or holding every value with room
    to keep 16 values per k: the fallback passes (ranges of bit patterns, narrowed until the
    values fit) still select the whole-matrix median, in more passes."""
    train, held, labels = _data(400)
    rk = rank_markers(train, labels, method="gram")
    whole = error_curve(rk, held, labels, k_max=8)

    def first(pilot, rank, cap, threads):
        out = {}
        for k in range(1, rank + 1):
            S = np.sort(np.concatenate([v for part in pilot for v in part.values[k]]))
            lo, hi = {"below": (0, S[S.size // 10]), "above": (S[-S.size // 10], S[-1]),
                      "everything": (0.0, np.inf)}[where]
            bits = np.array([lo, hi]).view(np.int64)
            out[k] = [sc._Probe(None, int(bits[0]), int(bits[1]), cap, threads)]
        return out

    monkeypatch.setattr(sc, "_first_probes", first)
    monkeypatch.setattr(sc, "TILE_FRAMES", 16)  # three tiles a block: both threads work
    if where == "everything":
        monkeypatch.setattr(sc, "KEEP_BYTES", 8 * 16 * 8)
    blocks, passes = _counted(held, 37)
    streamed = streamed_error_curve(rk, blocks, labels, k_max=8, threads=threads)
    assert len(passes) > 2
    assert list(streamed["median_abs_error_mm"]) == list(whole["median_abs_error_mm"])


def test_the_median_among_many_equal_distances(monkeypatch):
    """Every held-out frame the same: each marker's distance repeats in every frame; with room
    to keep 16 values per k, the ranges narrow to the one repeated value."""
    train, held, labels = _data(300)
    held = np.tile(held[:3], (300, 1))
    rk = rank_markers(train, labels, method="gram")
    whole = error_curve(rk, held, labels, k_max=8)
    monkeypatch.setattr(sc, "KEEP_BYTES", 8 * 16 * 8)
    blocks, passes = _counted(held, 64)
    streamed = streamed_error_curve(rk, blocks, labels, k_max=8)
    assert len(passes) > 2
    assert list(streamed["median_abs_error_mm"]) == list(whole["median_abs_error_mm"])
