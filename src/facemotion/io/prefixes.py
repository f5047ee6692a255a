"""Labels of the form "Subject:Marker" and the choice of one subject.

Vicon writes each subject's markers as ``Subject:Marker``; OptiTrack Motive names a marker of an
asset ``Asset:Marker``. A file may hold several subjects. The sheet's ``subject_prefix`` column
picks one: its markers are kept and lose the prefix, the others are left out (with a log line).
Without a choice, a file whose labels all carry the same prefix loses it; a file with several
prefixes is an error listing them. The sheet names markers without the prefix.
"""

from __future__ import annotations

import logging

from facemotion.errors import InputError, token
from facemotion.io.recording import Recording

log = logging.getLogger("facemotion")
NO_PREFIX = "(no prefix)"


def split_label(label: str) -> tuple[str, str]:
    """'Subject:Marker' -> ('Subject', 'Marker'); 'Marker' -> ('', 'Marker')."""
    prefix, sep, name = str(label).partition(":")
    if not sep:
        return "", str(label)
    return prefix.strip(), name.strip()


def prefixes(labels: list[str]) -> list[str]:
    """Distinct prefixes in label order ('' for labels without one)."""
    out: list[str] = []
    for lab in labels:
        p = split_label(lab)[0]
        if p not in out:
            out.append(p)
    return out


def _listing(found: list[str]) -> str:
    return ", ".join(token(p) if p else NO_PREFIX for p in found)


def _subject_like(labels: list[str], found: list[str]) -> bool:
    """Whether several prefixes can be subjects: each a printable name, and fewer of them
    than half the labels (a subject has several markers)."""
    named = [p for p in found if p]
    return (all(p.isprintable() and len(p) <= 64 for p in named)
            and len(found) <= max(2, len(labels) // 2))


def subject_columns(labels: list[str], subject_prefix: str | None,
                    where: str) -> tuple[list[int], list[str], str | None]:
    """Columns of the chosen subject, their labels without the prefix, and the prefix
    (None when the labels have none); see the module docstring."""
    found = prefixes(labels)
    if subject_prefix:
        wanted = str(subject_prefix).strip().rstrip(":")
        if wanted not in found:
            raise InputError(f"{where}: no marker label starts with subject prefix "
                             f"'{wanted}:' (prefixes in the file: {_listing(found)})")
    elif found == [""]:
        return list(range(len(labels))), list(labels), None
    elif len(found) == 1:
        wanted = found[0]
    elif not _subject_like(labels, found):
        raise InputError(f"{where}: the marker labels do not read as 'Subject:Marker' names "
                         f"({len(found)} different texts before ':' among {len(labels)} "
                         "labels, or unprintable ones): the label section looks damaged")
    else:
        raise InputError(f"{where}: labels belong to several subjects (prefixes "
                         f"{_listing(found)}); choose one with the sheet's subject_prefix "
                         "column (--subject-prefix on the command line)")
    keep = [i for i, lab in enumerate(labels) if split_label(lab)[0] == wanted]
    names = [split_label(labels[i])[1] for i in keep]
    empty = [labels[i] for i, n in zip(keep, names, strict=True) if not n]
    if empty:
        raise InputError(f"{where}: label(s) {', '.join(empty[:5])} have nothing after the "
                         "subject prefix")
    return keep, names, wanted


def select_subject(rec: Recording, subject_prefix: str | None = None) -> Recording:
    """Keep one subject's markers, without their prefix (see the module docstring)."""
    where = rec.source or "recording"
    keep, names, wanted = subject_columns(rec.labels, subject_prefix, where)
    if wanted is None:
        return rec
    dropped = [lab for i, lab in enumerate(rec.labels) if i not in set(keep)]
    if dropped:
        log.info("%s: subject '%s': %d markers kept; left out %d labels of other subjects "
                 "(%s%s)", where, wanted, len(keep), len(dropped), ", ".join(dropped[:8]),
                 ", ..." if len(dropped) > 8 else "")
    else:
        log.info("%s: all %d labels carry the subject prefix '%s:', which is removed", where,
                 len(keep), wanted)
    return Recording(names, rec.points[:, keep, :].copy(), rec.rate, rec.source,
                     rec.filled[:, keep].copy(), rec.units, rec.units_source)
