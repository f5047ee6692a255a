"""The docs against the studies: every number, table and figure of README.md and docs/ is what
the studies compute now.

The workflow test runs the default, real-data and dense studies in a temporary directory, then
``facemotion docs --check`` against this repository's README.md and docs/: a result that moved
fails it, with one line per block or figure (``make study real dense pages`` rewrites them).
The unit tests show that the check rejects a block with one number changed and a figure with one
byte changed, and keep the README short and every relative link of the docs alive.
"""

import os
import re
import subprocess
import sys
import time
from pathlib import Path

import pytest
from click.testing import CliRunner
from helpers import REPO, SHARED_DATA

from facemotion.cli import cli, main
from facemotion.errors import InputError
from facemotion.study import pages
from facemotion.study.pages import EXTERNAL, Block, Figure, Sources

#: The README is read in a few minutes; everything longer belongs in docs/.
README_MAX_LINES = 220
#: Pages the docs link to that their own change of the repository writes (the architecture
#: guide, the changelog): a link may exist before the page does.
WRITTEN_ELSEWHERE = {"docs/architecture.md", "CHANGELOG.md"}
#: The studies the docs read, with their configs (None: the default study).
STUDIES = {"paper": None, "real": "config/real.yaml", "dense": "config/dense.yaml"}


# ---- the docs against fresh studies -----------------------------------------------------------

@pytest.fixture(scope="module")
def fresh_studies(tmp_path_factory, shared_data):
    """The docs' studies run from scratch in a temporary directory (one at a time, 2 cores);
    their wall times are printed."""
    work = tmp_path_factory.mktemp("docs_studies")
    env = dict(os.environ, PYTHONHASHSEED="0")
    for study, configfile in STUDIES.items():
        cmd = [sys.executable, "-m", "snakemake", "-s", str(REPO / "Snakefile"), "--directory",
               str(work), "--cores", "2", "--config", f"shared_data={shared_data}"]
        if configfile:
            cmd += ["--configfile", str(REPO / configfile)]
        start = time.monotonic()
        proc = subprocess.run(cmd, capture_output=True, text=True, env=env)
        assert proc.returncode == 0, (f"study {study} failed:\n{proc.stdout[-3000:]}\n"
                                      f"{proc.stderr[-5000:]}")
        print(f"study {study}: {time.monotonic() - start:.0f} s")
        assert (work / "results" / study / "manifest.tsv").is_file()
    return work / "results"


@pytest.mark.workflow
def test_docs_show_what_the_studies_compute(fresh_studies, shared_data):
    out = pages.run(REPO, fresh_studies, shared_data, check=True)
    assert not out.problems and not out.differs, (
        "README.md or docs/ differ from the studies (run `make study real dense pages`):\n"
        + "\n".join(out.problems + out.differs))
    # nothing skipped but the blocks another command writes: every study and figure was checked
    skipped = {re.search(r"block (\S+) skipped", line).group(1) if "block" in line else line
               for line in out.skipped}
    assert skipped == set(EXTERNAL), out.skipped
    assert out.unchanged == len(pages.BLOCKS) + len(pages.FIGURES)
    # the command line says the same, with exit status 0
    proc = subprocess.run([sys.executable, "-m", "facemotion.cli", "docs", "--check",
                           "--results", str(fresh_studies), "--repo", str(REPO),
                           "--shared-data", str(shared_data)], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "up to date" in proc.stdout


# ---- the check on a small page ------------------------------------------------------------------

@pytest.fixture
def small_docs(tmp_path, monkeypatch):
    """A repository with one page, one block that reads a study's table, one external block and
    one figure, and a finished study that feeds them."""
    study = tmp_path / "results" / "paper"
    (study / "tables").mkdir(parents=True)
    (study / "tables" / "numbers.tsv").write_text("k\terror_mm\n1\t1.23\n10\t0.53\n")
    (study / "figures").mkdir()
    (study / "figures" / "curve.png").write_bytes(bytes(range(256)) * 4)
    (study / "manifest.tsv").write_text("path\n")

    def render(src):
        rows = pages._tsv(src.root("paper") / "tables" / "numbers.tsv")
        return pages._table(["k", "error (mm)"], rows.values.tolist(), "rr")

    monkeypatch.setattr(pages, "BLOCKS", [Block("docs/page.md", "numbers", ("paper",),
                                                "results/paper/tables/numbers.tsv", render)])
    monkeypatch.setattr(pages, "FIGURES", [Figure("curve.png", "paper", "figures/curve.png")])
    repo = tmp_path / "repo"
    (repo / "docs" / "figures").mkdir(parents=True)
    (repo / "README.md").write_text("# x\n")
    (repo / "docs" / "page.md").write_text(
        "# Page\n\nThe table below.\n\n<!-- generated:numbers:start -->\n"
        "<!-- generated:numbers:end -->\n\nProse stays.\n\n<!-- generated:bench-qr:start -->\n"
        "a benchmark's table\n<!-- generated:bench-qr:end -->\n\n![curve](figures/curve.png)\n")
    out = pages.run(repo, tmp_path / "results", check=False)
    assert out.written and not out.problems
    return repo, tmp_path / "results"


def check(repo, results, capsys):
    with pytest.raises(SystemExit) as exit_:
        main(["docs", "--check", "--repo", str(repo), "--results", str(results)])
        raise SystemExit(0)
    return exit_.value.code, capsys.readouterr()


def test_write_then_check_passes_and_keeps_the_prose(small_docs, capsys):
    repo, results = small_docs
    text = (repo / "docs" / "page.md").read_text()
    assert "| 10 | 0.53 |" in text and "Prose stays." in text and "a benchmark's table" in text
    assert "written by `make pages`" in text
    assert (repo / "docs" / "figures" / "curve.png").read_bytes() == bytes(range(256)) * 4
    code, cap = check(repo, results, capsys)
    assert code == 0, cap.out
    assert "block bench-qr skipped: written by make bench" in cap.out


def test_check_rejects_one_number_changed(small_docs, capsys):
    repo, results = small_docs
    page = repo / "docs" / "page.md"
    page.write_text(page.read_text().replace("| 10 | 0.53 |", "| 10 | 0.54 |"))
    before = page.read_text()
    code, cap = check(repo, results, capsys)
    assert code == 1
    lines = [line for line in cap.out.splitlines() if "differs" in line]
    assert lines == [lines[0]] and "docs/page.md: block numbers differs" in lines[0]
    assert "0.54" in lines[0] and "0.53" in lines[0]
    assert page.read_text() == before  # --check writes nothing
    # writing mends it, and only the block
    pages.run(repo, results)
    assert page.read_text() == before.replace("| 10 | 0.54 |", "| 10 | 0.53 |")


def test_check_rejects_a_figure_with_one_byte_changed(small_docs, capsys):
    repo, results = small_docs
    fig = repo / "docs" / "figures" / "curve.png"
    data = bytearray(fig.read_bytes())
    data[100] ^= 1
    fig.write_bytes(bytes(data))
    code, cap = check(repo, results, capsys)
    assert code == 1
    assert "docs/figures/curve.png differs from results/paper/figures/curve.png" in cap.out
    assert fig.read_bytes() == bytes(data)


def test_a_figure_nothing_generates_is_reported_and_deleted(small_docs, capsys):
    repo, results = small_docs
    stray = repo / "docs" / "figures" / "old.png"
    stray.write_bytes(b"png")
    code, cap = check(repo, results, capsys)
    assert code == 1 and "docs/figures/old.png: generated by nothing" in cap.out
    pages.run(repo, results)
    assert not stray.exists()


def test_a_study_not_run_is_skipped_and_said(small_docs, tmp_path, capsys):
    repo, _ = small_docs
    code, cap = check(repo, tmp_path / "nothing", capsys)
    assert code == 0
    assert "block numbers skipped: no finished study at" in cap.out and "make study" in cap.out
    assert "docs/figures/curve.png skipped" in cap.out


def test_missing_or_unpaired_markers_are_errors(small_docs, capsys):
    repo, results = small_docs
    page = repo / "docs" / "page.md"
    text = page.read_text()
    page.write_text(text.replace("<!-- generated:numbers:end -->", ""))
    with pytest.raises(InputError, match="markers of block numbers do not pair up"):
        pages.run(repo, results, check=True)
    page.write_text(text.replace("generated:numbers:", "generated:other:"))
    code, cap = check(repo, results, capsys)
    assert code == 1 and "block numbers is missing" in cap.out


def test_the_docs_command_explains_its_options():
    res = CliRunner().invoke(cli, ["docs", "--help"])
    assert res.exit_code == 0, res.output
    for p in cli.commands["docs"].params:
        if p.param_type_name == "option" and p.name != "help":
            assert next(o for o in p.opts if o.startswith("--")) in res.output
            assert p.help and len(p.help) > 20


# ---- the repository's docs without studies ----------------------------------------------------

def test_blocks_that_read_no_study_are_up_to_date(tmp_path):
    """The settings, formats, designs, calibration and config blocks come from the repository
    alone: checked on every run of the tests, studies or not."""
    out = pages.run(REPO, tmp_path / "no_results", SHARED_DATA, check=True)
    assert not out.problems and not out.differs, "\n".join(out.problems + out.differs)
    checked = len(pages.BLOCKS) + len(pages.FIGURES) - sum(
        1 for line in out.skipped if "no finished study" in line)
    assert out.unchanged == checked > 0


def test_every_block_and_figure_is_on_a_page():
    texts = {p: (REPO / p).read_text() for p in pages.pages(REPO)}
    for b in pages.BLOCKS:
        assert f"<!-- generated:{b.name}:start -->" in texts[b.page], (b.page, b.name)
    shown = "\n".join(texts.values())
    for f in pages.FIGURES:
        assert f"figures/{f.name})" in shown, f"{f.name} is copied but no page shows it"
    names = [b.name for b in pages.BLOCKS]
    assert len(names) == len(set(names))


def test_readme_is_short():
    lines = (REPO / "README.md").read_text().splitlines()
    assert len(lines) <= README_MAX_LINES, f"README.md has {len(lines)} lines"


def _slug(heading: str) -> str:
    """GitHub's anchor of a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", heading.strip().lower()).replace(" ", "-")


def _links(text: str) -> list[str]:
    text = re.sub(r"```.*?```", "", text, flags=re.S)        # code blocks
    text = re.sub(r"`[^`\n]*`", "", text)                     # code spans
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    return re.findall(r"!?\[[^\]]*\]\(([^)\s]+)\)", text)


def test_every_relative_link_points_to_a_file():
    docs = [REPO / "README.md", REPO / "CONTRIBUTING.md", REPO / "config" / "README.md",
            *sorted((REPO / "docs").glob("*.md"))]
    broken = []
    for page in docs:
        for target in _links(page.read_text()):
            if re.match(r"[a-z]+:", target):
                continue  # http(s), mailto
            path, _, anchor = target.partition("#")
            dest = (page.parent / path).resolve() if path else page
            rel = os.path.relpath(dest, REPO)
            if not dest.exists():
                if rel not in WRITTEN_ELSEWHERE:
                    broken.append(f"{page.relative_to(REPO)}: {target} (no {rel})")
                continue
            if anchor and dest.suffix == ".md":
                headings = re.findall(r"^#+ (.+)$", re.sub(r"```.*?```", "", dest.read_text(),
                                                           flags=re.S), flags=re.M)
                if anchor not in {_slug(h) for h in headings}:
                    broken.append(f"{page.relative_to(REPO)}: {target} (no such heading)")
    assert not broken, "\n".join(broken)


def test_the_page_list_is_the_docs_folder():
    listed = set(pages.pages(REPO))
    on_disk = {"README.md", *(str(p.relative_to(REPO)) for p in (REPO / "docs").glob("*.md"))}
    assert listed == on_disk
    assert {Path(b.page) for b in pages.BLOCKS} <= {Path(p) for p in on_disk}
    assert Sources(REPO, REPO / "results").study("no-such-study") is None
