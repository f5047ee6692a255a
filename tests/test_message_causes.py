"""Messages show no file content beyond a short token, say the real cause, and are one line:
a password file through every reader; a missing config file of `facemotion study`; bit flips in
a real C3D header; a garbage label set."""

import subprocess
import sys
from pathlib import Path

import pytest

from facemotion.errors import InputError, token
from facemotion.io.prefixes import subject_columns
from facemotion.io.registry import FORMAT_NAMES

SECRET = ("root:$6$Zq8v1c2x3b4n5m6Q$abcdefghijklmnopqrstuvwxyz0123456789ABCDEFGHIJ:20228:0:"
          "99999:7:::\ndaemon:*:20228:0:99999:7:::\n")


def run(*args, cwd=None):
    exe = Path(sys.executable).with_name("facemotion")
    return subprocess.run([str(exe), *map(str, args)], capture_output=True, text=True,
                          cwd=cwd)


def leaked(text: str, secret: str, n: int = 8) -> list[str]:
    """Runs of ``n`` characters of ``secret`` found in ``text``."""
    return sorted({secret[i:i + n] for i in range(len(secret) - n + 1)
                   if secret[i:i + n].strip() and secret[i:i + n] in text})


@pytest.mark.parametrize("fmt", FORMAT_NAMES)
def test_a_password_file_through_every_reader_shows_nothing_of_it(tmp_path, fmt):
    (tmp_path / "shadow").write_text(SECRET)
    res = run("info", tmp_path / "shadow", "--format", fmt)
    assert res.returncode == 1
    assert res.stderr.count("\n") == 1 and res.stdout == ""
    assert leaked(res.stderr.replace(str(tmp_path), ""), SECRET) == []


def test_a_token_is_a_short_value_or_only_its_length():
    assert token("mm") == "'mm'" and "\t" not in token("a\tb")
    assert token("root:*:20228:0:99999:7:::") == "a text of 25 characters"


def test_study_with_a_missing_config_file_is_one_line(tmp_path):
    res = run("study", "--configfile", "missing.yaml", "-n", cwd=tmp_path)
    assert res.returncode == 1
    assert res.stderr.strip().splitlines() == [
        f"facemotion: error: --configfile missing.yaml: no such file (looked for "
        f"{tmp_path / 'missing.yaml'})"]
    assert not (tmp_path / ".snakemake").exists()


@pytest.mark.parametrize("offset, bit, cause", [
    (2, 1, "number of points"), (4, 0, "analog samples per frame"), (8, 3, "number of frames"),
    (16, 0, "data start block"), (15, 7, "storage"),
])
def test_bit_flips_in_a_c3d_header_are_a_damaged_header_not_a_cut_file(
        shared_data, tmp_path, offset, bit, cause):
    from facemotion.io.c3d import read_c3d

    data = bytearray((shared_data / "animface" / "animface_jaw.c3d").read_bytes())
    data[offset] ^= 1 << bit
    (tmp_path / "f.c3d").write_bytes(bytes(data))
    with pytest.raises(InputError) as e:
        read_c3d(tmp_path / "f.c3d")
    msg = str(e.value)
    assert f"header's {cause}" in msg and "the header is damaged" in msg, msg
    assert "cut short" not in msg


def test_a_cut_c3d_is_still_cut_short(shared_data, tmp_path):
    from facemotion.io.c3d import read_c3d

    data = (shared_data / "animface" / "animface_jaw.c3d").read_bytes()
    (tmp_path / "f.c3d").write_bytes(data[:-20_000])
    with pytest.raises(InputError, match="C3D file is cut short"):
        read_c3d(tmp_path / "f.c3d")


def test_garbage_labels_are_not_called_several_subjects():
    garbage = ["\x01\x02:a", "k\x7f:b", "z:c", "q:d"]
    with pytest.raises(InputError, match="do not read as 'Subject:Marker' names .*damaged"):
        subject_columns(garbage, None, "f.c3d")
    with pytest.raises(InputError, match=r"several subjects \(prefixes 'V', 'W'\)"):
        subject_columns(["V:1", "V:2", "W:1", "W:2"], None, "f.c3d")
