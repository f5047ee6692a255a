"""The displacements file read in blocks, and the Gram pass over blocks and threads."""

import hashlib
import zipfile

import numpy as np
import pytest
import scipy.linalg

from facemotion.errors import InputError
from facemotion.ingest.displacement_file import (
    DisplacementsWriter,
    load_displacements,
    open_displacements,
    save_displacements,
)
from facemotion.ingest.displacements import Displacements
from facemotion.ranking.gram import gram
from facemotion.ranking.routes import rank_markers


def make(F=(400, 301, 350), n=23, seed=0):
    rng = np.random.default_rng(seed)
    rows = 3 * sum(F)
    A = rng.standard_normal((rows, 5)) @ rng.standard_normal((5, n))
    A += 0.2 * rng.standard_normal((rows, n))
    rs = np.concatenate([np.full(3 * f, s) for s, f in enumerate(F)])
    rf = np.concatenate([np.repeat(np.arange(f), 3) for f in F])
    sn = rng.standard_normal((len(F), n, 3))
    return Displacements(A, [f"M{j}" for j in range(n)], [f"s{i}" for i in range(len(F))],
                         rs, rf, 120.0, rng.random((sum(F), n)) < 0.05,
                         rng.random(sum(F)), sn.mean(axis=0), sn)


def test_round_trip_is_exact_uncompressed_and_byte_identical(tmp_path):
    d = make()
    p1, p2 = tmp_path / "a.npz", tmp_path / "b.npz"
    save_displacements(p1, d)
    save_displacements(p2, d)
    assert hashlib.sha256(p1.read_bytes()).digest() == hashlib.sha256(p2.read_bytes()).digest()
    with zipfile.ZipFile(p1) as zf:
        assert {i.compress_type for i in zf.infolist()} == {zipfile.ZIP_STORED}
    back = load_displacements(p1)
    for name in ("A", "row_sentence", "row_frame", "fill_mask", "head_residual", "neutral",
                 "sentence_neutral"):
        np.testing.assert_array_equal(getattr(back, name), getattr(d, name))
    assert back.labels == d.labels and back.sentences == d.sentences and back.rate == d.rate
    with np.load(p1) as z:  # still an ordinary npz
        np.testing.assert_array_equal(z["A"], d.A)


def test_blocks_of_some_sentences_match_the_in_memory_subset(tmp_path):
    d = make()
    save_displacements(tmp_path / "d.npz", d)
    f = open_displacements(tmp_path / "d.npz")
    for sel in ([0, 1, 2], [2, 0], [1]):
        ref = d.subset(sel).A
        rb = f.rows(sel)
        assert rb.shape == ref.shape
        got = np.vstack([b.copy() for b in rb.blocks(block_rows=3 * 37)])
        np.testing.assert_array_equal(got, ref)
        np.testing.assert_array_equal(rb.read(), ref)
        np.testing.assert_array_equal(rb.columns([4, 0, 7], block_rows=60), ref[:, [4, 0, 7]])


def test_older_deflated_files_are_still_read(tmp_path):
    d = make()
    p = tmp_path / "old.npz"
    np.savez_compressed(p, A=d.A, labels=np.array(d.labels), sentences=np.array(d.sentences),
                        row_sentence=d.row_sentence, row_frame=d.row_frame,
                        rate=np.array(d.rate), fill_mask=d.fill_mask,
                        head_residual=d.head_residual, neutral=d.neutral)
    f = open_displacements(p)
    np.testing.assert_array_equal(f.rows([1]).read(), d.subset([1]).A)
    np.testing.assert_array_equal(load_displacements(p).A, d.A)


def test_bad_files_name_the_problem_and_a_failed_write_leaves_nothing(tmp_path):
    d = make()
    p = tmp_path / "d.npz"
    save_displacements(p, d)
    data = p.read_bytes()
    (tmp_path / "cut.npz").write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="cut.npz"):
        open_displacements(tmp_path / "cut.npz").rows().read()
    with pytest.raises(InputError, match="not found"):
        open_displacements(tmp_path / "none.npz")
    w = DisplacementsWriter(tmp_path / "w.npz", d.labels, rows=30)
    with pytest.raises(InputError, match="shape"):
        w.write_rows(np.zeros((3, 2)))
    assert list(tmp_path.glob("*w.npz*")) == []
    w = DisplacementsWriter(tmp_path / "w.npz", d.labels, rows=30)
    w.write_rows(np.zeros((27, len(d.labels))))
    with pytest.raises(InputError, match="27 rows of A written, 30 declared"):
        w.close(sentences=np.array(["s"]))
    assert list(tmp_path.glob("*w.npz*")) == []


@pytest.mark.parametrize("route", ["rows", "blas"])
@pytest.mark.parametrize("threads", [1, 2, 3])
def test_gram_over_blocks_and_threads_equals_a_t_a(tmp_path, route, threads):
    d = make(n=41)
    save_displacements(tmp_path / "d.npz", d)
    f = open_displacements(tmp_path / "d.npz")
    ref = d.A.T @ d.A
    tol = 1e-12 * np.abs(ref).max()
    np.testing.assert_allclose(gram(d.A, threads=threads, route=route, block_rows=3 * 29), ref,
                               atol=tol)
    sub = d.subset([2, 0]).A
    np.testing.assert_allclose(gram(f.rows([2, 0]), threads=threads, route=route,
                                    block_rows=3 * 29), sub.T @ sub, atol=tol)


@pytest.mark.parametrize("method", ["gram", "tsqr", "scipy", "auto"])
def test_ranking_from_disk_equals_scipy_on_the_array(tmp_path, method):
    d = make(n=30, seed=3)
    save_displacements(tmp_path / "d.npz", d)
    rb = open_displacements(tmp_path / "d.npz").rows([0, 2])
    A = d.subset([0, 2]).A
    _, P = scipy.linalg.qr(A, mode="r", pivoting=True)
    rk = rank_markers(rb, method=method)
    np.testing.assert_array_equal(rk.order, P)
    np.testing.assert_allclose(rk.r, rank_markers(A, d.labels, method="scipy").r, rtol=1e-7)


def test_nonfinite_and_static_markers_are_named_from_disk(tmp_path):
    d = make(n=12)
    d.A[7, 3] = np.nan
    save_displacements(tmp_path / "nan.npz", d)
    with pytest.raises(InputError, match="M3"):
        rank_markers(open_displacements(tmp_path / "nan.npz").rows())
    d = make(n=12)
    d.A[:, 5] = 0.0
    save_displacements(tmp_path / "static.npz", d)
    with pytest.raises(InputError, match="M5 never move"):
        rank_markers(open_displacements(tmp_path / "static.npz").rows())


def test_streaming_writer_gives_the_same_file(tmp_path):
    d = make()
    save_displacements(tmp_path / "a.npz", d)
    w = DisplacementsWriter(tmp_path / "b.npz", d.labels, rows=d.A.shape[0])
    for a in range(0, d.A.shape[0], 999):
        w.write_rows(d.A[a:a + 999])
    w.close(sentences=np.array(d.sentences), row_sentence=d.row_sentence,
            row_frame=d.row_frame, rate=np.array(d.rate), fill_mask=d.fill_mask,
            head_residual=d.head_residual, neutral=d.neutral,
            sentence_neutral=d.sentence_neutral)
    assert (tmp_path / "a.npz").read_bytes() == (tmp_path / "b.npz").read_bytes()


def test_ranking_from_disk_holds_a_block_not_the_matrix(tmp_path):
    """A of 300 MB ranks in a child process whose peak RSS stays below A's size."""
    import subprocess
    import sys

    n, rows = 200, 3 * 62_500  # 300 MB of float64
    w = DisplacementsWriter(tmp_path / "big.npz", [f"V{j}" for j in range(n)], rows)
    rng = np.random.default_rng(0)
    W = rng.standard_normal((8, n))
    for a in range(0, rows, 30_000):
        m = min(30_000, rows - a)
        w.write_rows(rng.standard_normal((m, 8)) @ W + 0.1 * rng.standard_normal((m, n)))
    F = rows // 3
    w.close(sentences=np.array(["s0"]), row_sentence=np.zeros(rows, dtype=np.int64),
            row_frame=np.repeat(np.arange(F), 3), rate=np.array(30.0),
            fill_mask=np.zeros((F, n), dtype=bool), head_residual=np.zeros(F),
            neutral=np.zeros((n, 3)))
    code = (
        "import sys\n"
        "from facemotion.ingest.displacement_file import open_displacements\n"
        "from facemotion.ranking.routes import rank_markers\n"
        "rk = rank_markers(open_displacements(sys.argv[1]).rows(), method='gram', threads=1)\n"
        "assert rk.n_ranked == 200\n"
        "hwm = [int(x.split()[1]) for x in open('/proc/self/status') if x.startswith('VmHWM')]\n"
        "print(hwm[0] / 1024)\n")
    out = subprocess.run([sys.executable, "-c", code, str(tmp_path / "big.npz")],
                         capture_output=True, text=True, check=True)
    peak_mib = float(out.stdout.strip())
    assert peak_mib < 0.8 * (8 * rows * n) / 2**20  # well below the 286 MiB of A
