"""Parameter sweeps across datasets and cross-subject summaries.

A sweep is a grid over the settings that matter (epsilon tolerance, k, number of training
sentences); the workflow expands it over every dataset and runs each point as a job.
"""

from __future__ import annotations

import itertools
from collections import Counter

import numpy as np
import pandas as pd

from facemotion.errors import InputError

GRID_KEYS = ("tolerance_mm", "k", "train_sentences", "marker_subset")
DEFAULTS = {"tolerance_mm": 0.5, "k": 10, "train_sentences": None, "marker_subset": None}


def _value_name(value) -> str:
    """A grid value as written in a point's name: floats in their shortest exact form."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        return str(value)
    return str(value) if isinstance(value, int) else repr(float(value))


def point_name(point: dict, axes) -> str:
    """The name of a sweep point from its value on each axis, as Snakemake's ``Paramspace``
    writes file names (``axis~value`` joined by ``_``), e.g. ``tolerance_mm~0.5_k~10``.

    A point's name depends only on its own values, so adding a value to a grid adds points
    without renaming the others."""
    return "_".join(f"{axis}~{_value_name(point[axis])}" for axis in axes) or "default"


def expand_grid(spec: dict) -> list[dict]:
    """The cartesian product of the sweep's value lists, in a fixed order.

    ``marker_subsets`` (name -> labels) becomes the axis ``marker_subset`` (its names, sorted);
    each point then carries the name and its ``markers``.  Each point's ``name`` is
    :func:`point_name` over the sweep's axes; a value repeated on an axis is an InputError.
    """
    spec = dict(spec)
    subsets = spec.pop("marker_subsets", None) or {}
    if subsets:
        spec["marker_subset"] = sorted(subsets)
    keys = [k for k in GRID_KEYS if spec.get(k)]
    values = [list(spec[k]) for k in keys]
    for key, vals in zip(keys, values, strict=True):
        names = [_value_name(v) for v in vals]
        if len(set(names)) != len(names):
            dup = sorted({n for n in names if names.count(n) > 1})
            raise InputError(f"sweep setting {key}: value(s) {', '.join(dup)} repeated")
    points = []
    for combo in itertools.product(*values) if keys else [()]:
        point = dict(DEFAULTS)
        point.update(dict(zip(keys, combo, strict=True)))
        if point["marker_subset"] is not None:
            point["markers"] = [str(m) for m in subsets[point["marker_subset"]]]
        point["name"] = point_name(point, keys)
        points.append(point)
    return points


def settled_after(sweep: pd.DataFrame, tolerance: float) -> int:
    """Sentences after which every first-pivot r_rms stays within ``tolerance`` (relative)
    of its final value (the same rule as the stability table)."""
    wide = sweep.pivot(index="n_sentences", columns="order", values="r_rms").sort_index()
    final = wide.iloc[-1]
    ok = (np.abs(wide - final) <= tolerance * np.abs(final)).all(axis=1).to_numpy()
    # the first n from which all later rows are within tolerance
    bad = np.flatnonzero(~ok)
    idx = 0 if bad.size == 0 else bad[-1] + 1
    return int(wide.index[min(idx, len(wide) - 1)])


def evaluate_point(train, held, point: dict, method: str = "auto", n_first: int = 10,
                   settle_tolerance: float = 0.1, r_normalisation: str = "none") -> dict:
    """One sweep point on one dataset (``train``/``held``: Displacements): epsilon-rank (the
    paper's rule, R under ``r_normalisation``), first pivots, held-out error at k, sentences
    for the first pivots to settle."""
    # imported here so the workflow can expand grids at parse time without the numerics
    from facemotion.ranking.epsilon_rank import epsilon_rank
    from facemotion.ranking.routes import rank_markers
    from facemotion.ranking.stability import sentence_sweep
    from facemotion.regions.prediction import error_curve

    if point.get("markers"):
        train = train.select_markers(point["markers"])
        held = held.select_markers(point["markers"]) if held is not None else None
    n_train = point.get("train_sentences")
    if n_train is not None:
        if n_train > len(train.sentences):
            raise InputError(f"sweep setting train_sentences={n_train} exceeds the dataset's "
                             f"{len(train.sentences)} training sentences")
        train = train.subset(list(range(n_train)))
    k = int(point["k"])
    n = len(train.labels)
    if k >= n:
        raise InputError(f"sweep setting k={k} must be smaller than the number of markers ({n})")
    ranking = rank_markers(train.A, train.labels, method=method)
    tol = float(point["tolerance_mm"])
    rank = epsilon_rank(ranking, [tol], normalisation=r_normalisation).iloc[0]
    row = {
        "marker_subset": point.get("marker_subset") or "all",
        "n_markers": n,
        "tolerance_mm": tol,
        "k": k,
        "train_sentences": len(train.sentences),
        "r_normalisation": r_normalisation,
        "epsilon_rank": int(rank["epsilon_rank"]),
        "diagonal_count": int(rank["diagonal_count"]),
        "redundant_markers": rank["redundant_markers"],
        "first_pivots": ",".join(ranking.labels_in_order[:n_first]),
    }
    if len(train.sentences) >= 2:
        sweep = sentence_sweep(train.A, train.labels, train.row_sentence,
                               n_pivots=min(12, n))
        row["sentences_to_settle"] = settled_after(sweep, settle_tolerance)
    else:
        row["sentences_to_settle"] = np.nan
    if held is not None:
        curve = error_curve(ranking, held.A, held.labels).set_index("k")
        row["heldout_mean_abs_error_mm"] = float(curve.loc[k, "mean_abs_error_mm"])
        row["heldout_rel_error_per_marker"] = float(curve.loc[k, "rel_error_per_marker"])
    else:
        row["heldout_mean_abs_error_mm"] = np.nan
        row["heldout_rel_error_per_marker"] = np.nan
    return row


def top_k_frequency(selected: pd.DataFrame, k: int = 10) -> pd.DataFrame:
    """How often each marker is among the first k pivots across the columns of a Table I."""
    cols = [c for c in selected.columns if c != "order"]
    counts: Counter = Counter()
    for c in cols:
        counts.update(selected[c].astype(str).iloc[:k])
    rows = sorted(counts.items(), key=lambda kv: (-kv[1], kv[0]))
    return pd.DataFrame({"marker": [r[0] for r in rows],
                         "count": [r[1] for r in rows],
                         "fraction": [r[1] / len(cols) for r in rows]})


#: markers the paper names, and the column of their pivot order in the talkers table
NAMED = {"40": "lower_lip_40", "56": "jaw_56", "34": "left_corner_34", "38": "right_corner_38",
         "36": "upper_lip_36"}


def talker_summary(r_values: dict[str, pd.DataFrame], curves: dict[str, pd.DataFrame]
                   ) -> tuple[pd.DataFrame, pd.DataFrame]:
    """One row per talker (``r_values`` and ``curves``: each talker's r_values.tsv and
    error_curve.tsv, in the same order): its first 10 pivots, the pivot order of each marker
    the paper names (-1 when the talker lacks it) and the held-out mean error at k = 10; and
    the talkers' first 16 pivots as the columns of a Table I (for :func:`top_k_frequency`)."""
    rows, selected = [], {"order": list(range(1, 17))}
    for talker, r in r_values.items():
        curve = curves[talker].set_index("k")
        order = list(r["marker"])
        selected[talker] = order[:16]
        row = {"talker": talker, "first_pivots": ",".join(order[:10])}
        for label, name in NAMED.items():
            row[f"rank_{name}"] = order.index(label) + 1 if label in order else -1
        row["heldout_mean_abs_error_mm_k10"] = float(curve.loc[10, "mean_abs_error_mm"])
        rows.append(row)
    return pd.DataFrame(rows), pd.DataFrame(selected)
