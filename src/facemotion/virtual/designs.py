"""The virtual subjects' designs, listed once: the sheet's ``simulate`` values.

Each design says how many sentences a subject of it reads by default, which talker reads
them, which formats it is written in, and what its sheet row asks of the loading path. The
subject sheet's schema, the sheet reader, the virtual-talker sweep and the simulators all read
this table.
"""

from __future__ import annotations

from dataclasses import dataclass

from facemotion.errors import InputError, token

#: The virtual talkers' head-band markers (rigid with the head, round the forehead and temples).
HEAD_LABELS: tuple[str, ...] = tuple(f"H{i}" for i in range(1, 7))


@dataclass(frozen=True)
class Design:
    """One design of virtual subject."""

    name: str
    description: str
    sentences: int | None      # sentences by default; None: the sheet's n_sentences
    talker: int                # the talker (talker_seed) when the sheet gives none
    formats: tuple[tuple[str, str], ...]  # (sheet format, file suffix) it is written in
    rng_stream: int | None     # the talker design's own random stream (fixed by design)
    copy_markers: tuple[tuple[str, str], ...] = ()  # the sheet's default copy_markers
    vertices: int | None = None  # dense designs: tracked points of the face mesh

    @property
    def dense(self) -> bool:
        return self.vertices is not None

    @property
    def format_names(self) -> tuple[str, ...]:
        return tuple(f for f, _ in self.formats)

    def suffix(self, fmt: str) -> str:
        return dict(self.formats)[fmt]


_C3D = (("c3d", "c3d"),)
_DENSE = (("trc", "trc"), ("c3d", "c3d"), ("openface_csv", "csv"))

DESIGNS: dict[str, Design] = {d.name: d for d in (
    Design("S1", "Lucero & Munhall's S1: 40 sentences; marker 13 tracked only in each "
           "sentence's first frame and filled by copying 11", 40, 1, _C3D, 1,
           copy_markers=(("13", "11"),)),
    Design("S2a", "S2, first session: 50 sentences", 50, 2, _C3D, 2),
    Design("S2b", "S2, second session: the same 50 sentences recorded again, markers "
           "re-placed", 50, 2, _C3D, 3),
    Design("S", "a clean subject of n_sentences sentences", None, 0, _C3D, 4),
    Design("D468", "the dense talker at MediaPipe's 468 face-mesh vertices (n_sentences from "
           "the sheet)", None, 2, _DENSE, None, vertices=468),
    Design("D5023", "the dense talker at 5,023 points of the subdivided face mesh "
           "(n_sentences from the sheet)", None, 2, _DENSE, None, vertices=5023),
)}
DESIGN_NAMES: tuple[str, ...] = tuple(DESIGNS)
#: The designs of the 57-marker talker (virtual.talker); the others are dense.
TALKER_DESIGNS: tuple[str, ...] = tuple(d for d in DESIGNS if not DESIGNS[d].dense)
DENSE_DESIGNS: tuple[str, ...] = tuple(d for d in DESIGNS if DESIGNS[d].dense)


def get_design(name: str, where: str = "design") -> Design:
    """The design named ``name``; InputError naming ``where`` otherwise."""
    if name not in DESIGNS:
        raise InputError(f"{where}: unknown design {token(name)} (one of "
                         f"{', '.join(DESIGN_NAMES)})")
    return DESIGNS[name]
