"""Sweep grids, cross-subject counts, the manifest and the script adapter's error handling."""

import json
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from facemotion.errors import InputError
from facemotion.study.manifest import build_manifest
from facemotion.study.provenance import Provenance, write_artifact, write_table
from facemotion.study.sweeps import expand_grid, settled_after, top_k_frequency


def test_expand_grid_is_the_cartesian_product_in_order():
    pts = expand_grid({"tolerance_mm": [0.25, 0.5], "k": [5, 10, 15]})
    assert len(pts) == 6
    assert pts[0] == {"tolerance_mm": 0.25, "k": 5, "train_sentences": None,
                      "marker_subset": None, "name": "tolerance_mm~0.25_k~5"}
    assert pts[-1]["tolerance_mm"] == 0.5 and pts[-1]["k"] == 15
    assert expand_grid({}) == [{"tolerance_mm": 0.5, "k": 10, "train_sentences": None,
                                "marker_subset": None, "name": "default"}]


def test_point_names_say_their_values_and_survive_a_new_grid_value():
    before = {p["name"]: p for p in expand_grid({"tolerance_mm": [0.5, 1], "k": [5, 10]})}
    after = {p["name"]: p for p in expand_grid({"tolerance_mm": [0.25, 0.5, 1],
                                                "k": [5, 7, 10]})}
    assert set(before) <= set(after)  # adding values adds points, renames none
    for name, point in before.items():
        assert after[name] == point
        tol, k = name.split("_k~")
        assert float(tol.removeprefix("tolerance_mm~")) == point["tolerance_mm"]
        assert int(k) == point["k"]
    pts = expand_grid({"train_sentences": [3], "marker_subsets": {"lips": ["a", "b"]}})
    assert [p["name"] for p in pts] == ["train_sentences~3_marker_subset~lips"]
    with pytest.raises(InputError, match="tolerance_mm: value.*0.5 repeated"):
        expand_grid({"tolerance_mm": [0.5, 0.50]})


def test_settled_after_finds_the_last_excursion():
    rows = []
    values = {1: [5.0, 2.0], 2: [3.0, 2.5], 3: [3.05, 2.02], 4: [3.0, 2.0]}
    for n, vals in values.items():
        for order, v in enumerate(vals, 1):
            rows.append({"n_sentences": n, "order": order, "marker": str(order), "r_rms": v})
    sweep = pd.DataFrame(rows)
    assert settled_after(sweep, 0.05) == 3   # n=2 is 25 % off for order 2
    assert settled_after(sweep, 0.7) == 1


def test_top_k_frequency_counts_datasets():
    table = pd.DataFrame({"order": [1, 2, 3], "A": ["40", "34", "38"], "B": ["40", "56", "34"]})
    freq = top_k_frequency(table, k=2).set_index("marker")
    assert freq.loc["40", "count"] == 2 and freq.loc["40", "fraction"] == 1.0
    assert freq.loc["34", "count"] == 1 and "38" not in freq.index


def test_manifest_lists_the_current_jobs_and_detects_tampering(tmp_path, monkeypatch):
    """Planted: job 1 writes a table that job 2 reads; job 2 writes a table and a figure; a
    stale job (a subject no longer in the sheet) left its table. From job 2's table the
    manifest reaches job 2's figure (same job) and job 1's table (an input), not the stale
    one; a tampered file and a corrupt sidecar are errors naming the file."""
    monkeypatch.chdir(tmp_path)
    df = pd.DataFrame({"order": [1], "marker": ["40"], "r": [1.0], "r_rms": [0.1],
                       "r_rms_frame": [0.17], "r_normalised": [1.0], "r_normalisation": ["none"]})
    a = "results/x/qr/r_values.tsv"
    write_table(df, a, "r_values", Provenance("rank_markers", job_outputs=[a]))
    b, fig = "results/tables/summary.tsv", "results/tables/summary_plot.png"
    prov = Provenance("tabulate", inputs=[a], job_outputs=[b, fig])
    write_table(df, b, "summary", prov)
    write_artifact(fig, b"png", "figure/summary", prov)
    write_table(df, "results/old/qr/r_values.tsv", "r_values", Provenance("rank_markers"))
    Path("results/old/qr/r_values.meta.json").write_text("garbage")  # stale: never read
    m = build_manifest("results", targets=[b])
    assert list(m["path"]) == sorted([a, b, fig])
    assert m.set_index("path").loc[a, "schema_id"] == "facemotion/r_values"
    assert m.set_index("path").loc[a, "sidecar"] == "results/x/qr/r_values.meta.json"
    # the manifest job writes its TSV without pandas: the same bytes as pandas' table
    from facemotion.study.manifest import manifest_rows, manifest_tsv
    from facemotion.study.provenance import table_bytes

    assert manifest_tsv(manifest_rows("results", targets=[b])) == table_bytes(m)
    with open(a, "a") as f:
        f.write("tampered\n")
    with pytest.raises(InputError, match="checksum differs"):
        build_manifest("results", targets=[b])
    Path("results/tables/summary.meta.json").write_text('{"outputs": [')
    with pytest.raises(InputError, match=r"^results/tables/summary\.meta\.json: not a valid "
                       r"sidecar \(JSONDecodeError"):
        build_manifest("results", targets=[b])


def test_script_adapter_turns_errors_into_one_line(tmp_path):
    code = textwrap.dedent(f"""
        from types import SimpleNamespace
        from facemotion.errors import InputError
        from facemotion.study.adapter import run_step
        sm = SimpleNamespace(rule="demo", log=["{tmp_path}/demo.log"], input=[], params={{}},
                             wildcards={{}})
        def main(sm, log, prov):
            raise InputError("file x.c3d: marker '13' missing in every frame")
        run_step(sm, main)
    """)
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 1
    assert proc.stderr.strip() == ("facemotion: demo: file x.c3d: marker '13' missing in "
                                   "every frame")
    assert "marker '13'" in (tmp_path / "demo.log").read_text()
    assert "Traceback" not in proc.stderr


def test_sidecar_records_params_and_wildcards(tmp_path):
    from types import SimpleNamespace

    from facemotion.study.adapter import provenance_for

    f = tmp_path / "in.npz"
    f.write_bytes(np.zeros(3).tobytes())
    sm = SimpleNamespace(rule="rank_markers", input=[str(f)],
                         params={"tolerances_mm": [0.5]}, wildcards={"dataset": "S1"})
    prov = provenance_for(sm)
    meta = prov.sidecar("r_values", "1", [])
    assert meta["config"] == {"params": {"tolerances_mm": [0.5]}, "wildcards": {"dataset": "S1"}}
    assert meta["inputs"][0]["path"] == str(f)
    json.dumps(meta)


def _toy_displacements(n_sent=6, n=8, seed=0):
    from facemotion.ingest.displacements import Displacements

    rng = np.random.default_rng(seed)
    W = rng.standard_normal((3, n)) * 3
    blocks, rs, rf = [], [], []
    for s in range(n_sent):
        F = 120
        src = np.sin(np.linspace(0, 6, F)[:, None, None] * rng.uniform(1, 3, (1, 3, 3)))
        d = np.einsum("fck,kn->fcn", src, W) + 0.3 * rng.standard_normal((F, 3, n))
        blocks.append(d.reshape(3 * F, n))
        rs.append(np.full(3 * F, s))
        rf.append(np.repeat(np.arange(F), 3))
    A = np.vstack(blocks)
    F = A.shape[0] // 3
    return Displacements(A, [f"m{j}" for j in range(n)], [f"s{s}" for s in range(n_sent)],
                         np.concatenate(rs), np.concatenate(rf), 100.0,
                         np.zeros((F, n), bool), np.zeros(F), rng.normal(size=(n, 3)))


def test_marker_subset_axis_selects_columns():
    from facemotion.ranking.routes import rank_markers
    from facemotion.study.sweeps import evaluate_point

    pts = expand_grid({"k": [2], "marker_subsets": {"lips": ["m1", "m3", "m5", "m7"],
                                                    "all_but_one": [f"m{j}" for j in range(7)]}})
    assert [p["marker_subset"] for p in pts] == ["all_but_one", "lips"]
    assert pts[1]["markers"] == ["m1", "m3", "m5", "m7"]
    d = _toy_displacements()
    train, held = d.subset([0, 1, 2, 3]), d.subset([4, 5])
    row = evaluate_point(train, held, pts[1])
    assert row["n_markers"] == 4 and row["marker_subset"] == "lips"
    # independent reference: the ranking of the four columns alone
    sub = train.select_markers(["m1", "m3", "m5", "m7"])
    assert np.array_equal(sub.A, train.A[:, [1, 3, 5, 7]])
    ref = rank_markers(train.A[:, [1, 3, 5, 7]], ["m1", "m3", "m5", "m7"])
    assert row["first_pivots"] == ",".join(ref.labels_in_order)
    with pytest.raises(InputError, match="mX"):
        train.select_markers(["m1", "mX"])


def test_the_manifest_job_does_not_import_pandas():
    """The study's last job (write_manifest) starts without pandas' import (~0.5 s)."""
    import subprocess
    import sys

    code = ("import sys, facemotion.study.manifest, facemotion.study.adapter; "
            "print('pandas' in sys.modules)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert out.strip() == "False"


def test_talker_summary_ranks_the_papers_named_markers():
    """Per talker: the first 10 pivots, the pivot order of 40, 56, 34, 38, 36 (-1 when the
    talker lacks one) and the error at k = 10; the first 16 pivots as Table I columns."""
    from facemotion.study.sweeps import talker_summary, top_k_frequency

    orders = {"T1": [str(m) for m in [40, 34, 38, 2, 36] + list(range(60, 75)) + [56]],
              "T2": [str(m) for m in [34, 40, 36] + list(range(60, 80))]}
    r_values = {t: pd.DataFrame({"order": range(1, len(o) + 1), "marker": o})
                for t, o in orders.items()}
    curves = {t: pd.DataFrame({"k": range(1, 21), "mean_abs_error_mm": np.arange(1, 21) / i})
              for i, t in enumerate(orders, start=1)}
    table, selected = talker_summary(r_values, curves)
    assert list(table["talker"]) == ["T1", "T2"]
    assert table.loc[0, "first_pivots"] == "40,34,38,2,36,60,61,62,63,64"
    ranks = table[["rank_lower_lip_40", "rank_jaw_56", "rank_left_corner_34",
                   "rank_right_corner_38", "rank_upper_lip_36"]].to_numpy()
    np.testing.assert_array_equal(ranks, [[1, 21, 2, 3, 5], [2, -1, 1, -1, 3]])
    np.testing.assert_allclose(table["heldout_mean_abs_error_mm_k10"], [10.0, 5.0])
    assert list(selected.columns) == ["order", "T1", "T2"] and len(selected) == 16
    freq = top_k_frequency(selected, k=3).set_index("marker")["count"]
    assert freq.to_dict() == {"34": 2, "40": 2, "36": 1, "38": 1}
