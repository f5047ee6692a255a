"""Subject sheet and dataset resolution: the user's interface to their data."""

import pytest

from facemotion.errors import InputError
from facemotion.study.sheet import (
    natural_key,
    parse_sentences,
    read_subject_sheet,
    resolve_datasets,
)

HEADER = "subject\trecordings\tformat\thead_markers\texclude_markers\n"


def write_sheet(tmp_path, rows, header=HEADER):
    p = tmp_path / "subjects.tsv"
    p.write_text(header + "".join(r + "\n" for r in rows))
    return p


def test_glob_is_relative_to_sheet_and_naturally_sorted(tmp_path):
    d = tmp_path / "data"
    d.mkdir()
    for name in ["s10.c3d", "s2.c3d", "s1.c3d"]:
        (d / name).write_bytes(b"")
    sheet = write_sheet(tmp_path, ["A\tdata/s*.c3d\tc3d\th1,h2,h3\th1,h2,h3"])
    subj = read_subject_sheet(sheet)["A"]
    assert [p.split("/")[-1] for p in subj.recordings] == ["s1.c3d", "s2.c3d", "s10.c3d"]
    assert subj.head_markers == ["h1", "h2", "h3"]
    assert natural_key("a2") < natural_key("a10")


def test_shared_data_placeholder(tmp_path):
    shared = tmp_path / "shared"
    shared.mkdir()
    (shared / "x.trc").write_text("")
    sheet = write_sheet(tmp_path, ["B\t{shared_data}/x.trc\ttrc\t\t"])
    assert read_subject_sheet(sheet, shared_data=shared)["B"].recordings == [str(shared / "x.trc")]


def test_simulated_subject_files_are_declared(tmp_path):
    sheet = write_sheet(tmp_path, ["S1\t\tc3d\tH1,H2,H3\t\tS1"],
                        header=HEADER.rstrip("\n") + "\tsimulate\n")
    subj = read_subject_sheet(sheet, virtual_dir="results/virtual")["S1"]
    assert len(subj.recordings) == 40
    assert subj.recordings[0] == "results/virtual/S1/S1_s01.c3d"


@pytest.mark.parametrize("row,needle", [
    ("A\tnope/*.c3d\tc3d\t\t", "match no file"),
    ("A\tmissing.c3d\tc3d\t\t", "not found"),
    ("A\tx.c3d\tbvh\t\t", "unknown format 'bvh'"),
    ("A b\tx.c3d\tc3d\t\t", "subject id"),
])
def test_bad_rows_name_the_problem(tmp_path, row, needle):
    sheet = write_sheet(tmp_path, [row])
    with pytest.raises(InputError, match=needle):
        read_subject_sheet(sheet)


def test_unknown_units_and_missing_columns(tmp_path):
    (tmp_path / "x.c3d").write_bytes(b"")
    sheet = write_sheet(tmp_path, ["A\tx.c3d\tc3d\t\t\tfurlong"],
                        header=HEADER.rstrip("\n") + "\tunits\n")
    with pytest.raises(InputError, match="unknown units 'furlong'"):
        read_subject_sheet(sheet)
    bad = tmp_path / "bad.tsv"
    bad.write_text("subject\tformat\nA\tc3d\n")
    with pytest.raises(InputError, match=r"missing column\(s\) \['recordings'"):
        read_subject_sheet(bad)
    with pytest.raises(InputError, match="file not found"):
        read_subject_sheet(tmp_path / "none.tsv")


def test_sentence_selection():
    assert parse_sentences("first:3", 10, "x") == [0, 1, 2]
    assert parse_sentences("last:2", 10, "x") == [8, 9]
    assert parse_sentences("2-4,7", 10, "x") == [1, 2, 3, 6]
    assert parse_sentences([1, 3], 10, "x") == [0, 2]
    with pytest.raises(InputError, match=r"datasets.d.train: sentence\(s\) \[11\] outside"):
        parse_sentences("11", 10, "datasets.d.train")
    with pytest.raises(InputError, match="cannot read"):
        parse_sentences("all", 10, "x")


def test_default_split_holds_out_last_quarter(tmp_path):
    sheet = write_sheet(tmp_path, ["S2a\t\tc3d\t\t\tS2a"],
                        header=HEADER.rstrip("\n") + "\tsimulate\n")
    subjects = read_subject_sheet(sheet)
    ds = resolve_datasets(subjects, {"S2a_star": {"subject": "S2a", "train": "last:30"}})
    assert ds["S2a"].train == list(range(38)) and ds["S2a"].heldout == list(range(38, 50))
    assert ds["S2a_star"].train == list(range(20, 50))
    assert ds["S2a_star"].heldout == list(range(20))
    with pytest.raises(InputError, match="both training and held out"):
        resolve_datasets(subjects, {"x": {"subject": "S2a", "train": "1-5", "heldout": "5-6"}})
    with pytest.raises(InputError, match="unknown subject 'S9'"):
        resolve_datasets(subjects, {"x": {"subject": "S9"}})


def test_copy_markers_column(tmp_path):
    header = HEADER.rstrip("\n") + "\tsimulate\tcopy_markers\n"
    sheet = write_sheet(tmp_path, ["S1\t\tc3d\tH1,H2,H3\t\tS1\t13=11"], header=header)
    assert read_subject_sheet(sheet)["S1"].copy_markers == [("13", "11")]
    sheet = write_sheet(tmp_path, ["S1\t\tc3d\tH1,H2,H3\t\tS1\t13"], header=header)
    with pytest.raises(InputError, match=r"row 2: copy_markers: '13' must look like"):
        read_subject_sheet(sheet)


def test_label_map_column_is_read_relative_to_the_sheet_and_checked(tmp_path):
    header = HEADER.rstrip("\n") + "\tsimulate\tlabel_map\n"
    (tmp_path / "maps").mkdir()
    (tmp_path / "maps" / "S1.tsv").write_text("label\tcommon\nlipL\tcorner_left\n")
    sheet = write_sheet(tmp_path, ["S1\t\tc3d\tH1,H2,H3\t\tS1\tmaps/S1.tsv",
                                   "S2a\t\tc3d\tH1,H2,H3\t\tS2a\t"], header=header)
    subjects = read_subject_sheet(sheet)
    assert subjects["S1"].label_map.common == {"lipL": "corner_left"}
    assert subjects["S2a"].label_map is None
    (tmp_path / "maps" / "S1.tsv").write_text("label\tcommon\nlipL\tc\nlipR\tc\n")
    with pytest.raises(InputError) as e:
        read_subject_sheet(sheet)
    assert str(e.value) == (f"subject sheet {sheet}, row 2 (subject 'S1'): label map "
                            f"{tmp_path / 'maps' / 'S1.tsv'}, line 3: labels 'lipL' and "
                            "'lipR' are both mapped to 'c'")
    (tmp_path / "maps" / "S1.tsv").unlink()
    with pytest.raises(FileNotFoundError, match=r"row 2 \(subject 'S1'\): label map .*S1.tsv: "
                                                "file not found"):
        read_subject_sheet(sheet)


def test_s1_design_copies_11_into_13_by_default(tmp_path):
    header = HEADER.rstrip("\n") + "\tsimulate\n"
    sheet = write_sheet(tmp_path, ["S1\t\tc3d\tH1,H2,H3\t\tS1", "S2a\t\tc3d\tH1,H2,H3\t\tS2a"],
                        header=header)
    subjects = read_subject_sheet(sheet)
    assert subjects["S1"].copy_markers == [("13", "11")]
    assert subjects["S2a"].copy_markers == []


def test_dense_designs_are_written_in_their_format(tmp_path):
    header = HEADER.rstrip("\n") + "\tsimulate\tn_sentences\n"
    sheet = write_sheet(tmp_path, ["D\t\ttrc\tH1\tH1\tD468\t12",
                                   "F\t\topenface_csv\tH1\tH1\tD5023\t3"], header=header)
    subj = read_subject_sheet(sheet, virtual_dir="v")
    assert subj["D"].recordings[-1] == "v/D/D_s12.trc" and len(subj["D"].recordings) == 12
    assert subj["F"].recordings[0] == "v/F/F_s01.csv"
    sheet = write_sheet(tmp_path, ["S\t\ttrc\t\t\tS2a"], header=HEADER.rstrip("\n")
                        + "\tsimulate\n")
    with pytest.raises(InputError, match="written as c3d, not 'trc'"):
        read_subject_sheet(sheet)


def test_sheet_is_read_literally(tmp_path):
    """A '#' in a cell is part of it (no comment character); a byte-order mark is ignored; a
    marker listed twice and a directory as recordings are errors naming the sheet's row."""
    (tmp_path / "take#1.trc").write_text("")
    (tmp_path / "takes").mkdir()
    sheet = tmp_path / "s.tsv"
    sheet.write_text("\ufeffsubject\trecordings\tformat\thead_markers\texclude_markers\n"
                     "A\ttake#1.trc\ttrc\t\tL#1\n", encoding="utf-8")
    a = read_subject_sheet(sheet)["A"]
    assert a.recordings == [str(tmp_path / "take#1.trc")] and a.exclude_markers == ["L#1"]
    sheet.write_text("subject\trecordings\tformat\thead_markers\texclude_markers\n"
                     "A\ttake#1.trc\ttrc\tH1,H2,H1\t\n")
    with pytest.raises(InputError, match=r"row 2: column head_markers of subject 'A' lists "
                                         r"marker\(s\) H1 twice"):
        read_subject_sheet(sheet)
    sheet.write_text("subject\trecordings\tformat\thead_markers\texclude_markers\n"
                     "A\ttakes\ttrc\t\t\n")
    with pytest.raises(InputError, match=r"row 2: recordings .*takes of subject 'A' is a "
                                         r"directory; give a file or a glob such as takes/\*\.trc"):
        read_subject_sheet(sheet)


def test_the_rate_column_declares_a_rate_and_reaches_the_loading_params(tmp_path):
    from facemotion.study.sheet import dataset_params

    (tmp_path / "clip.csv").write_bytes(b"")
    sheet = write_sheet(tmp_path, ["A\tclip.csv\topenface_csv\t\t\t30", "B\tclip.csv\topenface_csv"
                                   "\t\t\t"], header=HEADER.rstrip("\n") + "\trate\n")
    subjects = read_subject_sheet(sheet)
    assert subjects["A"].rate == 30.0 and subjects["B"].rate is None
    datasets = resolve_datasets(subjects, None)
    assert dataset_params(subjects, datasets, "A")["rate"] == 30.0
    # a sheet without a declared rate gives the params it always gave
    assert "rate" not in dataset_params(subjects, datasets, "B")
    bad = write_sheet(tmp_path, ["A\tclip.csv\topenface_csv\t\t\t0"],
                      header=HEADER.rstrip("\n") + "\trate\n")
    with pytest.raises(InputError, match=r"subject 'A'.*rate must be a positive number of Hz"):
        read_subject_sheet(bad)
