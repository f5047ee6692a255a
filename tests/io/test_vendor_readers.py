"""Readers of vendor exports, on files the tests write to each documented layout:
Qualisys Track Manager TSV, OptiTrack Motive CSV, OpenFace 2.x landmark CSV."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from facemotion.errors import InputError
from facemotion.ingest.loading import load_dataset
from facemotion.io.openface import read_openface_csv
from facemotion.io.optitrack import read_optitrack_csv
from facemotion.io.qualisys import read_qualisys_tsv
from facemotion.io.registry import read_recording
from facemotion.io.wide_csv import write_csv

RATE = 100.0


def planted(frames=40, markers=("Chin", "Lip Upper", "Lip Lower", "Nose"), seed=0):
    rng = np.random.default_rng(seed)
    pts = rng.normal(size=(frames, len(markers), 3)) * 50 + 200
    pts[3, 1] = np.nan           # one occluded sample
    pts[10:13, 2] = np.nan       # a short gap
    return list(markers), pts


def num(x: float) -> str:
    return "" if not np.isfinite(x) else repr(float(x))


# ----------------------------------------------------------------------------- Qualisys TSV

def write_qtm(path, labels, pts, *, column_header=True, frame_time=True, missing="",
              header_overrides=None, rate=RATE):
    F, n, _ = pts.shape
    header = {"NO_OF_FRAMES": str(F), "NO_OF_CAMERAS": "8", "NO_OF_MARKERS": str(n),
              "FREQUENCY": f"{rate:g}", "NO_OF_ANALOG": "0", "ANALOG_FREQUENCY": "0",
              "DESCRIPTION": "--", "TIME_STAMP": "2024-03-01, 10:19:43.755\t2063631.96",
              "DATA_INCLUDED": "3D"}
    header.update(header_overrides or {})
    lines = ["FILE_VERSION\t2.0.0"] + [f"{k}\t{v}" for k, v in header.items() if v is not None]
    lines.append("EVENT\tSentence start\t12\t0.110")
    lines.append("MARKER_NAMES\t" + "\t".join(labels) + "\t")
    lines.append("TRAJECTORY_TYPES\t" + "\t".join(["Measured"] * n))
    if column_header:
        lines.append("Frame\tTime\t" + "\t".join(f"{m} {a}" for m in labels for a in "XYZ")
                     + "\t")
    for f in range(F):
        vals = [num(x) if np.isfinite(x) else missing for x in pts[f].ravel()]
        lead = [str(f + 1), f"{f / rate:.5f}"] if frame_time else []
        lines.append("\t".join(lead + vals))
    path.write_text("\r\n".join(lines) + "\r\n")


@pytest.mark.parametrize("column_header, frame_time", [(True, True), (False, True),
                                                       (False, False)])
def test_qtm_layouts_read_back_exactly(tmp_path, column_header, frame_time):
    labels, pts = planted()
    write_qtm(tmp_path / "take.tsv", labels, pts, column_header=column_header,
              frame_time=frame_time)
    rec = read_qualisys_tsv(tmp_path / "take.tsv")
    assert rec.labels == labels and rec.rate == RATE
    assert np.array_equal(rec.points, pts, equal_nan=True)


def test_qtm_zero_samples_are_missing_and_units_are_mm(tmp_path):
    labels, pts = planted()
    write_qtm(tmp_path / "take.tsv", labels, pts, missing="0.000")
    rec = read_qualisys_tsv(tmp_path / "take.tsv")
    assert np.array_equal(np.isnan(rec.points), np.isnan(pts))
    # QTM writes mm: the format's units win over the sheet's
    rec_cm = read_qualisys_tsv(tmp_path / "take.tsv", units="cm")
    assert np.array_equal(rec_cm.points, rec.points, equal_nan=True)
    assert (rec_cm.units, rec_cm.units_source) == ("mm", "file")


@pytest.mark.parametrize("overrides, match", [
    ({"NO_OF_MARKERS": "5"}, "NO_OF_MARKERS is 5 but MARKER_NAMES lists 4 names"),
    ({"NO_OF_FRAMES": "41"}, "NO_OF_FRAMES is 41 but there are 40 data lines"),
    ({"FREQUENCY": "EXT"}, "FREQUENCY 'EXT' is not a number"),
    ({"DATA_INCLUDED": "2D"}, "holds '2D' data, no 3D markers; export 3D trajectories"),
    ({"DATA_INCLUDED": "6D"}, "a QTM 6D export .rigid bodies., no markers"),
    ({"FREQUENCY": None}, "QTM TSV header has no FREQUENCY value"),
])
def test_qtm_header_errors(tmp_path, overrides, match):
    labels, pts = planted()
    write_qtm(tmp_path / "t.tsv", labels, pts, header_overrides=overrides)
    with pytest.raises(InputError, match=match):
        read_qualisys_tsv(tmp_path / "t.tsv")


def test_qtm_data_errors(tmp_path):
    labels, pts = planted()
    write_qtm(tmp_path / "t.tsv", labels, pts)
    text = (tmp_path / "t.tsv").read_text().replace("Nose Z", "Nose Q")
    (tmp_path / "t.tsv").write_text(text)
    with pytest.raises(InputError, match="column header has no 'Nose Z' column"):
        read_qualisys_tsv(tmp_path / "t.tsv")
    write_qtm(tmp_path / "t.tsv", labels, pts)
    lines = (tmp_path / "t.tsv").read_text().splitlines()
    fields = lines[20].split("\t")
    fields[5] = "12.3x"
    lines[20] = "\t".join(fields)
    (tmp_path / "t.tsv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"t.tsv, line 21: non-numeric value '12.3x' in field 6"):
        read_qualisys_tsv(tmp_path / "t.tsv")
    (tmp_path / "x.tsv").write_text("Frame\tTime\n1\t0\n")
    with pytest.raises(InputError, match="not a QTM TSV export"):
        read_qualisys_tsv(tmp_path / "x.tsv")
    write_qtm(tmp_path / "w.tsv", labels, pts, column_header=False)
    lines = (tmp_path / "w.tsv").read_text().splitlines()
    lines[-40] = "\t".join(lines[-40].split("\t")[:-1])
    (tmp_path / "w.tsv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"13 fields, expected 12 .* or 14 \(with frame"):
        read_qualisys_tsv(tmp_path / "w.tsv")


# ----------------------------------------------------------------------------- Motive CSV

def write_motive(path, labels, pts, *, units="Millimeters", asset="Face", timecode=False,
                 frames_total=None, rate=RATE, per_mm=1.0):
    """Motive 1.23 layout: rigid body 'Head' (rotation, position, mean error), its rigid
    body markers, the labelled markers ('Face:Chin', ...) and one unlabeled marker."""
    F, n, _ = pts.shape
    meta = ["Format Version", "1.23", "Take Name", "block1", "Take Notes", "",
            "Capture Frame Rate", f"{rate:.6f}", "Export Frame Rate", f"{rate:.6f}",
            "Capture Start Time", "2024-03-01 10.19.43.755 AM", "Total Frames in Take", str(F),
            "Total Exported Frames", str(frames_total or F), "Rotation Type", "Quaternion",
            "Length Units", units, "Coordinate Space", "Global"]
    if units is None:
        meta = meta[:-4] + meta[-2:]
    lead = 3 if timecode else 2
    cols = []  # (type, name, id, quantity, axis)
    cols += [("Rigid Body", "Head", "1", "Rotation", a) for a in "XYZW"]
    cols += [("Rigid Body", "Head", "1", "Position", a) for a in "XYZ"]
    cols += [("Rigid Body", "Head", "1", "Mean Marker Error", "")]
    for k in (1, 2, 3):
        cols += [("Rigid Body Marker", f"Head:Marker{k}", f"1:{k}", "Position", a)
                 for a in "XYZ"]
        cols += [("Rigid Body Marker", f"Head:Marker{k}", f"1:{k}", "Marker Quality", "")]
    for j, m in enumerate(labels):
        name = f"{asset}:{m}" if asset else m
        cols += [("Marker", name, f"2:{j}", "Position", a) for a in "XYZ"]
    cols += [("Marker", "Unlabeled 1042", "3:1042", "Position", a) for a in "XYZ"]
    pad = [""] * (lead - 2)  # under a TimeCode column
    rows = [meta, [],
            ["", "Type"] + pad + [c[0] for c in cols],
            ["", "Name"] + pad + [f'"{c[1]}"' if "," in c[1] else c[1] for c in cols],
            ["", "ID"] + pad + [c[2] for c in cols],
            [""] * lead + [c[3] for c in cols],
            ["Frame", "Time (Seconds)"] + (["TimeCode"] if timecode else [])
            + [c[4] for c in cols]]
    rng = np.random.default_rng(5)
    for f in range(F):
        row = [str(f), f"{f / rate:.6f}"] + ([f"10:19:43:{f:02d}.00"] if timecode else [])
        row += [repr(x) for x in rng.normal(size=8)] + [repr(x) for x in rng.normal(size=12)]
        row += [num(x / per_mm) for x in pts[f].ravel()]
        row += [repr(x) for x in rng.normal(size=3)]
        rows.append(row)
    path.write_text("\n".join(",".join(r) for r in rows) + "\n")


@pytest.mark.parametrize("timecode", [False, True])
def test_motive_reads_only_labelled_marker_positions(tmp_path, caplog, timecode):
    labels, pts = planted()
    write_motive(tmp_path / "take.csv", labels, pts, timecode=timecode)
    with caplog.at_level(logging.INFO, logger="facemotion"):
        rec = read_recording(tmp_path / "take.csv", "optitrack_csv")
    assert rec.labels == labels and rec.rate == RATE
    assert np.array_equal(rec.points, pts, equal_nan=True)
    text = caplog.text
    assert "1 rigid body (Head)" in text
    assert "3 rigid body markers (Head:Marker1, Head:Marker2, Head:Marker3)" in text
    assert "1 unlabeled marker (Unlabeled 1042)" in text
    assert "all 4 labels carry the subject prefix 'Face:'" in text


def test_motive_units_from_the_header(tmp_path):
    labels, pts = planted()
    write_motive(tmp_path / "m.csv", labels, pts, units="Meters", per_mm=1000.0)
    rec = read_optitrack_csv(tmp_path / "m.csv")
    assert np.allclose(rec.points, pts, rtol=1e-12, equal_nan=True)
    assert (rec.units, rec.units_source) == ("m", "file")
    # the file's Length Units win over the sheet's
    assert np.array_equal(read_optitrack_csv(tmp_path / "m.csv", units="mm").points,
                          rec.points, equal_nan=True)
    write_motive(tmp_path / "none.csv", labels, pts, units=None)
    with pytest.raises(InputError, match="line 1 has no Length Units; give the units"):
        read_optitrack_csv(tmp_path / "none.csv")
    assert np.array_equal(read_optitrack_csv(tmp_path / "none.csv", units="mm").points, pts,
                          equal_nan=True)
    write_motive(tmp_path / "ft.csv", labels, pts, units="Feet")
    with pytest.raises(InputError, match="unknown Length Units 'Feet'"):
        read_optitrack_csv(tmp_path / "ft.csv")


def test_motive_errors(tmp_path):
    labels, pts = planted()
    write_motive(tmp_path / "n.csv", labels, pts, frames_total=41)
    with pytest.raises(InputError, match="Total Exported Frames is 41 but there are 40 data"):
        read_optitrack_csv(tmp_path / "n.csv")
    (tmp_path / "plain.csv").write_text("time,a_x,a_y,a_z\n0,1,2,3\n")
    with pytest.raises(InputError, match="not a Motive CSV export .line 1 starts with 'time'"):
        read_optitrack_csv(tmp_path / "plain.csv")
    write_motive(tmp_path / "z.csv", labels, pts)
    lines = (tmp_path / "z.csv").read_text().splitlines()
    axes = lines[6].split(",")
    axes[-4] = "W"  # the last labelled marker (Nose) loses its Z position column
    lines[6] = ",".join(axes)
    (tmp_path / "z.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match="marker 'Face:Nose' has no Z position column"):
        read_optitrack_csv(tmp_path / "z.csv")
    write_motive(tmp_path / "v.csv", labels, pts)
    lines = (tmp_path / "v.csv").read_text().splitlines()
    cells = lines[9].split(",")
    cells[22] = "abc"
    lines[9] = ",".join(cells)
    (tmp_path / "v.csv").write_text("\n".join(lines) + "\n")
    with pytest.raises(InputError, match=r"v.csv, line 10: non-numeric value 'abc' in column 23"):
        read_optitrack_csv(tmp_path / "v.csv")


def test_motive_several_assets_need_a_choice(tmp_path):
    labels, pts = planted()
    write_motive(tmp_path / "a.csv", labels, pts)
    text = (tmp_path / "a.csv").read_text().replace("Face:Nose", "Other:Nose")
    (tmp_path / "a.csv").write_text(text)
    with pytest.raises(InputError, match=r"several subjects \(prefixes 'Face', 'Other'\)"):
        read_recording(tmp_path / "a.csv", "optitrack_csv")
    rec = read_recording(tmp_path / "a.csv", "optitrack_csv", subject_prefix="Face")
    assert rec.labels == labels[:3]


# ----------------------------------------------------------------------------- OpenFace CSV

def write_openface(path, pts, *, fps=30.0, success=None, face_ids=None, frames=None,
                   times=None, confidence=None):
    """OpenFace 2.2 FeatureExtraction layout (', ' separated header, 68 landmarks)."""
    F, n, _ = pts.shape
    success = np.ones(F, int) if success is None else success
    cols = ["frame", "face_id", "timestamp", "confidence", "success"]
    cols += [f"gaze_0_{a}" for a in "xyz"] + ["pose_Tx", "pose_Ty", "pose_Tz"]
    cols += [f"x_{k}" for k in range(n)] + [f"y_{k}" for k in range(n)]
    cols += [f"{a}_{k}" for a in "XYZ" for k in range(n)] + ["AU01_r", "AU45_c"]
    lines = [", ".join(cols)]
    for f in range(F):
        t = f / fps if times is None else times[f]
        frame = f + 1 if frames is None else frames[f]
        row = [str(frame), str(0 if face_ids is None else face_ids[f]), f"{t:.3f}",
               (f"{confidence[f]:g}" if confidence is not None
                else "0.98" if success[f] else "0"), str(int(success[f]))]
        row += ["0.1", "0.2", "-0.9", "12.5", "-3.1", "410.0"]
        row += ["320.5"] * n + ["240.5"] * n
        row += [repr(float(pts[f, k, a])) for a in range(3) for k in range(n)]
        row += ["0.3", "0.0"]
        lines.append(", ".join(row))
    path.write_text("\n".join(lines) + "\n")


def test_openface_landmarks_with_failed_frames_missing(tmp_path):
    rng = np.random.default_rng(2)
    # a face: landmarks spread over ~100 mm, moving a fraction of a mm per frame
    pts = rng.normal(size=(1, 68, 3)) * 30 + [0, 0, 450] + rng.normal(size=(90, 68, 3)) * 0.2
    success = np.ones(90, int)
    success[[5, 6, 40]] = 0
    write_openface(tmp_path / "clip.csv", pts, success=success)
    rec = read_recording(tmp_path / "clip.csv", "openface_csv")
    assert rec.labels == [f"L{k}" for k in range(68)] and rec.rate == 30.0
    ok = success == 1
    assert np.array_equal(rec.points[ok], pts[ok])
    assert np.isnan(rec.points[~ok]).all()


@pytest.mark.parametrize("kwargs, match", [
    ({"frames": [1, 2, 3, 5, 6, 7]}, "line 5: frame 5 does not follow 3"),
    ({"frames": [1, 2, 3, 3, 4, 5]}, "line 5: frame 3 does not follow 3"),
    ({"frames": [1, 2, 4, 3, 5, 6]}, "line 4: frame 4 does not follow 2"),
    ({"times": [0, 0.033, 0.067, 0.2, 0.233, 0.267]}, "timestamps are not uniformly sampled"),
    ({"face_ids": [0, 1, 0, 1, 0, 1]}, r"several faces \(face_id 0, 1\)"),
    ({"success": np.array([1, 1, 2, 1, 1, 1])}, "success must be 0 or 1, got 2 at line 4"),
])
def test_openface_errors(tmp_path, kwargs, match):
    pts = np.ones((6, 68, 3))
    write_openface(tmp_path / "c.csv", pts, **kwargs)
    with pytest.raises(InputError, match=match):
        read_openface_csv(tmp_path / "c.csv")


def test_openface_without_3d_landmarks(tmp_path):
    (tmp_path / "c.csv").write_text("frame, face_id, timestamp, confidence, success, x_0, y_0\n"
                                    "1, 0, 0.000, 0.9, 1, 320.1, 240.2\n")
    with pytest.raises(InputError, match="no 3-D landmark columns X_0, Y_0, Z_0"):
        read_openface_csv(tmp_path / "c.csv")


# ----------------------------------------------------------------------------- one take, three ways

def test_the_same_take_from_three_exports_gives_the_same_A(tmp_path):
    """A take exported as QTM TSV, Motive CSV and the wide CSV, cut by one interval table."""
    labels, pts = planted(frames=120, markers=("H1", "H2", "H3", "Chin", "LipU", "LipL"))
    t = np.arange(120)[:, None, None] / RATE
    pts = pts[0] + 4.0 * np.sin(2 * np.pi * 1.5 * t + np.arange(18).reshape(1, 6, 3))
    pts[:, :3] = pts[0, :3]  # a still head; the face moves a few mm at speech rates
    pts[70, 4] = np.nan
    pts = np.round(pts, 6)  # what the wide CSV writer keeps, so all three hold the same numbers
    write_qtm(tmp_path / "block.tsv", labels, pts)
    write_motive(tmp_path / "block.csv", labels, pts)
    write_csv(tmp_path / "wide" / "block.csv", read_qualisys_tsv(tmp_path / "block.tsv"))
    (tmp_path / "iv.tsv").write_text("take\tstart_s\tend_s\tname\nblock\t0.05\t0.5\tone\n"
                                     "block\t0.55\t1.1\ttwo\n")
    from facemotion.ingest.segments import segment_subject

    results = []
    for fmt, path in (("qualisys_tsv", tmp_path / "block.tsv"),
                      ("optitrack_csv", tmp_path / "block.csv"),
                      ("csv", tmp_path / "wide" / "block.csv")):
        segs, _ = segment_subject("tsv:iv.tsv", [str(path)], fmt, tmp_path, "row 2")
        loaded = load_dataset([str(path)], fmt, head_markers=["H1", "H2", "H3"],
                              exclude_markers=["H1", "H2", "H3"], train=[0], heldout=[1],
                              sentences=segs)
        results.append(loaded)
    for other in results[1:]:
        assert np.array_equal(results[0].displacements.A, other.displacements.A)
    assert list(results[0].sentences["frames"]) == [45, 55]
