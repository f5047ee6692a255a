"""The study's interactive 3-D page: markers, regions, the designed set, per-marker details."""

import json

import pandas as pd

from facemotion.ingest.displacement_file import load_displacements
from facemotion.plots.face3d import FaceView, face_page, regions_from_coefficients
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def view(label, npz, coefficients, r_values, markers, marker_set) -> FaceView:
    d = load_displacements(npz)
    coef = pd.read_csv(coefficients, sep="\t", dtype={"main_marker": str})
    coef = coef.set_index("main_marker")
    coef.columns = [str(c) for c in coef.columns]
    regions = regions_from_coefficients(d.labels, {m: coef.loc[m].to_dict() for m in coef.index})
    r = pd.read_csv(r_values, sep="\t", dtype={"marker": str})
    order = dict(zip(r["marker"], r["order"], strict=True))
    per = pd.read_csv(markers, sep="\t", dtype={"marker": str}).set_index("marker").loc[d.labels]
    with open(marker_set, encoding="utf-8") as f:
        selected = json.load(f)["selected"]
    return FaceView(label, d.labels, d.neutral, regions, [int(order[m]) for m in d.labels],
                    selected, per["expected_error_mm"].to_numpy(),
                    per["error_low_mm"].to_numpy(), per["error_high_mm"].to_numpy())


def main(sm, log, prov):
    i = sm.input
    views = [view(label, *files) for label, *files in zip(
        sm.params.labels, i.npz, i.coefficients, i.r_values, i.markers, i.marker_set,
        strict=True)]
    html = face_page(views, f"facemotion study '{sm.params.study}'")
    write_artifact(sm.output.page, html.encode("utf-8"), "face_3d_page", prov)


run_step(snakemake, main)  # noqa: F821
