"""A marker set from files to files: design from pilot takes, outputs a lab keeps, and the
reconstruction of new takes recorded with the reduced set.

* :func:`design` (``facemotion.design``): load pilot takes as the study does
  (:func:`facemotion.load`), the head markers removed from the analysis (they are placed anyway,
  to remove the head motion), and :func:`~facemotion.regions.design.design_markers`.  The rest
  pose saved with the set is the first pilot take's first frame with every marker present, in
  that frame's head position (``head_reference``).
* :func:`write_outputs`: the saved set (JSON), a TSV per marker, a figure of the set on the
  face and a protocol text.
* :func:`reconstruct`: a new take with the placed (and head) markers -> every marker of the
  set.  Head motion is removed against the design's ``head_reference``; the placed markers'
  displacements from the take's first frame (the study's ``first_frame`` neutral) predict the
  others' displacements, A_s = A_m X (Lucero & Munhall 2008, Sec. II.D), added to their rest
  positions; the result is moved back into the take's own (lab) coordinates frame by frame.
  Predicted samples are flagged (``Recording.filled``); a marker present in the take keeps its
  measured samples and only its missing ones are predicted.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.io.recording import Recording, finite_samples
from facemotion.regions.design import MarkerSetDesign, design_markers


def _rest_pose(path: str, fmt: str | None, head: list[str], labels: list[str],
               units: str | None) -> tuple[np.ndarray, np.ndarray]:
    """The head markers' and the analysed markers' positions in the first frame of ``path``
    where all of them are present (mm, that take's coordinates)."""
    from facemotion.io.registry import read_recording

    rec = read_recording(path, fmt, units=units)
    idx = [rec.index(m) for m in head + labels]
    ok = np.flatnonzero(finite_samples(rec.points[:, idx]).all(axis=1))
    if ok.size == 0:
        raise InputError(f"{path}: no frame has every head and analysed marker present, "
                         "needed for the rest pose of the marker set")
    pts = rec.points[ok[0]]
    return pts[idx[:len(head)]], pts[idx[len(head):]]


def read_label_map(path) -> dict[str, dict[str, str]]:
    """A label-mapping table (TSV with columns subject, label, common): for each subject, its
    own marker labels -> the common names the subjects are pooled under."""
    from facemotion.errors import MissingFileError

    p = Path(path)
    if not p.is_file():
        raise MissingFileError(f"{p}: label map not found")
    table = pd.read_csv(p, sep="\t", dtype=str, keep_default_na=False)
    missing = [c for c in ("subject", "label", "common") if c not in table.columns]
    if missing:
        raise InputError(f"{p}: label map lacks column(s) {', '.join(missing)} (needs "
                         "subject, label, common)")
    out: dict[str, dict[str, str]] = {}
    for i, row in enumerate(table.itertuples(index=False), start=2):
        m = out.setdefault(row.subject, {})
        if row.label in m:
            raise InputError(f"{p}: line {i}: subject {row.subject!r} maps {row.label!r} twice")
        if row.common in m.values():
            raise InputError(f"{p}: line {i}: subject {row.subject!r} maps two labels to "
                             f"{row.common!r}")
        m[row.label] = row.common
    return out


def _pooled(paths, subjects, label_map, head, drop, fmt, progress, options):
    """Each subject's takes loaded under its own labels, renamed to the common ones, and
    stacked on the markers every subject has: (Displacements, groups, first subject's head
    markers and markers in its own names, markers left out)."""
    from facemotion.ingest.loading import load
    from facemotion.regions.consensus import pool_subjects

    if subjects is None or len(subjects) != len(paths):
        raise InputError("label map: needs each take's subject (subjects=, one per take)")
    parts = []
    for sub in dict.fromkeys(subjects):
        own = label_map.get(sub, {})
        back = {c: lab for lab, c in own.items()}
        h = [back.get(m, m) for m in head]
        d = load([p for p, s in zip(paths, subjects, strict=True) if s == sub], fmt=fmt,
                 head_markers=h, exclude_markers=list(dict.fromkeys(
                     h + [back.get(m, m) for m in drop])), progress=progress,
                 **options).displacements
        parts.append((sub, d, [own.get(m, m) for m in d.labels], h))
    d, groups, cols0, left_out = pool_subjects([p[:3] for p in parts])
    first_own = [parts[0][1].labels[j] for j in cols0]
    return d, groups, parts[0][3], first_own, left_out


def design(paths, *, head_markers=(), drop_markers=(), target_mm: float = 1.0,
           k: int | None = None, force=(), exclude=(), symmetric: bool = False,
           subjects=None, label_map: dict | None = None, fmt: str | None = None,
           resamples: int = 1000, level: float = 0.95, seed: int = 0,
           progress: bool = False, **options) -> MarkerSetDesign:
    """Recommend a marker set from pilot takes (``facemotion.design``).

    paths: the pilot takes (one sentence each); head_markers: >= 3 markers that move with the
    head only (removed as rigid motion, placed in every take, never part of k); drop_markers:
    markers left out altogether; subjects: each take's subject, when the takes come from
    several (resampled too in the interval); label_map: {subject: {its label: common name}}
    (:func:`read_label_map`) for subjects recorded with differently named markers: each
    subject is loaded under its own names and the subjects are pooled on the common names
    every one of them has (marker lists here are in common names); target_mm, k, force,
    exclude, symmetric,
    resamples, level, seed: :func:`~facemotion.regions.design.design_markers`; progress:
    bars on stderr while the takes are read and over the cross-validation (on a terminal);
    options: the loading settings of :func:`facemotion.load` (units, max_interp_s,
    long_gaps, neutral).
    """
    from facemotion.ingest.loading import load

    paths = [str(paths)] if isinstance(paths, str | Path) else [str(p) for p in paths]
    head = [str(h) for h in head_markers]
    if head and len(head) < 3:
        raise InputError(f"head markers: {len(head)} given ({', '.join(head)}); at least 3")
    drop = [str(m) for m in drop_markers]
    left_out: list[str] = []
    if label_map:
        disp, groups, head0, own0, left_out = _pooled(paths, subjects, label_map, head, drop,
                                                      fmt, progress, options)
    else:
        disp = load(paths, fmt=fmt, head_markers=head,
                    exclude_markers=list(dict.fromkeys(head + drop)), progress=progress,
                    **options).displacements
        groups, head0, own0 = subjects, head, None
    out = design_markers(disp, target_mm=target_mm, k=k, force=force, exclude=exclude,
                         symmetric=symmetric, groups=groups, resamples=resamples,
                         level=level, seed=seed, progress=progress)
    ref, rest = _rest_pose(paths[0], fmt, head0, own0 or out.labels, options.get("units"))
    out.head_markers, out.head_reference, out.neutral = head, ref if head else None, rest
    if left_out:
        out.settings["not_in_every_subject"] = left_out
    out.settings.update(takes=[Path(p).name for p in paths], drop=[str(m) for m in drop_markers],
                        loading={k: v for k, v in options.items()})
    return out


def _lab_frame(points: np.ndarray, R: np.ndarray, t: np.ndarray) -> np.ndarray:
    """Head-frame points (F, m, 3) back to the take's coordinates: lab = (head - t) R."""
    return np.matmul(points - t[:, None, :], R)


def reconstruct(rec: Recording, marker_set: MarkerSetDesign, keep_measured: bool = True
                ) -> Recording:
    """Every marker of ``marker_set`` (and its head markers) in the take ``rec``, which holds at
    least the placed and the head markers (module notes).  Predicted samples are flagged in
    ``filled``; frames where a placed marker is missing stay missing for the predicted ones.
    keep_measured: a predicted marker present in ``rec`` keeps its measured samples (only its
    missing ones are predicted); False predicts all of them (to compare with the measured)."""
    from facemotion.ingest.head_motion import align_head_transforms

    ms = marker_set
    src = rec.source or "recording"
    lacking = [m for m in ms.head_markers + ms.selected if m not in rec.labels]
    if lacking:
        raise InputError(f"{src}: lacks marker(s) {', '.join(lacking)} of the marker set "
                         f"(placed: {', '.join(ms.selected)}; head: {', '.join(ms.head_markers)})")
    if not ms.head_markers or ms.head_reference is None or ms.neutral is None:
        raise InputError("marker set: made without head markers; reconstruction needs them to "
                         "bring a new take into the set's head frame")
    aligned, _, R, t = align_head_transforms(rec, ms.head_markers, ms.head_reference)
    main = aligned.points[:, [rec.index(m) for m in ms.selected]]          # (F, k, 3)
    first = np.flatnonzero(finite_samples(main).all(axis=1))
    if first.size == 0:
        raise InputError(f"{src}: no frame has all placed markers {', '.join(ms.selected)}")
    d_main = main - main[first[0]]
    sec = list(ms.coef.columns)
    # A_s = A_m X with the rows of A being (frame, axis): per axis, (F, k) @ (k, n - k)
    d_sec = np.einsum("fkc,ks->fsc", d_main, ms.coef.loc[ms.selected, sec].to_numpy())
    rest = ms.neutral[[ms.labels.index(m) for m in sec]]
    pred = _lab_frame(rest[None] + d_sec, R, t)                              # (F, n - k, 3)
    labels = ms.head_markers + ms.labels
    out = np.full((rec.n_frames, len(labels), 3), np.nan)
    flag = np.zeros((rec.n_frames, len(labels)), dtype=bool)
    for j, m in enumerate(labels):
        present = m in rec.labels and (keep_measured or m not in sec)
        measured = rec.points[:, rec.index(m)] if present else out[:, j]
        out[:, j] = measured
        if m in sec:
            gap = ~finite_samples(measured)
            p = pred[:, sec.index(m)]
            fill = gap & finite_samples(p)
            out[fill, j] = p[fill]
            flag[fill, j] = True
    return Recording(labels, out, rec.rate, rec.source, flag, rec.units, rec.units_source)


def reconstruction_table(rec: Recording, marker_set: MarkerSetDesign) -> pd.DataFrame:
    """One row per marker of a reconstructed take: its role and how many samples were
    reconstructed (the flag a TRC file cannot carry; written beside it)."""
    placed = set(marker_set.selected)
    head = set(marker_set.head_markers)
    roles = ["head" if m in head else "placed" if m in placed else "predicted"
             for m in rec.labels]
    return pd.DataFrame({"marker": rec.labels, "role": roles,
                         "reconstructed_frames": rec.filled.sum(axis=0).astype(int),
                         "frames": rec.n_frames})


def protocol_text(ms: MarkerSetDesign) -> str:
    """A short paragraph a lab can paste into its protocol (numbers from the design)."""
    pct = f"{ms.level:.0%}"
    if not ms.settings.get("target_mm"):
        how = "a number chosen in advance"
    elif ms.settings.get("target_reached") is False:
        how = (f"no number of markers reached the target of {ms.settings['target_mm']:g} mm "
               "mean held-out error; this is the largest number evaluated")
    else:
        how = (f"the smallest number whose expected mean held-out error is at most "
               f"{ms.settings['target_mm']:g} mm")
    head = (f" Head markers {', '.join(ms.head_markers)} are placed too, to remove the head "
            "motion." if ms.head_markers else "")
    method = ms.candidates.loc[ms.candidates["recommended"], "method"].iloc[0]
    return (
        f"Marker set. {ms.k} facial markers are placed ({', '.join(ms.selected)}); {how}.{head} "
        f"The positions of the {len(ms.predicted)} other markers of the pilot set "
        f"({len(ms.labels)} in all) are predicted from the placed markers' displacements by "
        "linear regression, A_s = A_m X (Lucero & Munhall 2008, J. Acoust. Soc. Am. 124:2283, "
        f"Sec. II.D), with X fitted on {len(ms.sentences)} pilot sentences"
        + (f" of {len(ms.subjects)} subjects" if ms.subjects else "") +
        f". The set was chosen by {method} selection among the candidates of facemotion's "
        f"design (QR with column pivoting, greedy and, where feasible, exhaustive search), by "
        f"{ms.settings['folds']}-fold cross-validation over sentences. Expected mean 3-D "
        f"prediction error: {ms.expected_error_mm:.2f} mm ({pct} bootstrap interval "
        f"{ms.error_low_mm:.2f}-{ms.error_high_mm:.2f} mm, {ms.settings['resampled']} "
        f"resampled, {ms.settings['resamples']} resamples{_reselected(ms.settings)}, seed "
        f"{ms.settings['seed']}).\n")


def _reselected(settings: dict) -> str:
    """How many resamples chose the set again, when not all of them (designs saved before
    the setting existed chose it in all)."""
    n = settings.get("selection_resamples", settings["resamples"])
    return "" if n == settings["resamples"] else f", the set chosen again in {n} of them"


def write_outputs(ms: MarkerSetDesign, out_dir, stem: str = "marker_set") -> list[Path]:
    """Write ``<stem>.json`` (the set, docs/design.md), ``<stem>.tsv`` (one row per marker),
    ``<stem>.png`` (the set on the face) and ``<stem>_protocol.txt``; returns the paths."""
    from facemotion.io.atomic import atomic_path, atomic_write_bytes
    from facemotion.plots.marker_set import plot_design
    from facemotion.plots.save import figure_bytes

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = [out / f"{stem}.json", out / f"{stem}.tsv", out / f"{stem}.png",
             out / f"{stem}_protocol.txt"]
    ms.save(paths[0])
    with atomic_path(paths[1]) as tmp:
        ms.per_marker.to_csv(tmp, sep="\t", index=False, float_format="%.6g",
                             lineterminator="\n")
    if ms.neutral is not None:
        fig = plot_design(ms)
        atomic_write_bytes(paths[2], figure_bytes(fig, "png"))
    else:
        paths.remove(paths[2])
    with atomic_path(paths[-1]) as tmp:
        tmp.write_text(protocol_text(ms), encoding="utf-8")
    return paths


def write_reconstruction(path, rec: Recording, ms: MarkerSetDesign) -> list[Path]:
    """Write a reconstructed take as C3D (reconstructed samples with residual 0, the C3D mark
    of computed samples, and each marker's role in POINT:DESCRIPTIONS) or TRC, by suffix, and
    beside it ``<path>.reconstructed.tsv`` (:func:`reconstruction_table`)."""
    from facemotion.io.atomic import atomic_path

    p = Path(path)
    table = reconstruction_table(rec, ms)
    if p.suffix.lower() == ".c3d":
        from facemotion.io.c3d import write_c3d

        desc = [f"{r}; {n} sample(s) reconstructed by facemotion" if n else r
                for r, n in zip(table["role"], table["reconstructed_frames"], strict=True)]
        write_c3d(p, rec, flag_filled=True, descriptions=desc)
    elif p.suffix.lower() == ".trc":
        from facemotion.io.trc import write_trc

        write_trc(p, rec)
    else:
        raise InputError(f"{p}: reconstructed takes are written as .c3d or .trc")
    side = p.with_name(p.name + ".reconstructed.tsv")
    with atomic_path(side) as tmp:
        table.to_csv(tmp, sep="\t", index=False, lineterminator="\n")
    return [p, side]
