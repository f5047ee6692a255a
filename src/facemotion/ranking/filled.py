"""How much of each ranked marker the data hold, and which first pivots are mostly filled.

Gap filling (interpolation, PCA from the other markers, copies) makes up samples; a marker
that is mostly made up can still come out as an early pivot of QR with column pivoting, its
"independent motion" then being the filling's. The ranking tables carry each marker's filled
and outlier fraction (from the gap report), and a pivot among the first k that is filled more
than a given share is named wherever the ranking is shown.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from facemotion.errors import InputError

#: The first pivots checked, and the filled share above which one is named (the defaults of
#: the settings qr.flag_pivots and qr.flag_filled_fraction).
FLAG_PIVOTS = 10
FLAG_FILLED_FRACTION = 0.5
#: A gap report's fill_method of a marker left out of A by qr.max_filled_fraction.
LEFT_OUT = "left out"


def marker_fractions(gap_report: pd.DataFrame) -> pd.DataFrame:
    """Per marker (index): ``filled_fraction`` (samples made up by gap filling, outliers
    replaced included) and ``outlier_fraction`` (samples refused as implausible), each of the
    marker's frames in the gap report."""
    need = ("marker", "frames", "filled_frames", "outlier_frames")
    missing = [c for c in need if c not in gap_report.columns]
    if missing:
        raise InputError(f"gap report: lacks column(s) {', '.join(missing)}")
    frames = gap_report["frames"].to_numpy(dtype=float)
    safe = np.where(frames > 0, frames, 1.0)
    return pd.DataFrame({
        "filled_fraction": np.where(frames > 0, gap_report["filled_frames"] / safe, 0.0),
        "outlier_fraction": np.where(frames > 0, gap_report["outlier_frames"] / safe, 0.0),
    }, index=gap_report["marker"].astype(str).to_numpy())


def with_fractions(table: pd.DataFrame, gap_report: pd.DataFrame) -> pd.DataFrame:
    """``table`` (one row per marker, column ``marker``) with ``filled_fraction`` and
    ``outlier_fraction`` appended; a marker the gap report lacks is an error."""
    fr = marker_fractions(gap_report)
    absent = [m for m in table["marker"].astype(str) if m not in fr.index]
    if absent:
        raise InputError(f"gap report: no row for marker(s) {', '.join(absent[:5])}")
    out = table.copy()
    for col in fr.columns:
        out[col] = fr.loc[table["marker"].astype(str), col].to_numpy()
    return out


def mostly_filled_pivots(table: pd.DataFrame, first_k: int = FLAG_PIVOTS,
                         share: float = FLAG_FILLED_FRACTION) -> pd.DataFrame:
    """Rows of an r-values table (with ``filled_fraction``) among the first ``first_k``
    pivots whose filled fraction exceeds ``share``."""
    if first_k < 1:
        raise InputError(f"first_k: must be at least 1, got {first_k}")
    if not 0 <= share < 1:
        raise InputError(f"share: must be in [0, 1), got {share}")
    rows = table[(table["order"] <= first_k) & (table["filled_fraction"] > share)]
    return rows.sort_values("order")


def describe_pivots(rows: pd.DataFrame) -> str:
    """``pivot 1 Mouth_Down 85 % filled; pivot 4 ...`` ('' for none)."""
    return "; ".join(f"pivot {int(r.order)} {r.marker} {100 * r.filled_fraction:.0f} % filled"
                     for r in rows.itertuples())


def left_out_markers(gap_report: pd.DataFrame) -> list[str]:
    """Markers of the gap report left out of A as mostly made up (:data:`LEFT_OUT`)."""
    return [str(m) for m in gap_report.loc[gap_report["fill_method"] == LEFT_OUT, "marker"]]
