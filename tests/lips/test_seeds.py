"""B&P Table 1 over seeds of the virtual lip talker: cells, aggregation, direction counts."""

import numpy as np
import pandas as pd
import pytest

from facemotion.errors import InputError
from facemotion.lips.pipeline import CHOSEN_READING, PAPER_TABLE1, VIEWS, LipSettings, run_virtual
from facemotion.lips.seeds import (
    COLUMNS,
    aggregate_seeds,
    direction_counts,
    seed_table1,
    table1_cells,
)
from facemotion.lips.virtual import make_virtual_talker


def _reconstruction(cells: dict) -> pd.DataFrame:
    """A reconstruction table: (reading, view, covariance) -> MSE, on the tracked points,
    plus a mesh-node row that must be ignored."""
    rows = [{"view": v, "point_set": "tracked_points", "covariance": c,
             "estimator_reading": r, "noise_var_model_units2": 0.0 if r == "pseudo_inverse"
             else 1e-3, "mse_per_dof_model_units2": x} for (r, v, c), x in cells.items()]
    rows.append({"view": "xy_all_points", "point_set": "mesh_nodes", "covariance": "10_modes",
                 "estimator_reading": "noise_term", "noise_var_model_units2": 1e-3,
                 "mse_per_dof_model_units2": 99.0})
    return pd.DataFrame(rows)


def _planted(frontal_modes_better: bool) -> dict:
    cells = {}
    for r in ("noise_term", "pseudo_inverse"):
        for v in VIEWS:
            full = 2.0 if (v == "xy_all_points" and frontal_modes_better
                           and r == "noise_term") else 0.5
            cells[r, v, "10_modes"], cells[r, v, "full_covariance"] = 1.0, full
    return cells


def test_cells_ratio_direction_and_paper_values():
    t = table1_cells(_reconstruction(_planted(True)), 10, "virtual", 3)
    assert list(t.columns) == list(COLUMNS) and len(t) == 6
    xy = t[(t.view == "xy_all_points")].set_index("estimator_reading")
    assert xy.loc["noise_term", "full_over_modes"] == 2.0 and xy.loc["noise_term", "modes_better"]
    assert xy.loc["pseudo_inverse", "full_over_modes"] == 0.5
    assert not xy.loc["pseudo_inverse", "modes_better"]
    assert t.chosen_reading.eq(t.estimator_reading == CHOSEN_READING).all()
    assert CHOSEN_READING == "noise_term"
    # the paper's frontal view: full / 10 modes = 7.50e-3 / 6.70e-3 (Table 1), 10 modes better
    p = xy.loc["noise_term"]
    assert p.paper_full_over_10_modes == pytest.approx(7.50e-3 / 6.70e-3)
    assert p.paper_10_modes_better
    assert (t.paper_mse_10_modes_model_units2 == [PAPER_TABLE1[v][0] for v in t.view]).all()
    # with another number of modes the paper's 10-mode cells do not apply
    other = _reconstruction({(r, v, "5_modes" if c == "10_modes" else c): x
                             for (r, v, c), x in _planted(True).items()})
    t5 = table1_cells(other, 5, "virtual", 3)
    assert t5.paper_full_over_10_modes.isna().all() and t5.n_modes.eq(5).all()


def test_a_missing_cell_is_named():
    cells = _planted(False)
    del cells["noise_term", "yz_all_points", "full_covariance"]
    with pytest.raises(InputError, match="seed 7: .*yz_all_points \\(noise_term\\)"):
        table1_cells(_reconstruction(cells), 10, "virtual", 7)


def test_aggregation_counts_the_frontal_direction_per_seed():
    # planted: 10 modes better on the frontal view for seeds 1 and 3 of 0-4 (noise term only)
    tables = [table1_cells(_reconstruction(_planted(s in (1, 3))), 10, "virtual", s)
              for s in (4, 2, 0, 3, 1)]
    t = aggregate_seeds(tables)
    assert t.seed.tolist() == sorted(t.seed.tolist()) and len(t) == 30
    assert t.view.tolist()[:3] == list(VIEWS)
    d = direction_counts(t).set_index(["estimator_reading", "view"])
    xy = d.loc["noise_term", "xy_all_points"]
    assert (xy.n_seeds, xy.n_modes_better, xy.seeds_modes_better) == (5, 2, "1 3")
    assert xy.n_paper_direction == 2 and xy.chosen_reading
    assert d.loc["pseudo_inverse", "xy_all_points"].n_modes_better == 0
    assert d.loc["noise_term", "yz_all_points"].n_paper_direction == 5   # paper: full better
    assert d.loc["noise_term", "xy_all_points"].median_full_over_modes == 0.5


def test_aggregation_rejects_a_repeated_seed_and_missing_columns():
    one = table1_cells(_reconstruction(_planted(False)), 10, "virtual", 2)
    with pytest.raises(InputError, match="lip subject virtual, seed 2 is given twice"):
        aggregate_seeds([one, one])
    with pytest.raises(InputError, match="lack the columns \\['modes_better'\\]"):
        aggregate_seeds([one.drop(columns="modes_better")])
    with pytest.raises(InputError, match="no per-seed tables"):
        aggregate_seeds([])


def test_seed_table1_is_the_talker_of_that_seed():
    spec = {"source": "virtual", "frames": 40}
    settings = LipSettings(train_frames=tuple(range(30)), test_frames=tuple(range(30, 40)),
                           n_modes=5)
    t = seed_table1(spec, settings, 2, "v")
    talker = make_virtual_talker(n_frames=40, seed=2)
    rec = run_virtual(talker, talker.recording, **settings.model_kwargs()).reconstruction
    ref = rec[(rec.point_set == "tracked_points") & (rec.view == "xy_all_points")
              & (rec.estimator_reading == "noise_term")].set_index("covariance")
    row = t[(t.view == "xy_all_points") & t.chosen_reading].iloc[0]
    assert row.mse_modes_model_units2 == ref.loc["5_modes", "mse_per_dof_model_units2"]
    assert row.full_over_modes == pytest.approx(
        ref.loc["full_covariance", "mse_per_dof_model_units2"]
        / ref.loc["5_modes", "mse_per_dof_model_units2"], rel=1e-12)
    assert np.all(t.seed == 2) and set(t.estimator_reading) == {"noise_term", "pseudo_inverse"}
    # another seed is another talker
    assert not np.allclose(seed_table1(spec, settings, 3, "v").mse_modes_model_units2,
                           t.mse_modes_model_units2)
    with pytest.raises(InputError, match="virtual lip talker only"):
        seed_table1({"source": "grid"}, settings, 0, "g")
