"""The top-level API: lazy and light imports, names that resolve, results as pandas."""

import json
import subprocess
import sys

import numpy as np
import pytest

import facemotion as fm
from facemotion import lips
from facemotion.io.recording import Recording
from facemotion.io.trc import write_trc
from facemotion.io.wide_csv import write_csv

HEAVY = ("numpy", "scipy", "pandas", "matplotlib", "snakemake", "ezc3d", "click")


def test_import_is_light():
    code = ("import sys, json, facemotion; "
            f"print(json.dumps(sorted(m for m in sys.modules if m.split('.')[0] in {HEAVY!r})))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout
    assert json.loads(out) == []


def test_every_public_name_resolves():
    assert sorted(fm.__all__) == sorted([*fm._LAZY, *fm._SUBMODULES])
    for name in fm.__all__:
        assert getattr(fm, name) is not None, name
        assert name in dir(fm)
    for name in lips.__all__:
        assert getattr(lips, name) is not None, name
    with pytest.raises(AttributeError):
        fm.no_such_name  # noqa: B018
    assert fm.rank_markers.__module__ == "facemotion.ranking.routes"
    assert fm.fit_regions.__name__ == "fit_coefficients"


def test_functions_named_like_a_submodule_stay_functions():
    code = ("import facemotion.lips.pipeline, facemotion.lips.llse; "
            "from facemotion.lips.pca import Modes; "
            "from facemotion import lips; import facemotion.lips.pca; "
            "print(callable(lips.modes), lips.modes.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["True", "facemotion.lips"]
    code = ("import facemotion as fm; from facemotion.ranking.stability import stability; "
            "import facemotion.ranking.stability; print(callable(fm.sentence_sweep), "
            "fm.sentence_sweep.__module__)")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                         check=True).stdout.split()
    assert out == ["True", "facemotion.ranking.stability"]


def _rec(frames=40, n=5, seed=0, source=""):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(frames, n, 3)) * 3 + np.arange(n)[None, :, None] * 20
    return Recording([f"M{j}" for j in range(n)], pts, 50.0, source=source)


def test_read_infers_format_from_the_suffix(tmp_path):
    rec = _rec()
    write_trc(tmp_path / "a.TRC", rec)
    write_csv(tmp_path / "b.csv", rec)
    for name in ("a.TRC", "b.csv"):
        got = fm.read(tmp_path / name)
        assert got.labels == rec.labels
        np.testing.assert_allclose(got.points, rec.points, atol=1e-4)
    (tmp_path / "c.xyz").write_text("x")
    with pytest.raises(fm.InputError, match=r"c\.xyz.*suffix"):
        fm.read(tmp_path / "c.xyz")


def test_recording_and_displacements_to_pandas():
    rec = _rec(frames=6, n=3)
    df = rec.to_frame()
    assert df.shape == (6, 9)
    assert df.loc[2 / 50.0, ("M1", "z")] == rec.points[2, 1, 2]
    d = fm.displacement_matrix([rec, _rec(frames=4, n=3, seed=1)], names=["s1", "s2"])
    A = d.to_frame()
    assert A.shape == (30, 3) and list(A.columns) == ["M0", "M1", "M2"]
    # row (s2, frame 3, y) of marker M2: its position minus s2's first frame
    other = _rec(frames=4, n=3, seed=1)
    assert A.loc[("s2", 3, "y"), "M2"] == pytest.approx(other.points[3, 2, 1]
                                                         - other.points[0, 2, 1])
    named = fm.displacement_matrix(_rec(source="/x/take_07.c3d"))
    assert named.sentences == ["take_07"]


def test_ranking_to_frame_is_the_pivot_order():
    rng = np.random.default_rng(3)
    A = rng.normal(size=(60, 4)) * [1, 5, 2, 3]
    rk = fm.rank_markers(A, ["a", "b", "c", "d"])
    t = rk.to_frame()
    assert t["marker"].tolist() == ["b", "d", "c", "a"]  # by column size, nearly orthogonal
    assert t["order"].tolist() == [1, 2, 3, 4]
    np.testing.assert_allclose(t["r_rms"], t["r"] / np.sqrt(60))


def test_load_splits_training_and_heldout(tmp_path):
    paths = []
    for i in range(3):
        p = tmp_path / f"s{i}.csv"
        write_csv(p, _rec(seed=i))
        paths.append(p)
    data = fm.load(paths, heldout_sentences=[2])     # counting from 1, as the config
    assert data.train.sentences == ["s0", "s2"]
    assert data.heldout.sentences == ["s1"]
    assert data.sentences["role"].tolist() == ["train", "train", "heldout"]
    assert fm.load(paths[0]).heldout is None
    with pytest.raises(fm.InputError, match="heldout_sentences: every recording is held out"):
        fm.load(paths, heldout_sentences=[1, 2, 3])
    with pytest.raises(fm.InputError, match=r"sentence number\(s\) \[0\] out of range .* from 1"):
        fm.load(paths, heldout_sentences=[0])
    # the 0.2 form counts from 0, with a warning, for one release
    with pytest.warns(DeprecationWarning, match="counts sentences from 0"):
        old = fm.load(paths, heldout=[1])
    assert old.heldout.sentences == ["s1"]
    with pytest.warns(DeprecationWarning), pytest.raises(fm.InputError, match="out of range"):
        fm.load(paths, heldout=[5])
    with pytest.raises(fm.InputError, match="give one of them"):
        fm.load(paths, heldout=[1], heldout_sentences=[2])


def test_missing_files_are_file_not_found_and_facemotion_errors(tmp_path):
    for call in (lambda: fm.read(tmp_path / "absent.c3d"),
                 lambda: fm.load([tmp_path / "absent.csv"])):
        with pytest.raises(FileNotFoundError, match="absent") as err:
            call()
        assert isinstance(err.value, fm.InputError)


def test_lips_fit_modes_reconstruct_recover_a_planted_low_rank_motion():
    mesh = lips.parametric_lip_mesh()
    rng = np.random.default_rng(5)
    free = np.setdiff1d(np.arange(mesh.n_nodes), mesh.fixed)
    tracked = [mesh.labels[i] for i in free[:: max(1, len(free) // 12)][:12]]
    goals = np.einsum("fk,kmc->fmc", rng.normal(size=(80, 3)), rng.normal(size=(3, 12, 3)))
    U = lips.fit(mesh, goals, tracked)
    idx = mesh.indices(tracked)
    np.testing.assert_allclose(U[:, idx], goals, atol=1e-8)       # constraints met
    np.testing.assert_array_equal(U[:, mesh.fixed], 0.0)
    # the fit is linear in the goals, so three latent courses give three modes
    model = lips.modes(U)
    assert model.variances[3] < 1e-12 * model.variances[0]
    model3 = lips.modes(U, n_modes=3)
    assert model3.table()["cumulative_fraction"].iloc[-1] == pytest.approx(1.0)
    # reconstruct every DOF from the tracked nodes' DOF only
    observed = (3 * idx[:, None] + np.arange(3)).ravel()
    flat = U.reshape(len(U), -1)
    est = lips.reconstruct(model3, flat[:, observed], observed)
    np.testing.assert_allclose(est, flat, atol=1e-8 * np.abs(flat).max())
