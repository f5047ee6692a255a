"""C3D files as real systems write them (../shared/data/c3d_suite, see its README).

Every file that ezc3d reads either loads with exactly its marker points, coordinates equal to
ezc3d's in mm (at the 32-bit precision the file stores), or stops with one clear line. The
format variants of one c3d.org sample (PC integer / DEC real; PC real / DEC integer) give
identical points. Sources: c3d.org sample files Sample01 and Sample02 (public test files, via
kineticstoolkit's test suite); ktk_* files from kineticstoolkit (Apache-2.0), Félix Chénier.
"""

from __future__ import annotations

import logging
from pathlib import Path

import ezc3d
import numpy as np
import pytest
from helpers import SHARED_DATA

from facemotion.errors import InputError
from facemotion.io.c3d import read_c3d, write_c3d
from facemotion.io.recording import Recording
from facemotion.io.registry import read_recording

SUITE_FILES = {
    "c3dorg_sample01_Eb015pi.c3d": 26, "c3dorg_sample01_Eb015vr.c3d": 26,
    "c3dorg_sample02_pc_real.c3d": 36, "c3dorg_sample02_dec_int.c3d": 36,
    "ktk_racing_static.c3d": 41, "ktk_tennis_serve_2players.c3d": 78,
}


def suite() -> Path:
    root = SHARED_DATA
    d = root / "c3d_suite"
    if not all((d / f).is_file() for f in SUITE_FILES):
        pytest.fail(f"C3D suite not found at {d}; set FACEMOTION_SHARED_DATA to the shared "
                    "data folder")
    return d


def ezc3d_reference(path, columns=None):
    """ezc3d's points as (frames, points, 3) in mm at float32 precision, and its labels."""
    c = ezc3d.c3d(str(path))
    point = c["parameters"]["POINT"]
    n = c["data"]["points"].shape[1]
    labels = [str(x).strip() for x in point["LABELS"]["value"]][:n]
    scale = {"mm": 1.0, "m": 1000.0}[str(point["UNITS"]["value"][0]).strip()]
    pts = c["data"]["points"][:3].astype(np.float32).astype(float).transpose(2, 1, 0) * scale
    residual = c["data"]["meta_points"]["residuals"][0].T
    if columns is not None:
        pts, residual = pts[:, columns], residual[:, columns]
        labels = [labels[j] for j in columns]
    return labels, pts, residual


@pytest.mark.parametrize("name", [f for f in SUITE_FILES if "2players" not in f])
def test_single_subject_files_load_with_exactly_their_markers(name):
    path = suite() / name
    rec = read_c3d(path)
    labels, ref, residual = ezc3d_reference(path)
    assert rec.labels == labels and rec.n_markers == SUITE_FILES[name]
    valid = np.isfinite(rec.points).all(axis=2)
    # missing exactly where the file says so: negative residual, NaN, or (0, 0, 0) unscored
    expected_missing = (residual < 0) | ~np.isfinite(ref).all(axis=2) \
        | ((ref == 0).all(axis=2) & ~(residual > 0))
    assert np.array_equal(~valid, expected_missing)
    assert np.array_equal(rec.points[valid], ref[valid])
    assert valid.mean() > 0.5  # a real trial, mostly seen


@pytest.mark.parametrize("a, b", [
    ("c3dorg_sample01_Eb015pi.c3d", "c3dorg_sample01_Eb015vr.c3d"),
    ("c3dorg_sample02_dec_int.c3d", "c3dorg_sample02_pc_real.c3d"),
])
def test_format_variants_give_identical_points(a, b):
    ra, rb = read_c3d(suite() / a), read_c3d(suite() / b)
    assert ra.labels == rb.labels and ra.rate == rb.rate
    assert np.array_equal(ra.points, rb.points, equal_nan=True)
    # ezc3d's own numbers differ by float32 rounding (the integer variant is int16 x scale
    # in double): the reader's choice of the stored precision is what makes them identical
    raw_a = ezc3d.c3d(str(suite() / a))["data"]["points"][:3]
    raw_b = ezc3d.c3d(str(suite() / b))["data"]["points"][:3]
    assert not np.array_equal(raw_a, raw_b, equal_nan=True)


def test_metre_files_are_read_in_mm():
    rec = read_c3d(suite() / "ktk_racing_static.c3d")
    assert rec.rate == pytest.approx(69.9, abs=1e-5)
    span = np.nanmax(rec.points, axis=(0, 1)) - np.nanmin(rec.points, axis=(0, 1))
    assert 300 < span.max() < 3000  # a person in a wheelchair, in mm


def test_two_subjects_need_a_choice():
    path = suite() / "ktk_tennis_serve_2players.c3d"
    with pytest.raises(InputError, match=r"ktk_tennis_serve_2players.c3d: labels belong to "
                                         r"several subjects \(prefixes 'Derrick', 'Viktor'\); "
                                         r"choose one with the sheet's subject_prefix"):
        read_recording(path, "c3d")
    with pytest.raises(InputError, match=r"no marker label starts with subject prefix 'Bob:' "
                                         r"\(prefixes in the file: 'Derrick', 'Viktor'\)"):
        read_recording(path, "c3d", subject_prefix="Bob")


@pytest.mark.parametrize("subject", ["Derrick", "Viktor"])
def test_subject_chosen_by_prefix(subject, caplog):
    path = suite() / "ktk_tennis_serve_2players.c3d"
    with caplog.at_level(logging.INFO, logger="facemotion"):
        rec = read_recording(path, "c3d", subject_prefix=subject)
    full = ezc3d_reference(path)[0]
    columns = [j for j, lab in enumerate(full) if lab.startswith(subject + ":")]
    labels, ref, _ = ezc3d_reference(path, columns)
    assert rec.labels == [lab.split(":", 1)[1] for lab in labels] and rec.n_markers == 39
    assert "C7" in rec.labels and "LFHD" in rec.labels
    assert np.array_equal(rec.points, ref, equal_nan=True)
    assert f"subject '{subject}': 39 markers kept; left out 39 labels" in caplog.text


def test_a_file_ezc3d_cannot_read_stops_with_one_line(tmp_path):
    """Sample02 made SGI (MIPS, big-endian): the header's words in big-endian order and the
    parameter section's processor byte 83 + 3. ezc3d reads no SGI file."""
    data = bytearray((suite() / "c3dorg_sample02_pc_real.c3d").read_bytes())
    for a, b in ((2, 4), (4, 6), (6, 8), (8, 10), (10, 12), (16, 18), (18, 20)):
        data[a:b] = data[a:b][::-1]  # 16-bit words
    for a, b in ((12, 16), (20, 24)):
        data[a:b] = data[a:b][::-1]  # 32-bit floats (scale, frame rate)
    data[(data[0] - 1) * 512 + 3] = 83 + 3
    (tmp_path / "sample02_sgi.c3d").write_bytes(bytes(data))
    with pytest.raises(InputError) as err:
        read_c3d(tmp_path / "sample02_sgi.c3d")
    msg = str(err.value)
    assert msg.startswith(f"{tmp_path / 'sample02_sgi.c3d'}: cannot read as C3D")
    assert "MIPS" in msg and "\n" not in msg


# ----------------------------------------------------------------------------- Vicon model outputs

def _vicon_like(path, with_type_groups=False):
    """Markers plus Plug-in-Gait-style outputs listed in POINT:ANGLES, FORCES, ... ."""
    rng = np.random.default_rng(0)
    markers = ["Subj:LFHD", "Subj:RFHD", "Subj:ULIP", "Subj:LLIP"]
    outputs = {"ANGLES": ["Subj:LHipAngles", "Subj:RHipAngles"],
               "FORCES": ["Subj:LHipForce"], "MOMENTS": ["Subj:LHipMoment"],
               "POWERS": ["Subj:LHipPower"], "SCALARS": ["Subj:Bodymass"],
               "MODELED_MARKERS": ["Subj:HEDO"]}
    labels = markers[:2] + outputs["ANGLES"] + markers[2:] + [
        x for k, v in outputs.items() if k != "ANGLES" for x in v]
    pts = rng.normal(size=(50, len(labels), 3)) * 100
    write_c3d(path, Recording(labels, pts, 100.0))
    c = ezc3d.c3d(str(path))
    for group, names in outputs.items():
        c.add_parameter("POINT", group, names)
    if with_type_groups:
        c.add_parameter("POINT", "TYPE_GROUPS", ["Markers", "Angles", "Forces"])
    c.write(str(path))
    return labels, pts, markers


@pytest.mark.parametrize("type_groups", [False, True])
def test_non_marker_points_are_left_out_with_a_log_line(tmp_path, caplog, type_groups):
    labels, pts, markers = _vicon_like(tmp_path / "pig.c3d", type_groups)
    with caplog.at_level(logging.INFO, logger="facemotion"):
        rec = read_recording(tmp_path / "pig.c3d", "c3d")
    assert rec.labels == ["LFHD", "RFHD", "ULIP", "LLIP"]
    cols = [labels.index(m) for m in markers]
    assert np.array_equal(rec.points, pts[:, cols].astype(np.float32).astype(float))
    line = next(r.getMessage() for r in caplog.records if "not markers" in r.getMessage())
    assert "left out 7 points that are not markers" in line
    for part in ("angles: Subj:LHipAngles, Subj:RHipAngles", "forces: Subj:LHipForce",
                 "moments: Subj:LHipMoment", "powers: Subj:LHipPower",
                 "scalars: Subj:Bodymass", "modeled_markers: Subj:HEDO"):
        assert part in line


def test_a_file_of_model_outputs_only_is_an_error(tmp_path):
    path = tmp_path / "angles.c3d"
    write_c3d(path, Recording(["A1", "A2"], np.ones((5, 2, 3)), 100.0))
    c = ezc3d.c3d(str(path))
    c.add_parameter("POINT", "ANGLES", ["A1", "A2"])
    c.write(str(path))
    with pytest.raises(InputError, match=r"angles.c3d: no marker points \(all 2 points are "
                                         r"angles\)"):
        read_c3d(path)


def test_labels_known_at_parse_time_follow_the_subject_prefix():
    from facemotion.io.registry import read_labels

    path = suite() / "ktk_tennis_serve_2players.c3d"
    labels = read_labels(path, "c3d", subject_prefix="Viktor")
    assert labels == read_recording(path, "c3d", subject_prefix="Viktor").labels
    with pytest.raises(InputError, match="several subjects"):
        read_labels(path, "c3d")
