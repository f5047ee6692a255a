"""Which first pivots are mostly made up by gap filling: planted fractions, both sides of the
share, and the summary line that names them."""

import pandas as pd
import pytest

from facemotion.errors import InputError
from facemotion.ranking.filled import (
    describe_pivots,
    left_out_markers,
    mostly_filled_pivots,
    with_fractions,
)
from facemotion.study.summary import rank_lines


def _gaps():
    return pd.DataFrame({"marker": ["Chin", "Mouth_Down", "Lip", "Brow"],
                         "frames": [200, 200, 200, 0], "filled_frames": [0, 170, 101, 0],
                         "outlier_frames": [0, 20, 0, 0],
                         "fill_method": ["none", "pca", "pca", "none"]})


def _r_values(order):
    return pd.DataFrame({"order": range(1, len(order) + 1), "marker": order,
                         "r": [9.0, 5.0, 2.0, 1.0][:len(order)]})


def test_fractions_are_the_gap_reports_counts_over_frames():
    t = with_fractions(_r_values(["Mouth_Down", "Chin", "Lip", "Brow"]), _gaps())
    assert list(t.columns[-2:]) == ["filled_fraction", "outlier_fraction"]
    assert t["filled_fraction"].tolist() == [0.85, 0.0, 0.505, 0.0]
    assert t["outlier_fraction"].tolist() == [0.1, 0.0, 0.0, 0.0]
    with pytest.raises(InputError, match="no row for marker.s. Nose"):
        with_fractions(_r_values(["Nose"]), _gaps())


def test_a_mostly_filled_first_pivot_is_named_and_a_later_or_less_filled_one_is_not():
    t = with_fractions(_r_values(["Mouth_Down", "Chin", "Lip", "Brow"]), _gaps())
    assert describe_pivots(mostly_filled_pivots(t, 1, 0.5)) == "pivot 1 Mouth_Down 85 % filled"
    # both sides of the share: 50.5 % is more than a half, not more than 0.51
    assert mostly_filled_pivots(t, 3, 0.5)["marker"].tolist() == ["Mouth_Down", "Lip"]
    assert mostly_filled_pivots(t, 3, 0.51)["marker"].tolist() == ["Mouth_Down"]
    assert mostly_filled_pivots(t, 3, 0.85).empty  # not more than 85 %
    late = with_fractions(_r_values(["Chin", "Brow", "Mouth_Down"]), _gaps())
    assert mostly_filled_pivots(late, 2, 0.5).empty  # the 3rd pivot is not among the first 2
    with pytest.raises(InputError, match="share: must be in"):
        mostly_filled_pivots(t, 3, 1.0)


def test_left_out_markers_are_read_from_the_gap_report():
    g = _gaps()
    g.loc[1, "fill_method"] = "left out"
    assert left_out_markers(g) == ["Mouth_Down"]


def test_the_summary_names_them():
    rs = pd.DataFrame({"dataset": ["S1", "S2"], "tolerance_mm": [0.5, 0.5],
                       "tolerance_from": ["qr.tolerances_mm"] * 2, "epsilon_rank": [3, 4],
                       "mostly_filled_pivots": ["pivot 1 Mouth_Down 85 % filled", ""],
                       "left_out_filled": ["", "Lip"]})
    selected = pd.DataFrame({"S1": ["Mouth_Down", "Chin"], "S2": ["Chin", "Brow"]})
    lines = rank_lines(rs, selected)
    assert "  S1: mostly filled first pivots: pivot 1 Mouth_Down 85 % filled" in lines
    assert "  S2: left out as mostly filled: Lip" in lines
    assert not any("S2: mostly filled" in x or "S1: left out" in x for x in lines)
