"""Provenance sidecars and byte-identical outputs."""

import hashlib
import json

import matplotlib

matplotlib.use("Agg")
import pandas as pd  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

from facemotion import __version__  # noqa: E402
from facemotion.errors import InputError  # noqa: E402
from facemotion.provenance import (  # noqa: E402
    Provenance,
    save_figure,
    sidecar_path,
    write_table,
)


def _fig():
    fig = Figure(figsize=(3, 2))
    ax = fig.add_subplot()
    ax.plot([0, 1, 2], [1, 0, 2], label="x")
    ax.set_title("title")
    ax.legend()
    return fig


def test_table_sidecar_records_inputs_config_and_checksums(tmp_path):
    inp = tmp_path / "in.txt"
    inp.write_text("data")
    prov = Provenance("rank_markers", {"params": {"k": 10}}, [str(inp)])
    out = tmp_path / "r_values.tsv"
    df = pd.DataFrame({"order": [1, 2], "marker": ["40", "56"], "r": [3.0, 2.0],
                       "r_rms": [0.1, 0.2], "r_rms_frame": [0.17, 0.35], "r_normalised": [3.0, 2.0],
                       "r_normalisation": ["none", "none"]})
    side = write_table(df, out, "r_values", prov)
    assert side == sidecar_path(out) == tmp_path / "r_values.meta.json"
    meta = json.loads(side.read_text())
    assert meta["schema_id"] == "facemotion/r_values"
    assert meta["package_version"] == __version__
    assert meta["config"] == {"params": {"k": 10}}
    assert meta["inputs"][0]["sha256"] == hashlib.sha256(b"data").hexdigest()
    assert meta["outputs"][0]["sha256"] == hashlib.sha256(out.read_bytes()).hexdigest()
    # Labels stay labels: '40' is written as 40 in a text table and read back as a label
    assert out.read_text().splitlines()[1].split("\t")[1] == "40"


def test_table_missing_required_column_is_refused(tmp_path):
    with pytest.raises(InputError, match="lacks required columns"):
        write_table(pd.DataFrame({"order": [1]}), tmp_path / "r.tsv", "r_values",
                    Provenance("x"))
    assert not (tmp_path / "r.tsv").exists()


def test_figures_are_byte_identical(tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    for d in (a, b):
        save_figure(_fig(), [d / "f.png", d / "f.pdf", d / "f.svg"], "test", Provenance("x"))
    for suffix in ("png", "pdf", "svg"):
        assert (a / f"f.{suffix}").read_bytes() == (b / f"f.{suffix}").read_bytes()
    meta = json.loads((a / "f.meta.json").read_text())
    assert [o["path"].split("/")[-1] for o in meta["outputs"]] == ["f.png", "f.pdf", "f.svg"]
