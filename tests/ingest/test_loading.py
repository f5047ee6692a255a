"""One path for every recording: read -> head alignment -> gaps -> displacements."""

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.ingest.loading import load_dataset, split_roles
from facemotion.io.recording import Recording
from facemotion.io.wide_csv import write_csv

HEAD = ["h1", "h2", "h3", "h4"]


def make_take(path, seed, n_frames=120, labels=None, drop=None):
    """A rigidly moving head (4 head markers) and 5 face markers with their own motion."""
    rng = np.random.default_rng(seed)
    labels = labels or HEAD + ["m1", "m2", "m3", "m4", "m5"]
    neutral = np.array([[0, 100, 0], [60, 90, 10], [-60, 90, 10], [0, 60, 40],
                        [0, 0, 50], [25, 0, 45], [-25, 0, 45], [0, -20, 50], [0, -60, 40]],
                       float)[: len(labels)]
    t = np.arange(n_frames) / 120.0
    face = np.zeros((n_frames, len(labels), 3))
    face[:, 4:, 1] = 3 * np.sin(2 * np.pi * 4 * t)[:, None] * rng.uniform(0.5, 1.5, len(labels) - 4)
    local = neutral + face
    rot = Rotation.from_rotvec(np.deg2rad(2) * np.sin(2 * np.pi * t)[:, None] * [1, 0.5, 0.2])
    pts = np.stack([r.apply(local[i]) for i, r in enumerate(rot)]) + [5, 0, 2] * t[:, None, None]
    if drop is not None:
        pts[drop[1]:drop[2], labels.index(drop[0])] = np.nan
    rec = Recording(labels, pts, 120.0, str(path))
    write_csv(path, rec)
    return local - local[0]


def test_head_motion_removed_and_roles_ordered(tmp_path):
    files = [tmp_path / f"s{i}.csv" for i in range(3)]
    truths = [make_take(f, i) for i, f in enumerate(files)]
    out = load_dataset([str(f) for f in files], "csv", head_markers=HEAD, exclude_markers=HEAD,
                       train=[2, 0], heldout=[1])
    d = out.displacements
    assert d.labels == ["m1", "m2", "m3", "m4", "m5"]
    assert d.sentences == ["s2", "s0", "s1"]
    assert list(out.sentences["role"]) == ["train", "train", "heldout"]
    # rows of sentence s2 are the displacements of take 2 (head motion removed, noiseless)
    rows = d.rows_for([0])
    expected = truths[2][:, 4:, :].reshape(-1, 3)
    got = d.A[rows].reshape(-1, 3, 5).transpose(0, 2, 1).reshape(-1, 3)
    assert np.max(np.abs(got - expected)) < 1e-4  # CSV text keeps ~1e-6 mm
    assert out.sentences["head_fit_max_mm"].max() < 1e-4
    train, held = split_roles(d, out.sentences)
    assert train.sentences == ["s2", "s0"] and held.sentences == ["s1"]


def test_gap_is_filled_and_flagged(tmp_path):
    f = tmp_path / "s0.csv"
    make_take(f, 0, drop=("m2", 30, 36))
    out = load_dataset([str(f)], "csv", head_markers=HEAD, exclude_markers=HEAD, train=[0],
                       heldout=[])
    j = out.displacements.labels.index("m2")
    assert out.missing[30:36, j].all() and out.missing.sum() == 6
    assert out.filled[30:36, j].all() and out.filled.sum() == 6
    row = out.gap_report.set_index("marker").loc["m2"]
    assert row["missing_frames"] == 6 and row["filled_frames"] == 6
    assert row["fill_method"] == "cubic"


def test_take_with_different_markers_names_the_file(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    make_take(a, 0)
    make_take(b, 1, labels=HEAD + ["m1", "m2", "m3", "m4", "mX"])
    with pytest.raises(InputError, match=r"b\.csv: marker labels differ .*extra markers mX"):
        load_dataset([str(a), str(b)], "csv", head_markers=HEAD, train=[0, 1], heldout=[])


@pytest.mark.parametrize("head,needle", [
    (["h1", "h2"], "at least 3 are needed"),
    (["h1", "h2", "hZ"], "hZ"),
])
def test_bad_head_markers(tmp_path, head, needle):
    f = tmp_path / "a.csv"
    make_take(f, 0)
    with pytest.raises(InputError, match=needle):
        load_dataset([str(f)], "csv", head_markers=head, train=[0], heldout=[])


def test_unknown_excluded_marker_and_missing_file(tmp_path):
    f = tmp_path / "a.csv"
    make_take(f, 0)
    with pytest.raises(InputError, match="marker 'nope'"):
        load_dataset([str(f)], "csv", exclude_markers=["nope"], train=[0], heldout=[])
    with pytest.raises(InputError, match="missing.csv"):
        load_dataset([str(tmp_path / "missing.csv")], "csv", train=[0], heldout=[])


def test_marker_missing_everywhere_is_an_error(tmp_path):
    f = tmp_path / "a.csv"
    make_take(f, 0, drop=("m3", 0, 120))
    with pytest.raises(InputError, match="m3"):
        load_dataset([str(f)], "csv", head_markers=HEAD, train=[0], heldout=[])


def test_dataset_without_heldout_sentences(tmp_path):
    """No held-out sentences: split_roles returns None for them (the workflow then asks for no
    evaluation outputs for that dataset, and the evaluation script refuses with an error)."""
    f = tmp_path / "a.csv"
    make_take(f, 0)
    out = load_dataset([str(f)], "csv", head_markers=HEAD, train=[0], heldout=[])
    train, held = split_roles(out.displacements, out.sentences)
    assert held is None and train.sentences == ["a"]
    no_train = out.sentences.assign(role="heldout")
    with pytest.raises(InputError, match="no training sentences"):
        split_roles(out.displacements, no_train)


def test_datasets_of_one_subject_share_its_takes(tmp_path, monkeypatch):
    """Two datasets of the same takes in other orders (as S2a and S2a*), loaded with one
    shared ``takes`` dict: each take is read once, and each dataset is exactly what loading it
    alone gives (the shared recordings are never modified)."""
    import facemotion.io.registry

    files = [str(tmp_path / f"s{i}.csv") for i in range(4)]
    for i, f in enumerate(files):
        make_take(f, i, drop=("m3", 20 + i, 26 + i))
    reads = []
    real_read = facemotion.io.registry.read_recording

    def counting_read(path, *args, **kwargs):
        reads.append(path)
        return real_read(path, *args, **kwargs)

    monkeypatch.setattr(facemotion.io.registry, "read_recording", counting_read)
    kw = {"head_markers": HEAD, "exclude_markers": HEAD}
    designs = [{"train": [0, 1, 2], "heldout": [3]}, {"train": [3, 2, 1], "heldout": [0]}]
    shared: dict = {}
    together = [load_dataset(files, "csv", **kw, **d, takes=shared) for d in designs]
    assert sorted(reads) == sorted(files)  # every take read once for both datasets
    reads.clear()
    alone = [load_dataset(files, "csv", **kw, **d) for d in designs]
    assert len(reads) == 2 * len(files)
    for a, b in zip(together, alone, strict=True):
        assert np.array_equal(a.displacements.A, b.displacements.A)
        assert np.array_equal(a.displacements.neutral, b.displacements.neutral)
        assert a.sentences.equals(b.sentences) and a.gap_report.equals(b.gap_report)
    # the second design really is another order (another neutral pose and A)
    assert not np.array_equal(together[0].displacements.A, together[1].displacements.A)


def test_datasets_of_one_subject_check_each_sentence_once(tmp_path, monkeypatch, caplog):
    """With a shared ``takes`` dict, a sentence checked clean for one dataset is not checked
    again for the next (the same results as checking it); a sentence whose check warned (an
    outlier) is checked, and warned about, again for every dataset."""
    import facemotion.ingest.validation

    files = [str(tmp_path / f"s{i}.csv") for i in range(4)]
    for i, f in enumerate(files):
        make_take(f, i)
    from facemotion.io.registry import read_recording

    rec = read_recording(files[2], "csv")
    rec.points[60, 5] += 400.0  # one sample far from the face: an outlier
    write_csv(files[2], rec)
    checked = []
    real_check = facemotion.ingest.validation.check_take

    def counting_check(rec, *args, **kwargs):
        checked.append(rec.source)
        return real_check(rec, *args, **kwargs)

    monkeypatch.setattr(facemotion.ingest.validation, "check_take", counting_check)
    kw = {"head_markers": HEAD, "exclude_markers": HEAD}
    designs = [{"train": [0, 1, 2], "heldout": [3]}, {"train": [3, 2, 1], "heldout": [0]}]
    shared: dict = {}
    with caplog.at_level("WARNING", logger="facemotion"):
        together = [load_dataset(files, "csv", **kw, **d, takes=shared) for d in designs]
    assert sorted(checked) == sorted(files + [files[2]])
    assert sum("outlier" in r.getMessage() for r in caplog.records) == 2
    checked.clear()
    alone = [load_dataset(files, "csv", **kw, **d) for d in designs]
    assert len(checked) == 2 * len(files)
    for a, b in zip(together, alone, strict=True):
        assert np.array_equal(a.displacements.A, b.displacements.A)
        assert a.sentences.equals(b.sentences) and a.gap_report.equals(b.gap_report)


def test_marker_lists_keep_include_order_and_add_head_markers_last():
    """The analysed markers follow include_markers (or the data's order) less the excluded
    ones; the checked markers are those plus the head markers not already analysed."""
    from facemotion.ingest.loading import check_marker_lists

    labels = HEAD + ["m1", "m2", "m3"]
    keep, used = check_marker_lists(labels, "take.csv", head_markers=["h2", "h1", "h3"],
                                    exclude_markers=["m2"], include_markers=["m3", "m2", "h1"])
    assert keep == ["m3", "h1"] and used == ["m3", "h1", "h2", "h3"]
    keep, used = check_marker_lists(labels, "take.csv", exclude_markers=HEAD)
    assert keep == used == ["m1", "m2", "m3"]
    with pytest.raises(InputError, match=r"^include_markers \(the arguments\): marker\(s\) m1 "
                                         "listed twice$"):
        check_marker_lists(labels, "take.csv", include_markers=["m1", "m1", "m2"],
                           markers_named_in="the arguments")
    with pytest.raises(InputError, match="^take.csv: fewer than 2 markers left"):
        check_marker_lists(labels, "take.csv", include_markers=["m1", "h1"],
                           exclude_markers=["h1"])


def test_head_motion_removal_stage_leaves_only_the_planted_face_motion():
    """Two takes of a rigidly moving head (remove_head_motion on in-memory recordings): after
    the stage every head marker stands still at one place for both takes, the fit residual is
    ~0, and each face marker's distance moved from the first frame is the planted one (the
    head frame differs from the world frame only by one fixed rigid transform)."""
    from facemotion.ingest.loading import remove_head_motion

    rng = np.random.default_rng(3)
    labels = HEAD + ["m1", "m2"]
    neutral = np.array([[0, 100, 0], [60, 90, 10], [-60, 90, 10], [0, 60, 40], [0, 0, 50],
                        [0, -60, 40]], float)
    recs, planted = [], []
    for take in range(2):
        local = np.repeat(neutral[None], 50, axis=0)
        local[:, 4:] += rng.normal(0, 2, (50, 2, 3))
        rot = Rotation.from_rotvec(rng.normal(0, 0.05, (50, 3)))
        pts = np.stack([r.apply(local[i]) for i, r in enumerate(rot)]) + rng.normal(0, 5, 3)
        recs.append(Recording(labels, pts, 100.0, f"take{take}"))
        planted.append(np.linalg.norm(local[:, 4:] - local[0, 4:], axis=2))
    aligned, residuals = remove_head_motion(recs, HEAD, "take0")
    head = np.concatenate([a.points[:, :4] for a in aligned])
    assert np.max(np.abs(head - head[0])) < 1e-9
    assert max(float(np.max(r)) for r in residuals) < 1e-9
    for a, want in zip(aligned, planted, strict=True):
        moved = np.linalg.norm(a.points[:, 4:] - a.points[0, 4:], axis=2)
        assert np.allclose(moved, want, atol=1e-9)
