"""Facts written once and read everywhere else: the formats, units and designs (their
registries), and the version.

The subject sheet's schema has no lists of its own for ``format``, ``units`` and ``simulate``
(facemotion.study.settings.sheet_schema fills them from the package), the command line's
``--format`` is the format registry, and the version is ``facemotion._version.__version__``,
which pyproject.toml, the installed metadata, CITATION.cff and CHANGELOG.md follow.
"""

from __future__ import annotations

import importlib
import importlib.metadata
import json
import re
import tomllib
from pathlib import Path

import pytest
import yaml
from click.testing import CliRunner
from helpers import REPO, SCHEMAS

from facemotion import cli
from facemotion._version import __version__
from facemotion.errors import InputError
from facemotion.io import registry
from facemotion.io.base import UNITS
from facemotion.io.registry import FORMAT_NAMES, FORMATS, SUFFIX_FORMATS
from facemotion.study.settings import sheet_schema, validate_sheet
from facemotion.virtual.designs import DESIGN_NAMES

SHEET_SCHEMA = SCHEMAS / "subjects.schema.yaml"
FILLED = ("format", "units", "simulate")


# --- formats, units, designs ----------------------------------------------------------------

def format_options():
    """(command name, its --format option) for every command of the CLI that has one."""
    out = []
    for name, command in cli.cli.commands.items():
        for p in command.params:
            if "--format" in getattr(p, "opts", ()):
                out.append((name, p))
    return out


def test_the_command_lines_format_choices_are_the_registry():
    options = format_options()
    assert {name for name, _ in options} >= {"info", "rank"}
    for name, option in options:
        assert list(option.type.choices) == list(FORMAT_NAMES), name


def test_the_command_lines_help_lists_the_suffixes_and_units():
    for name in ("info", "rank"):
        text = " ".join(CliRunner().invoke(cli.cli, [name, "--help"]).output.split())
        for choice in FORMAT_NAMES:
            assert choice in text, (name, choice)
        suffixes = re.search(r"else from the file suffix \(([^)]*)\)", text).group(1)
        assert suffixes.split(", ") == list(SUFFIX_FORMATS)
        units = re.search(r"Units \(([^)]*)\) of a file", text).group(1)
        assert units.split(", ") == list(UNITS)


def test_a_format_outside_the_registry_is_refused_by_the_command_line():
    result = CliRunner().invoke(cli.cli, ["info", "--format", "bvh", "x.bvh"])
    assert result.exit_code != 0
    assert "'bvh' is not one of" in result.output


def test_the_sheet_schema_file_holds_no_list_the_package_holds():
    raw = yaml.safe_load(SHEET_SCHEMA.read_text(encoding="utf-8"))
    for column in FILLED:
        assert "enum" not in raw["properties"][column], column


def test_the_sheet_schema_lists_are_the_packages():
    props = sheet_schema(SHEET_SCHEMA)["properties"]
    assert props["format"]["enum"] == list(FORMAT_NAMES)
    assert props["units"]["enum"] == ["", *UNITS]
    assert props["simulate"]["enum"] == ["", *DESIGN_NAMES]


def test_the_sheet_schema_follows_a_format_added_to_the_registry(monkeypatch):
    # Planted: one more format in the registry. The sheet's list follows it, so the lists
    # are read from the registry, not merely equal to it today.
    extra = registry.Format("bvh", "BioVision hierarchy", "bvh", "read_bvh", (".bvh",))
    monkeypatch.setitem(FORMATS, "bvh", extra)
    monkeypatch.setattr(registry, "FORMAT_NAMES", (*FORMAT_NAMES, "bvh"))
    assert sheet_schema(SHEET_SCHEMA)["properties"]["format"]["enum"][-1] == "bvh"


def test_every_registered_format_has_its_functions_and_suffixes():
    for name, form in FORMATS.items():
        assert name == form.name == name.lower()
        module = importlib.import_module(f"facemotion.io.{form.module}")
        for attr in (form.reader, form.label_reader, form.writer):
            if attr is not None:
                assert callable(getattr(module, attr)), (name, attr)
        for suffix in form.suffixes:
            assert registry.infer_format(f"take{suffix.upper()}") == name
    assert len(SUFFIX_FORMATS) == sum(len(f.suffixes) for f in FORMATS.values())


def write_sheet(tmp_path: Path, rows: list[dict]) -> Path:
    columns = ["subject", "recordings", "format", "head_markers", "exclude_markers", "units",
               "simulate"]
    lines = ["\t".join(columns)] + ["\t".join(r.get(c, "") for c in columns) for r in rows]
    path = tmp_path / "subjects.tsv"
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


@pytest.mark.parametrize("column,value", [("format", "bvh"), ("units", "furlong"),
                                          ("simulate", "S9")])
def test_a_sheet_value_outside_the_packages_lists_is_refused_naming_row_and_column(
        tmp_path, column, value):
    good = {"subject": "A", "recordings": "a.c3d", "format": "c3d", "units": "mm"}
    bad = {**good, "subject": "B", column: value}
    validate_sheet(write_sheet(tmp_path, [good]), SHEET_SCHEMA)
    with pytest.raises(InputError, match=rf"subjects\.tsv, row 3, column {column}: "
                                         rf"'{value}' is not one of"):
        validate_sheet(write_sheet(tmp_path, [good, bad]), SHEET_SCHEMA)


# --- the version ----------------------------------------------------------------------------

def changelog_version(text: str) -> str:
    """The version of the top released entry (``## [X.Y.Z] - date``) of a Keep a Changelog
    file; an ``Unreleased`` section above it is skipped."""
    for m in re.finditer(r"^## \[([^\]]+)\](.*)$", text, flags=re.MULTILINE):
        if m.group(1).lower() != "unreleased":
            assert re.fullmatch(r" - \d{4}-\d{2}-\d{2}", m.group(2)), m.group(0)
            return m.group(1)
    raise AssertionError("no released entry in the changelog")


def citation_version(text: str) -> str:
    return str(yaml.safe_load(text)["version"])


def version_problems(versions: dict[str, str]) -> list[str]:
    """Each place whose version differs from the package's."""
    return [f"{where}: {v} (the package: {__version__})" for where, v in versions.items()
            if v != __version__]


def installed_here() -> str | None:
    """The installed metadata's version when the installed facemotion is this checkout."""
    try:
        dist = importlib.metadata.distribution("facemotion")
    except importlib.metadata.PackageNotFoundError:
        return None
    url = json.loads(dist.read_text("direct_url.json") or "{}").get("url", "")
    if url.removeprefix("file://") != str(REPO):
        return None  # another checkout's (or a wheel's) metadata says nothing of this one
    return dist.version


def test_the_version_is_written_once_and_followed_everywhere():
    pyproject = tomllib.loads((REPO / "pyproject.toml").read_text(encoding="utf-8"))
    assert "version" not in pyproject["project"]
    assert pyproject["project"]["dynamic"] == ["version"]
    assert pyproject["tool"]["setuptools"]["dynamic"]["version"] == {
        "attr": "facemotion._version.__version__"}
    assert re.fullmatch(r"\d+\.\d+\.\d+", __version__)
    versions = {
        "CITATION.cff": citation_version((REPO / "CITATION.cff").read_text(encoding="utf-8")),
        "CHANGELOG.md": changelog_version((REPO / "CHANGELOG.md").read_text(encoding="utf-8")),
        "facemotion --version": CliRunner().invoke(cli.cli, ["--version"]).output.split()[-1],
    }
    if (installed := installed_here()) is not None:
        versions["installed metadata"] = installed
    assert version_problems(versions) == []


def test_the_version_check_rejects_a_place_left_behind():
    changelog = ("# Changelog\n\n## [Unreleased]\n\n### Added\n- x\n\n"
                 "## [0.1.9] - 2026-11-01\n\n## [0.1.0] - 2026-10-01\n")
    assert changelog_version(changelog) == "0.1.9"
    assert changelog_version(changelog.replace("0.1.9", __version__)) == __version__
    assert version_problems({"CHANGELOG.md": changelog_version(changelog),
                             "CITATION.cff": citation_version(f"version: {__version__}\n")}) \
        == [f"CHANGELOG.md: 0.1.9 (the package: {__version__})"]
    with pytest.raises(AssertionError):
        changelog_version("## [0.3.0] 2026-12-01\n")  # no dash before the date
    with pytest.raises(AssertionError):
        changelog_version("# Changelog\n\n## [Unreleased]\n")
