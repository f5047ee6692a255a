"""One marker's trajectory in a held-out sentence, measured and predicted from the k main
markers (Lucero & Munhall 2008, Sec. V, Fig. 9).

The paper draws marker 56 (the jaw), a secondary marker of the basis of ten, in held-out
sentence 31. A dataset without the requested marker (or a run that requests none) draws the
secondary marker that moves most in the sentence instead, and says so in the log, the table
and the figure; a main marker is drawn too, but the model copies it (zero error), which the
log and the figure say.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from facemotion.errors import InputError
from facemotion.regions.prediction import predict

if TYPE_CHECKING:
    from facemotion.ingest.displacements import Displacements
    from facemotion.ranking.result import MarkerRanking

log = logging.getLogger("facemotion")


@dataclass
class HeldoutTrajectory:
    """A marker's x, y, z displacement (F, 3) mm over one held-out sentence, measured and
    predicted; ``requested`` is the marker asked for (None: none was)."""

    marker: str
    requested: str | None
    sentence: str
    k: int
    in_basis: bool
    time_s: np.ndarray
    measured: np.ndarray
    model: np.ndarray

    def table(self) -> pd.DataFrame:
        """The largest |measured - model| per axis (``trajectory_errors.tsv``)."""
        errs = np.abs(self.measured - self.model).max(axis=0)
        return pd.DataFrame({"marker": self.marker, "requested_marker": self.requested or "",
                             "sentence": self.sentence, "k": self.k, "in_basis": self.in_basis,
                             "axis": ["x", "y", "z"], "max_abs_error_mm": errs})

    @property
    def note(self) -> str | None:
        """Why another marker than the requested one is drawn (None when it is the one)."""
        if self.requested == self.marker:
            return None
        if self.requested:
            return f"marker {self.requested} requested, not in this dataset"
        return "no marker requested: the secondary marker that moves most"


def trajectory_marker(one: Displacements, main_markers: list[str], requested: str | None
                      ) -> str:
    """``requested`` if the sentence ``one`` has it; otherwise the secondary marker that moves
    most in it (sum of squared displacements; ties: the later label), with a warning."""
    if requested is not None and requested in one.labels:
        return requested
    secondary = [m for m in one.labels if m not in main_markers]
    motion = {m: float(np.sum(one.A[:, one.labels.index(m)] ** 2)) for m in secondary}
    marker = max(secondary, key=lambda m: (motion[m], m))
    log.warning("eval.trajectory_marker %r %s: drawing %s, the secondary marker that moves "
                "most in %s", requested,
                "not set" if requested is None else "is not in this dataset", marker,
                one.sentences[0])
    return marker


def heldout_trajectory(ranking: MarkerRanking, k: int, held: Displacements,
                       sentence: int | None = None, requested: str | None = None, *,
                       sentence_number: int | None = None) -> HeldoutTrajectory:
    """The trajectory (Fig. 9) of the marker ``requested`` (or the one
    :func:`trajectory_marker` chooses) in held-out sentence ``sentence_number`` (counting from
    1, as the setting eval.trajectory_sentence does; default the first), predicted from the
    first k pivots of ``ranking``.  ``sentence`` (counting from 0) is deprecated and is removed
    in 0.3."""
    index = _sentence_index(sentence, sentence_number, len(held.sentences))
    main_markers = ranking.labels_in_order[:k]
    one = held.subset([index])
    marker = trajectory_marker(one, main_markers, requested)
    in_basis = marker in main_markers
    if in_basis:
        log.warning("trajectory marker %s is one of the %d main markers (pivot %d): the model "
                    "copies it and its error is zero; the figure says so", marker, k,
                    main_markers.index(marker) + 1)
    else:
        log.info("trajectory marker %s is a secondary marker at k = %d", marker, k)
    pred = predict(ranking, k, one.A)
    j = one.labels.index(marker)
    measured = one.A[:, j].reshape(-1, 3)
    return HeldoutTrajectory(marker, requested, one.sentences[0], k, in_basis,
                             np.arange(measured.shape[0]) / one.rate, measured,
                             pred[:, j].reshape(-1, 3))


def _sentence_index(old: int | None, number: int | None, n: int) -> int:
    """The 0-based index of held-out sentence ``number`` (from 1) or of the deprecated
    ``old`` (from 0), checked against the ``n`` held-out sentences."""
    if old is not None:
        if number is not None:
            raise InputError("sentence / sentence_number: give one of them (sentence_number "
                             "counts from 1)")
        import warnings

        warnings.warn("heldout_trajectory(sentence=...) counts held-out sentences from 0 and "
                      "is deprecated (removed in 0.3); use sentence_number=..., counting from "
                      "1 as eval.trajectory_sentence does", DeprecationWarning, stacklevel=3)
        index, name, first = int(old), "sentence", 0
    else:
        index, name, first = (1 if number is None else int(number)) - 1, "sentence_number", 1
    if not 0 <= index < n:
        raise InputError(f"{name}: held-out sentence {index + first} out of range for {n} "
                         f"held-out sentence(s) (counting from {first})")
    return index
