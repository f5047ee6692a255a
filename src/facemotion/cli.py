"""The ``facemotion`` command line: quick one-file answers, and a front door to the study.

    facemotion info take.c3d                          # labels, rate, units, frames, gaps
    facemotion rank s1.c3d s2.c3d --head A,B,C        # first pivots, r values, epsilon-rank
    facemotion study --configfile config/real.yaml    # the Snakemake workflow
    facemotion docs [--check]                         # the docs' numbers and figures

``rank`` loads the files by the workflow's own path (:func:`facemotion.load`: read, remove head
motion, select markers, fill gaps, displacements) with the workflow's default settings, so its
first pivots are those of a dataset of the same files in the study.  Errors are one line on
stderr and a non-zero exit status (2 for a wrong command line, 1 for bad input).
"""

from __future__ import annotations

import importlib.util
import math
import subprocess
import sys
from pathlib import Path

import click

from facemotion._version import __version__
from facemotion.errors import InputError
from facemotion.io.base import UNITS as UNIT_NAMES
from facemotion.io.registry import FORMAT_NAMES, SUFFIX_FORMATS
from facemotion.ranking.result import DEFAULT_R_NORMALISATION, R_NORMALISATIONS

#: Tolerances (mm) of the epsilon-rank when none are given: the study's default (qr.tolerances_mm).
DEFAULT_TOLERANCES_MM = (0.25, 0.5, 1.0)


def _labels(ctx, param, value) -> list[str]:
    """A comma-separated list of marker labels (the option may also be repeated)."""
    out = [x.strip() for v in value for x in v.split(",") if x.strip()]
    return out


def _numbers(ctx, param, value) -> list[float]:
    out = []
    for v in value:
        for x in v.split(","):
            if not x.strip():
                continue
            try:
                out.append(float(x))
            except ValueError:
                raise click.BadParameter(f"{x.strip()!r} is not a number") from None
    return out


def _tolerances(ctx, param, value) -> list[float]:
    """Tolerances (mm): positive finite numbers, checked before anything is printed."""
    out = _numbers(ctx, param, value)
    for x in out:
        if not math.isfinite(x) or x <= 0:
            raise click.BadParameter(f"{x:g} is not a positive tolerance (mm)")
    return out


FORMAT = click.option(
    "--format", "fmt", type=click.Choice(FORMAT_NAMES, case_sensitive=False),
    default=None, help="File format. Default: from the file's content (C3D header, TRC "
                       "PathFileType, Motive 'Format Version', QTM header, OpenFace or wide "
                       f"CSV columns), else from the file suffix ({', '.join(SUFFIX_FORMATS)}).")
SUBJECT_PREFIX = click.option(
    "--subject-prefix", default=None, metavar="NAME",
    help="The subject to read from a file whose labels are 'Subject:Marker' with several "
         "subjects (the sheet's subject_prefix); its markers lose the prefix.")
RATE = click.option(
    "--rate", type=float, default=None, metavar="HZ",
    help="Declared frame rate (the sheet's rate): replaces the rate an OpenFace CSV's "
         "timestamps imply; any other file must state this rate itself.")
UNITS = click.option(
    "--units", default=None, metavar="UNIT",
    help=f"Units ({', '.join(UNIT_NAMES)}) of a file that does not state its own (a CSV file, "
         "or a C3D/TRC file without POINT:UNITS/Units); a file's own units always apply. "
         "Default: such a "
         "CSV file is read as mm. Everything is reported in mm.")


def _target_mm(ctx, param, value) -> float:
    """A length such as 1mm, 0.5 mm, 0.1cm or 1 (mm), in mm."""
    if value is None:
        return None
    import re

    from facemotion.io.base import unit_scale

    m = re.fullmatch(r"\s*([0-9]*\.?[0-9]+(?:[eE][-+]?[0-9]+)?)\s*([a-zA-Z]*)\s*", value)
    if not m:
        raise click.BadParameter(f"{value!r} is not a length such as 1mm or 0.5")
    try:
        scale = unit_scale(m.group(2) or "mm", "--error")
    except InputError as e:
        raise click.BadParameter(str(e).split(": ", 1)[-1]) from None
    mm = float(m.group(1)) * scale
    if not mm > 0:
        raise click.BadParameter(f"{value!r}: the target error must be positive")
    return mm


def _emit(as_json: dict | None, tsv, text: str) -> None:
    """One of the three forms of a command's answer on stdout: JSON, TSV or text."""
    if as_json is not None:
        import json

        click.echo(json.dumps(as_json, indent=1, allow_nan=False, default=_json_default))
    elif tsv is not None:
        click.echo(tsv.to_csv(sep="\t", index=False, float_format="%.6g",
                              lineterminator="\n"), nl=False)
    else:
        click.echo(text)


def _json_default(value):
    """numpy scalars and arrays in JSON; NaN is refused by allow_nan=False upstream, so
    numbers are made finite or None first (:func:`_finite`)."""
    import numpy as np

    if isinstance(value, np.generic):
        return value.item()
    if isinstance(value, np.ndarray):
        return value.tolist()
    raise TypeError(f"not JSON serialisable: {type(value).__name__}")


def _finite(records):
    """NaN and inf as None (JSON null), recursively."""
    import math

    if isinstance(records, dict):
        return {k: _finite(v) for k, v in records.items()}
    if isinstance(records, list | tuple):
        return [_finite(v) for v in records]
    if isinstance(records, float) and not math.isfinite(records):
        return None
    return records


OUTPUT_FORMS = [
    click.option("--json", "as_json", is_flag=True,
                 help="Print the answer as one JSON object on stdout (for scripts)."),
    click.option("--tsv", "as_tsv", is_flag=True,
                 help="Print the answer's main table as TSV on stdout (for scripts)."),
]


def _output_forms(f):
    for option in reversed(OUTPUT_FORMS):
        f = option(f)
    return f


@click.group(context_settings={"help_option_names": ["-h", "--help"], "max_content_width": 100})
@click.version_option(__version__, prog_name="facemotion")
def cli() -> None:
    """How the face moves during speech: kinematic regions by QR with column pivoting
    (Lucero & Munhall 2008) and a lip model trained from data (Basu & Pentland 1997).

    Run `facemotion COMMAND --help` for a command's options. info, rank and design print
    JSON (--json) or a TSV table (--tsv) on stdout for scripts; messages go to stderr.

    \b
    Exit status: 0 done; 1 bad input (a file, marker or setting; one line on stderr names
    it) or, for `docs --check`, a difference; 2 a wrong command line; 130 interrupted;
    `study` returns Snakemake's own status.
    """


@cli.command()
@click.argument("file", type=click.Path(dir_okay=False))
@FORMAT
@UNITS
@SUBJECT_PREFIX
@RATE
@click.option("--markers/--no-markers", default=True, show_default=True,
              help="List every marker with its missing samples and gaps.")
@_output_forms
def info(file: str, fmt: str | None, units: str | None, subject_prefix: str | None,
         rate: float | None, markers: bool, as_json: bool = False, as_tsv: bool = False) -> None:
    """What a recording holds: markers, frame rate, units, frames and gaps (missing samples).

    FILE is one take in any format of --format. Coordinates are converted to mm on reading;
    the units line says what the file declared.
    """
    from facemotion.ingest.gaps import gap_report
    from facemotion.io.registry import read_recording

    rec = read_recording(file, fmt, units=units, subject_prefix=subject_prefix, rate=rate)
    report = gap_report(rec)
    n_missing = int(report["missing_frames"].sum())
    total = rec.n_frames * rec.n_markers
    table = report[["marker", "missing_frames", "n_gaps", "longest_gap_frames"]]
    if as_json or as_tsv:
        answer = {"file": rec.source, "markers": rec.n_markers, "rate_hz": rec.rate,
                  "frames": rec.n_frames, "duration_s": rec.n_frames / rec.rate,
                  "units": rec.units, "units_source": rec.units_source,
                  "missing_samples": n_missing, "samples": total,
                  "gaps": int(report["n_gaps"].sum()),
                  "per_marker": table.to_dict(orient="records")}
        _emit(_finite(answer) if as_json else None, table if as_tsv else None, "")
        return
    click.echo(f"file: {rec.source}")
    click.echo(f"markers: {rec.n_markers}")
    click.echo(f"rate: {rec.rate:g} Hz")
    click.echo(f"frames: {rec.n_frames} ({rec.n_frames / rec.rate:.3f} s)")
    where = {"file": "declared by the file", "sheet": "from --units",
             "default": "not declared, read as mm"}.get(rec.units_source, rec.units_source)
    click.echo(f"units: {rec.units} ({where}; reported in mm)")
    gappy = report[report["n_gaps"] > 0]
    click.echo(f"missing samples: {n_missing} of {total} "
               f"({100.0 * n_missing / total if total else 0.0:.2f}%), "
               f"{int(report['n_gaps'].sum())} gap(s) in {len(gappy)} marker(s)")
    if markers:
        click.echo(table.to_string(index=False))


@cli.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--head", "head", multiple=True, callback=_labels, metavar="A,B,C",
              help="Head markers (at least 3, comma-separated): markers that move only with "
                   "the head (forehead, nose bridge, inner eye corners). Their rigid motion is "
                   "removed from every marker, as in the study. Default: none (no head "
                   "correction).")
@click.option("--exclude", "exclude", multiple=True, callback=_labels, metavar="A,B,...",
              help="Markers left out of the ranking (comma-separated), e.g. the head markers "
                   "themselves, which no longer move once the head motion is removed.")
@click.option("--include", "include", multiple=True, callback=_labels, metavar="A,B,...",
              help="Rank only these markers (comma-separated). Default: every marker of the "
                   "file not excluded.")
@click.option("--tolerance", "tolerances", multiple=True, callback=_tolerances,
              metavar="MM[,MM...]",
              help="Tolerances epsilon (mm) of the epsilon-rank, comma-separated. Default: "
                   + ", ".join(f"{t:g}" for t in DEFAULT_TOLERANCES_MM) + " (the study's).")
@click.option("--r-normalisation", type=click.Choice(list(R_NORMALISATIONS)),
              default=DEFAULT_R_NORMALISATION, show_default=True,
              help="Reading of the paper's 'R values normalized to the size of R' (Fig. 2) that "
                   "the tolerances apply to: none (|r_kk| and ||R22||_2 in mm), per_coordinate "
                   "(divided by sqrt(rows of A)) or per_frame (by sqrt(frames)); the study's "
                   "qr.r_normalisation.")
@click.option("--first", "n_first", type=click.IntRange(min=1), default=10, show_default=True,
              help="How many first pivots to print on the 'first pivots' line.")
@click.option("--method", type=click.Choice(["auto", "gram", "tsqr", "scipy"]),
              default="auto", show_default=True,
              help="Route of the QR with column pivoting (all give the same pivots; see "
                   "facemotion.ranking.routes).")
@click.option("--max-interp-s", type=click.FloatRange(min=0), default=None, metavar="S",
              help="Longest gap (s) filled by cubic interpolation; longer gaps by PCA. "
                   "Default: the study's (0.1 s).")
@click.option("--long-gaps", type=click.Choice(["pca", "error"]), default=None,
              help="Longer gaps: fill by PCA from the other markers, or stop with an error. "
                   "Default: the study's (pca).")
@click.option("--neutral", type=click.Choice(["first_frame", "mean_first_10"]), default=None,
              help="Neutral pose each take's displacements are measured from. Default: the "
                   "study's (first_frame).")
@click.option("--max-gib", type=click.FloatRange(min=0, min_open=True), default=None,
              metavar="GIB",
              help="Stream the takes instead of holding them whole: each read in blocks, "
                   "checked, aligned, filled and added into A^T A within this memory bound "
                   "(GiB), for recordings longer than memory; A is written to a temporary "
                   "file under $TMPDIR and removed. The pivots are the whole-take path's (the "
                   "Gram route); --method is not used.")
@FORMAT
@UNITS
@SUBJECT_PREFIX
@RATE
@_output_forms
def rank(files, head, exclude, include, tolerances, r_normalisation, n_first, method,
         max_interp_s, long_gaps, neutral, max_gib, fmt, units, subject_prefix, rate,
         as_json=False, as_tsv=False) -> None:
    """Rank the markers of one or more takes by QR with column pivoting (Lucero & Munhall
    2008, Sec. III) and give the epsilon-rank (Sec. III, eq. 1).

    FILES are the takes (sentences) of one talker, stacked into one displacement matrix A as in
    the study (all of them train). Prints the first pivots, the r values in pivot order
    (r = |r_kk| in mm, and its normalised readings) and, for each tolerance, the epsilon-rank
    (the smallest k with ||R22||_2 <= tolerance) beside the count of |r_kk| above it.
    """
    from facemotion.ingest.loading import load
    from facemotion.ranking.epsilon_rank import epsilon_rank
    from facemotion.ranking.routes import rank_markers

    options = {k: v for k, v in (("units", units), ("max_interp_s", max_interp_s),
                                 ("long_gaps", long_gaps), ("neutral", neutral),
                                 ("subject_prefix", subject_prefix), ("rate", rate))
               if v is not None}
    if max_gib is None:
        data = load(list(files), fmt=fmt, head_markers=head, exclude_markers=exclude,
                    include_markers=include, progress=True, **options)
        _echo_filled(data.gap_report)
        ranking = rank_markers(data.train, method=method)
        rows, n = data.train.A.shape
    else:
        ranking = _rank_streamed(list(files), fmt, head, exclude, include, max_gib, options)
        rows, n = ranking.rows, ranking.n
    table = epsilon_rank(ranking, list(tolerances) or list(DEFAULT_TOLERANCES_MM),
                         normalisation=r_normalisation)
    if as_json or as_tsv:
        pivots = ranking.to_frame(r_normalisation)
        answer = {"takes": [str(f) for f in files], "rows": rows, "frames": rows // 3,
                  "markers": n, "first_pivots": ranking.labels_in_order[:n_first],
                  "pivots": pivots.to_dict(orient="records"),
                  "epsilon_rank": table.to_dict(orient="records")}
        _emit(_finite(answer) if as_json else None, pivots if as_tsv else None, "")
        return
    click.echo(f"A: {rows} rows ({rows // 3} frames) x {n} markers from {len(files)} take(s)")
    click.echo(f"first pivots: {', '.join(ranking.labels_in_order[:n_first])}")
    click.echo("")
    click.echo(ranking.to_frame(r_normalisation).to_string(
        index=False, float_format=lambda x: f"{x:.6g}"))
    click.echo("")
    # the redundant markers are the pivots after the epsilon-rank, in the order printed above
    click.echo(table.drop(columns=["redundant_markers"], errors="ignore").to_string(index=False))


def _rank_streamed(files, fmt, head, exclude, include, max_gib, options):
    """The takes streamed (:func:`facemotion.ingest.streaming.stream_dataset`, all of them
    training) and their Gram ranked."""
    import tempfile

    from facemotion.ingest.streaming import stream_dataset
    from facemotion.io.registry import infer_format
    from facemotion.ranking.qr import rank_from_gram

    fmt = fmt or infer_format(files[0])
    with tempfile.TemporaryDirectory(prefix="facemotion-") as tmp:
        data = stream_dataset(files, fmt, Path(tmp) / "A.npz", head_markers=head,
                              exclude_markers=exclude, include_markers=include,
                              train=list(range(len(files))), heldout=[], max_gib=max_gib,
                              markers_named_in="the arguments", **options)
    _echo_filled(data.gap_report)
    return rank_from_gram(data.gram, data.train_rows, data.labels)


def _echo_filled(report) -> None:
    """One line on stderr for the samples the loading filled: missing samples (gaps, invalid or
    non-finite values) and outliers, by marker, so a quick answer never hides them."""
    missing = report[report["missing_frames"] > 0]
    outliers = report[report["outlier_frames"] > 0]
    if missing.empty and outliers.empty:
        return
    def by_marker(rows, column):
        top = rows.sort_values(column, ascending=False, kind="stable")
        names = [f"{m} ({int(v)})" for m, v in zip(top["marker"], top[column], strict=True)]
        return ", ".join(names[:8]) + (f" and {len(names) - 8} more" if len(names) > 8 else "")
    parts = []
    if not missing.empty:
        parts.append(f"{int(missing['missing_frames'].sum())} missing sample(s) filled: "
                     + by_marker(missing, "missing_frames"))
    if not outliers.empty:
        parts.append(f"{int(outliers['outlier_frames'].sum())} outlier sample(s) treated as "
                     "gaps: " + by_marker(outliers, "outlier_frames"))
    click.echo("facemotion: " + "; ".join(parts) + " (marker (frames); "
               "`facemotion info FILE` lists the gaps of each marker)", err=True)


def _workflow_snakefile() -> Path:
    """The repository's Snakefile (an install from a source checkout, e.g. pip install -e)."""
    snakefile = Path(__file__).resolve().parents[2] / "Snakefile"
    if not snakefile.is_file():
        raise InputError(
            f"no Snakefile next to this installation ({snakefile.parent}); "
            "the workflow ships with the source repository: clone it and pip install -e "
            "'.[workflow]', or run snakemake -s /path/to/facemotion/Snakefile")
    return snakefile


def _check_config_files(args: list[str]) -> None:
    """Each file after --configfile/--configfiles exists (Snakemake reads them from the
    current directory, before anything else, and fails with a long traceback)."""
    files, taking = [], False
    for a in args:
        if a.startswith("--configfile=") or a.startswith("--configfiles="):
            files.append(a.split("=", 1)[1])
            taking = False
        elif a in ("--configfile", "--configfiles"):
            taking = True
        elif taking and not a.startswith("-"):
            files.append(a)
        else:
            taking = False
    for f in files:
        if not Path(f).expanduser().is_file():
            raise InputError(f"--configfile {f}: no such file (looked for "
                             f"{Path(f).expanduser().absolute()})")


@cli.command(context_settings={"ignore_unknown_options": True, "allow_extra_args": True})
@click.argument("snakemake_args", nargs=-1, type=click.UNPROCESSED)
def study(snakemake_args) -> None:
    """Run the Snakemake study: `snakemake -s <repository>/Snakefile SNAKEMAKE_ARGS...`.

    Every argument is passed to snakemake unchanged, e.g. `facemotion study --configfile
    config/real.yaml`, `facemotion study -n` (dry run), `facemotion study -- --help`
    (snakemake's own options). Without --cores/--jobs/--profile it runs on 2 cores. Outputs go
    to results/<study>/ under the current directory (or --directory). Needs the workflow extra:
    pip install 'facemotion[workflow]'.
    """
    if importlib.util.find_spec("snakemake") is None:
        raise InputError("Snakemake is not installed; `facemotion study` needs the workflow "
                         "extra: pip install 'facemotion[workflow]'")
    args = list(snakemake_args)
    if args[:1] == ["--"]:
        args = args[1:]
    _check_config_files(args)
    if not any(a in ("-s", "--snakefile") or a.startswith("--snakefile=") for a in args):
        args = ["--snakefile", str(_workflow_snakefile()), *args]
    scheduling = ("-c", "--cores", "-j", "--jobs", "--profile", "--workflow-profile", "-h",
                  "--help", "--version", "-v")
    if not any(a in scheduling or a.split("=")[0] in scheduling
               or (a.startswith("-c") and a[2:].isdigit())
               or (a.startswith("-j") and a[2:].isdigit()) for a in args):
        args = ["--cores", "2", *args]
    proc = subprocess.run([sys.executable, "-m", "snakemake", *args], check=False)
    if proc.returncode:
        sys.exit(proc.returncode)


@cli.command()
@click.option("--check", is_flag=True,
              help="Write nothing: compare every generated block and figure with its sources "
                   "and exit 1 with one line per difference.")
@click.option("--results", default="results", show_default=True,
              type=click.Path(file_okay=False),
              help="The folder holding the studies' results (results/<study>/).")
@click.option("--repo", default=".", show_default=True, type=click.Path(file_okay=False),
              help="The repository whose README.md and docs/ are written or checked.")
@click.option("--shared-data", default=None, type=click.Path(file_okay=False),
              help="The shared real data (some blocks measure them). Default: "
                   "../shared/data beside the repository.")
def docs(check: bool, results: str, repo: str, shared_data: str | None) -> None:
    """Write every number, table and figure README.md and docs/ show from the studies'
    outputs (results/paper, results/real, results/dense): the blocks between
    <!-- generated:NAME:start --> and <!-- generated:NAME:end --> markers, and the figures in
    docs/figures/. Blocks of a study that has not been run, and blocks another command writes
    (make bench), are skipped with a line saying so.
    """
    from facemotion.study.pages import run

    root = Path(repo).resolve()
    shared = Path(shared_data) if shared_data else root.parent / "shared" / "data"
    out = run(root, Path(results), shared, check=check)
    for line in out.skipped:
        click.echo(line)
    if check:
        for line in out.problems + out.differs:
            click.echo(line)
        if out.problems or out.differs:
            click.echo(f"facemotion docs --check: {len(out.problems) + len(out.differs)} "
                       "difference(s); `make pages` rewrites the blocks and figures", err=True)
            sys.exit(1)
        click.echo(f"facemotion docs --check: {out.unchanged} blocks and figures up to date")
        return
    for line in out.written:
        click.echo(line)
    for line in out.problems:
        click.echo(line)
    click.echo(f"facemotion docs: {len(out.written)} written, {out.unchanged} up to date")
    if out.problems:
        sys.exit(1)


@cli.command()
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--head", "head", multiple=True, callback=_labels, metavar="A,B,C",
              help="Head markers (at least 3): removed as rigid head motion and placed in "
                   "every take; never among the k markers.")
@click.option("--error", "target_mm", default="1mm", show_default=True, callback=_target_mm,
              metavar="LENGTH", help="Target mean held-out error (e.g. 1mm, 0.5mm); k is the "
                                     "smallest number of markers that reaches it.")
@click.option("--k", "k", type=click.IntRange(min=1), default=None,
              help="Number of markers to place, instead of a target error.")
@click.option("--force", "--include", "force", multiple=True, callback=_labels,
              metavar="A,B,...", help="Markers that must be placed.")
@click.option("--exclude", "exclude", multiple=True, callback=_labels, metavar="A,B,...",
              help="Markers never placed (they are still predicted).")
@click.option("--drop", "drop", multiple=True, callback=_labels, metavar="A,B,...",
              help="Markers left out altogether (neither placed nor predicted).")
@click.option("--symmetric", is_flag=True,
              help="Left-right symmetric sets only (markers paired by L/R in their labels).")
@click.option("--subject", "subjects", multiple=True, callback=_labels, metavar="S1,S2,...",
              help="Each take's subject, in the order of FILES, when the takes come from "
                   "several subjects (the interval then resamples subjects too).")
@click.option("--label-map", "label_map", default=None, type=click.Path(dir_okay=False),
              help="TSV with columns subject, label, common: each subject's marker labels -> "
                   "common names, for subjects recorded with differently named markers "
                   "(needs --subject; marker options then use the common names).")
@click.option("--resamples", type=click.IntRange(min=1), default=1000, show_default=True,
              help="Bootstrap resamples of the intervals.")
@click.option("--seed", type=int, default=0, show_default=True, help="Bootstrap seed.")
@click.option("--out", "out_dir", default="marker-set", show_default=True,
              type=click.Path(file_okay=False),
              help="Folder for marker_set.json (the set, for `facemotion reconstruct`), "
                   "marker_set.tsv, marker_set.png and marker_set_protocol.txt.")
@FORMAT
@UNITS
@_output_forms
def design(files, head, target_mm, k, force, exclude, drop, symmetric, subjects, label_map,
           resamples, seed, out_dir, fmt, units, as_json, as_tsv) -> None:
    """Recommend k markers to place, from pilot takes: the fewest that predict the others
    within the target mean held-out error (or a given k), with the expected error of every
    marker and a bootstrap interval, and the gap to greedy and exhaustive selection.

    FILES are the pilot takes (one sentence each). The set is chosen by cross-validation over
    the takes (docs/design.md). Writes the set and its coefficients, a TSV, a figure and a
    protocol text to --out; prints the set (text, --json or --tsv).
    """
    from facemotion.regions.marker_set import design as run_design
    from facemotion.regions.marker_set import read_label_map, write_outputs

    if subjects and len(subjects) != len(files):
        raise click.BadParameter(f"{len(subjects)} subjects for {len(files)} files",
                                 param_hint="--subject")
    options = {"units": units} if units else {}
    ms = run_design(list(files), head_markers=head, drop_markers=drop, target_mm=target_mm,
                    k=k, force=force, exclude=exclude, symmetric=symmetric,
                    subjects=list(subjects) or None,
                    label_map=read_label_map(label_map) if label_map else None, fmt=fmt,
                    resamples=resamples, seed=seed, progress=True, **options)
    written = write_outputs(ms, out_dir)
    click.echo("facemotion: wrote " + ", ".join(str(p) for p in written), err=True)
    _emit(_finite(ms.to_dict()) if as_json else None,
          ms.per_marker if as_tsv else None, ms.describe())


@cli.command()
@click.argument("marker_set", type=click.Path(dir_okay=False))
@click.argument("files", nargs=-1, required=True, type=click.Path(dir_okay=False))
@click.option("--out", "out_dir", default="reconstructed", show_default=True,
              type=click.Path(file_okay=False), help="Folder for the reconstructed takes.")
@click.option("--to", "to", type=click.Choice(["c3d", "trc"]), default="c3d",
              show_default=True, help="Format of the written takes.")
@click.option("--predict-all", is_flag=True,
              help="Predict every marker that is not placed, even where a take measured it "
                   "(to compare the prediction with the measurement). Default: measured "
                   "samples are kept and only missing ones predicted.")
@FORMAT
@UNITS
def reconstruct(marker_set, files, out_dir, to, predict_all, fmt, units) -> None:
    """Predict every marker of a saved set (MARKER_SET, from `facemotion design`) in new takes
    that hold its placed and head markers, and write them as C3D or TRC with the predicted
    samples flagged (C3D residual 0; the roles and counts in <file>.reconstructed.tsv).
    """
    from facemotion.io.registry import read_recording
    from facemotion.regions.design import MarkerSetDesign
    from facemotion.regions.marker_set import reconstruct as run
    from facemotion.regions.marker_set import write_reconstruction

    ms = MarkerSetDesign.load(marker_set)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    for f in files:
        rec = run(read_recording(f, fmt, units=units), ms, keep_measured=not predict_all)
        paths = write_reconstruction(out / (Path(f).stem + "." + to), rec, ms)
        n = int(rec.filled.sum())
        click.echo(f"{f}: {n} sample(s) of {len(ms.predicted)} predicted marker(s) "
                   f"reconstructed -> {paths[0]}")


def main(argv: list[str] | None = None) -> None:
    """Entry point of the ``facemotion`` command (one-line errors, non-zero exit status)."""
    args = sys.argv[1:] if argv is None else list(argv)
    if not args:  # a bare `facemotion` is a request for help, not a usage error
        click.echo(cli.get_help(click.Context(cli, info_name="facemotion")))
        sys.exit(0)
    try:
        status = cli.main(args=argv, prog_name="facemotion", standalone_mode=False)
    except click.exceptions.Exit as e:
        sys.exit(e.exit_code)
    except click.Abort:
        click.echo("facemotion: aborted", err=True)
        sys.exit(130)
    except click.ClickException as e:
        hint = ""
        if isinstance(e, click.UsageError) and e.ctx is not None:
            hint = f" (see '{e.ctx.command_path} --help')"
        click.echo(f"facemotion: error: {e.format_message()}{hint}", err=True)
        sys.exit(e.exit_code)
    except InputError as e:
        click.echo(f"facemotion: error: {e}", err=True)
        sys.exit(1)
    if isinstance(status, int) and status:
        sys.exit(status)


if __name__ == "__main__":
    main()
