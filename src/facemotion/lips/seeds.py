"""Basu & Pentland (1997) Table 1 on several seeds of the virtual lip talker.

One seed's Table 1 comes from `pipeline.run_virtual` on the talker of that seed; its cells are
kept per estimator reading (`pipeline.ESTIMATOR_READINGS`) and view, both columns of the table
in one row: the n-mode and the full-covariance MSE per DOF on the tracked points (the paper's
"all points"), their ratio full / n modes, and whether n modes beat the full covariance. The
paper's own cells and ratio sit beside them. The aggregation stacks the seeds; `direction_counts`
says on how many seeds each view goes the paper's way (for the frontal view, xy: 10 modes
better, ratio 1.12 in the paper).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.lips.pipeline import (
    CHOSEN_READING,
    PAPER_TABLE1,
    VIEWS,
    LipSettings,
    check_round_trip,
    run_virtual,
)
from facemotion.lips.virtual import make_virtual_talker

COLUMNS = ("lip_subject", "seed", "estimator_reading", "chosen_reading", "view", "n_modes",
           "noise_var_model_units2", "mse_modes_model_units2",
           "mse_full_covariance_model_units2", "full_over_modes", "modes_better",
           "paper_mse_10_modes_model_units2", "paper_mse_full_covariance_model_units2",
           "paper_full_over_10_modes", "paper_10_modes_better")


def table1_cells(reconstruction: pd.DataFrame, n_modes: int, subject: str,
                 seed: int) -> pd.DataFrame:
    """One seed's Table 1 (``reconstruction.tsv`` rows) as one row per reading and view."""
    rec = reconstruction[reconstruction["point_set"] == "tracked_points"]
    modes = f"{n_modes}_modes"
    rows = []
    for reading, part in rec.groupby("estimator_reading", sort=True):
        for view in VIEWS:
            cell = part[part["view"] == view].set_index("covariance")
            if not {modes, "full_covariance"} <= set(cell.index):
                raise InputError(f"lip subject {subject}, seed {seed}: Table 1 lacks the "
                                 f"{modes} or full-covariance cell of {view} ({reading})")
            m = float(cell.loc[modes, "mse_per_dof_model_units2"])
            f = float(cell.loc["full_covariance", "mse_per_dof_model_units2"])
            p10, pfull = PAPER_TABLE1[view] if n_modes == 10 else (np.nan, np.nan)
            rows.append({
                "lip_subject": subject, "seed": int(seed), "estimator_reading": reading,
                "chosen_reading": reading == CHOSEN_READING, "view": view, "n_modes": n_modes,
                "noise_var_model_units2": float(cell.loc[modes, "noise_var_model_units2"]),
                "mse_modes_model_units2": m, "mse_full_covariance_model_units2": f,
                "full_over_modes": f / m, "modes_better": bool(m < f),
                "paper_mse_10_modes_model_units2": p10,
                "paper_mse_full_covariance_model_units2": pfull,
                "paper_full_over_10_modes": pfull / p10, "paper_10_modes_better": p10 < pfull})
    return pd.DataFrame(rows, columns=list(COLUMNS))


def seed_table1(spec: dict, settings: LipSettings, seed: int, subject: str = "virtual",
                recording=None) -> pd.DataFrame:
    """Table 1 cells of the virtual lip talker ``spec`` (config ``lips.subjects``) simulated with
    ``seed``; ``recording``: its tracks as read back from file (checked), else its own."""
    if spec.get("source") != "virtual":
        raise InputError(f"lip subject {subject}: seeds apply to the virtual lip talker only "
                         f"(source {spec.get('source')!r})")
    talker = make_virtual_talker(n_frames=spec.get("frames", 150), seed=int(seed))
    rec = talker.recording
    if recording is not None:
        check_round_trip(talker, recording)
        rec = recording
    result = run_virtual(talker, rec, settings.normalisation, **settings.model_kwargs())
    return table1_cells(result.reconstruction, settings.n_modes, subject, seed)


def aggregate_seeds(tables: list[pd.DataFrame]) -> pd.DataFrame:
    """The seeds' tables stacked, sorted by lip subject, seed, reading and view; a seed given
    twice for a lip subject is an error."""
    if not tables:
        raise InputError("lip seeds: no per-seed tables to aggregate")
    out = pd.concat(tables, ignore_index=True)
    missing = [c for c in COLUMNS if c not in out.columns]
    if missing:
        raise InputError(f"lip seeds: per-seed tables lack the columns {missing}")
    key = ["lip_subject", "seed", "estimator_reading", "view"]
    dup = out[out.duplicated(key)]
    if len(dup):
        r = dup.iloc[0]
        raise InputError(f"lip seeds: lip subject {r['lip_subject']}, seed {r['seed']} is "
                         f"given twice")
    order = {v: i for i, v in enumerate(VIEWS)}
    out = out.sort_values(key, key=lambda s: s.map(order) if s.name == "view" else s)
    return out[list(COLUMNS)].reset_index(drop=True)


def direction_counts(table: pd.DataFrame) -> pd.DataFrame:
    """Per lip subject, reading and view: seeds, seeds where n modes beat the full covariance
    (as a space-separated list too), seeds on the paper's side, and the median ratio."""
    rows = []
    for (ls, reading, view), g in table.groupby(["lip_subject", "estimator_reading", "view"],
                                                sort=False):
        better = g[g["modes_better"].astype(bool)]["seed"].astype(int).tolist()
        paper = g["paper_10_modes_better"].iloc[0]
        same = [s for s, b in zip(g["seed"].astype(int), g["modes_better"].astype(bool),
                                  strict=True) if pd.notna(paper) and b == bool(paper)]
        rows.append({"lip_subject": ls, "estimator_reading": reading,
                     "chosen_reading": bool(g["chosen_reading"].iloc[0]), "view": view,
                     "n_seeds": len(g), "n_modes_better": len(better),
                     "seeds_modes_better": " ".join(map(str, better)),
                     "n_paper_direction": len(same),
                     "median_full_over_modes": float(g["full_over_modes"].median())})
    return pd.DataFrame(rows)
