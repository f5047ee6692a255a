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
from facemotion.study.provenance import Provenance, save_figure, sidecar_path, write_table


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


def test_outputs_respect_the_umask(tmp_path):
    """mkstemp makes 0600 files; every writer gives 0666 less the umask, like open()."""
    import os
    import stat

    import numpy as np
    import pandas as pd

    from facemotion.ingest.displacement_file import save_displacements
    from facemotion.ingest.displacements import Displacements
    from facemotion.io.c3d import write_c3d
    from facemotion.io.recording import Recording
    from facemotion.io.trc import write_trc
    from facemotion.io.wide_csv import write_csv
    from facemotion.plots.animation import write_animation
    from facemotion.study.provenance import Provenance, write_table

    rec = Recording(["a", "b"], np.arange(12.0).reshape(2, 2, 3) + 1, 100.0)
    d = Displacements(np.zeros((6, 2)), ["a", "b"], ["s"], np.zeros(6), np.repeat([0, 1], 3),
                      100.0, np.zeros((2, 2), bool), np.zeros(2), np.zeros((2, 3)))
    old = os.umask(0o027)
    try:
        write_table(pd.DataFrame({"summary": [1]}), tmp_path / "t.tsv", "summary",
                    Provenance("demo"))
        write_c3d(tmp_path / "r.c3d", rec)
        write_trc(tmp_path / "r.trc", rec)
        write_csv(tmp_path / "r.csv", rec)
        save_displacements(tmp_path / "d.npz", d)
        write_animation(tmp_path / "a.gif", [np.zeros((8, 8, 3), np.uint8)] * 2, 10)
    finally:
        os.umask(old)
    files = sorted(tmp_path.iterdir())
    assert [p.name for p in files] == ["a.gif", "d.npz", "r.c3d", "r.csv", "r.trc",
                                      "t.meta.json", "t.tsv"]
    assert {oct(stat.S_IMODE(p.stat().st_mode)) for p in files} == {"0o640"}


def test_c3d_cut_by_the_file_size_limit_is_an_error(tmp_path):
    """ezc3d writes a C3D cut at the file-size limit without a word; write_c3d checks."""
    import subprocess
    import sys
    import textwrap

    code = textwrap.dedent(f"""
        import errno, resource
        import numpy as np
        from facemotion.io.c3d import write_c3d
        from facemotion.io.recording import Recording
        resource.setrlimit(resource.RLIMIT_FSIZE, (20000, 20000))
        rec = Recording(["a", "b", "c"], np.ones((3000, 3, 3)), 100.0)
        try:
            write_c3d("{tmp_path}/big.c3d", rec)
        except OSError as e:
            print(e.errno == errno.EIO, e.filename)
    """)
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert out.stdout.split() == ["True", f"{tmp_path}/big.c3d"], out.stderr
    assert list(tmp_path.iterdir()) == []


def test_an_input_hashed_again_gives_its_current_digest(tmp_path):
    """Job inputs are hashed once per process while unchanged; a file replaced or rewritten
    since (other content, same size) gets its new digest."""
    import os
    import time

    from facemotion.study.provenance import sha256_file

    f = tmp_path / "A.npz"
    f.write_bytes(b"a" * 1000)
    assert sha256_file(f, job_input=True) == hashlib.sha256(b"a" * 1000).hexdigest()
    assert sha256_file(f, job_input=True) == hashlib.sha256(b"a" * 1000).hexdigest()
    tmp = tmp_path / "A.tmp"
    tmp.write_bytes(b"b" * 1000)
    os.replace(tmp, f)  # atomically replaced, as every output is written
    assert sha256_file(f, job_input=True) == hashlib.sha256(b"b" * 1000).hexdigest()
    time.sleep(0.02)
    f.write_bytes(b"c" * 1000)  # rewritten in place
    assert sha256_file(f, job_input=True) == hashlib.sha256(b"c" * 1000).hexdigest()
    assert sha256_file(f) == hashlib.sha256(b"c" * 1000).hexdigest()


def test_a_figure_of_one_dataset_is_titled_with_it(tmp_path):
    """save_figure names the dataset (its label) in the title unless a title already does,
    and records the titles in the sidecar."""
    import json

    from matplotlib.figure import Figure

    from facemotion.study.provenance import Provenance, save_figure

    prov = Provenance(step="rank_markers", config={
        "wildcards": {"dataset": "S2a_star"}, "params": {"label": "S2a*"}}, inputs=[])
    fig = Figure()
    fig.subplots().set_title("Independent motion of each pivot")
    side = save_figure(fig, [tmp_path / "a.png"], "r_values", prov)
    assert json.loads(side.read_text())["titles"] == ["S2a*: Independent motion of each pivot"]
    fig = Figure()
    fig.suptitle("Errors, S2a*")
    side = save_figure(fig, [tmp_path / "b.png"], "r_values", prov)
    assert json.loads(side.read_text())["titles"] == ["Errors, S2a*"]   # already named
    agg = Provenance(step="summarise_ranking", config={"wildcards": {}, "params": {}},
                     inputs=[])
    fig = Figure()
    fig.suptitle("All datasets")
    side = save_figure(fig, [tmp_path / "c.png"], "r_values", agg)
    assert json.loads(side.read_text())["titles"] == ["All datasets"]
