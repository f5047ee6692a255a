"""Fill a marker's missing samples by copying another marker's displacement.

Lucero & Munhall (2008, Sec. II) lost most of subject S1's left upper-eyelid marker (13) and,
since both lids seemed to move alike, copied the missing data from the right upper-lid marker
(11). This is that fill, for any pair the subject sheet names (``copy_markers: 13=11``), done
in head coordinates after the head alignment:

    p_t(f) = p_s(f) + o        for every frame f where the target t is missing and the source s
                               is measured,

where the offset o = p_t - p_s is taken at the first frame of the take where both are measured,
or, in a take where they never are, as the median of p_t - p_s over all frames of all takes
where both are. Within a take the target's displacement from any frame to any other is then
exactly the source's wherever it was filled: a displacement matrix built from these takes has
the target column equal to the source column on those rows, which is what QR with column
pivoting detects as a redundant marker (Fig. 2, Table I). Samples where the source is missing
too stay missing for the ordinary gap filling; every copied sample is flagged in ``filled``.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from facemotion.errors import InputError
from facemotion.io.recording import Recording, finite_samples


def parse_copy_markers(spec, where: str = "copy_markers") -> list[tuple[str, str]]:
    """'13=11, 20=21' (or a list of such items) -> [('13', '11'), ('20', '21')].

    A target may appear once, and no marker may be both a target and a source (no chains).
    """
    if spec is None:
        return []
    items = spec if isinstance(spec, list | tuple) else str(spec).split(",")
    pairs: list[tuple[str, str]] = []
    for item in items:
        item = str(item).strip()
        if not item:
            continue
        target, sep, source = item.partition("=")
        target, source = target.strip(), source.strip()
        if not sep or not target or not source or target == source:
            raise InputError(f"{where}: {item!r} must look like TARGET=SOURCE (two different "
                             "marker labels), e.g. 13=11")
        pairs.append((target, source))
    targets = [t for t, _ in pairs]
    dup = sorted({t for t in targets if targets.count(t) > 1})
    if dup:
        raise InputError(f"{where}: marker(s) {', '.join(dup)} to be filled twice")
    chain = sorted(set(targets) & {s for _, s in pairs})
    if chain:
        raise InputError(f"{where}: marker(s) {', '.join(chain)} both filled and copied from")
    return pairs


def pair_columns(labels: list[str], pairs: list[tuple[str, str]], where: str,
                 source: str | None) -> list[tuple[int, int]]:
    """Each pair's (target, source) columns in ``labels``; a marker not among them is an
    InputError."""
    for t, s in pairs:
        for m in (t, s):
            if m not in labels:
                raise InputError(f"{where}: marker {m!r} (in {t}={s}) is not among the "
                                 f"analysed markers of {source or 'the recording'}")
    return [(labels.index(t), labels.index(s)) for t, s in pairs]


def take_offsets(firsts: list[np.ndarray | None], pooled_median: Callable[[], np.ndarray | None],
                 pair: tuple[str, str], where: str) -> list[np.ndarray]:
    """Each take's offset o = p_t - p_s: its first frame with both measured (``firsts``,
    None where there is none), else the median over all takes (``pooled_median()``, None when
    no frame of any take has both; asked for only when a take needs it)."""
    if all(f is not None for f in firsts):
        return list(firsts)
    median = pooled_median()
    if median is None:
        t, s = pair
        raise InputError(f"{where}: markers {t!r} and {s!r} are never measured in the same "
                         f"frame, so {t!r}'s position relative to {s!r} is unknown")
    return [median if f is None else f for f in firsts]


def copy_rows(points: np.ndarray, jt: int, js: int, offset: np.ndarray) -> np.ndarray:
    """p_t = p_s + o, in place, in the frames of ``points`` (frames, markers, 3) where the
    target (column ``jt``) is missing and the source (``js``) is measured; returns those
    frames (bool)."""
    rows = ~np.isfinite(points[:, jt]).all(axis=1) & np.isfinite(points[:, js]).all(axis=1)
    points[rows, jt] = points[rows, js] + offset
    return rows


def copy_fill(recs: list[Recording], pairs: list[tuple[str, str]],
              where: str = "copy_markers") -> tuple[list[Recording], dict[str, int]]:
    """Fill each target's missing samples from its source (see the module notes).

    recs: head-aligned takes with the same labels. Returns the filled takes (copies) and the
    number of samples copied per target label.
    """
    if not pairs:
        return list(recs), {}
    columns = pair_columns(recs[0].labels, pairs, where, recs[0].source)
    out = [Recording(list(r.labels), r.points.copy(), r.rate, r.source, r.filled.copy())
           for r in recs]
    counts: dict[str, int] = {}
    for (t, s), (jt, js) in zip(pairs, columns, strict=True):
        diffs, firsts = [], []
        for r in recs:
            both = finite_samples(r.points[:, [jt, js]]).all(axis=1)
            d = r.points[both, jt] - r.points[both, js]
            diffs.append(d)
            firsts.append(d[0] if len(d) else None)
        pooled = np.concatenate(diffs)
        offsets = take_offsets(firsts, lambda p=pooled: np.median(p, axis=0) if p.size else None,
                               (t, s), where)
        n = 0
        for r, offset in zip(out, offsets, strict=True):
            rows = copy_rows(r.points, jt, js, offset)
            r.filled[rows, jt] = True
            n += int(rows.sum())
        counts[t] = n
    return out, counts
