"""The measurement noise of a dataset, estimated from its own displacements (beyond the papers).

The papers' epsilon (0.5 mm, Lucero & Munhall Sec. IV) is the marker system's stated accuracy.
A lab's tracker may be much better or much worse, so the study also ranks at a tolerance set by
the noise the data show.  Two estimates, both per coordinate (mm), of what the ranking sees:

* ``high_frequency_mm``: within each sentence, every coordinate's residual after a local cubic
  fit (a Savitzky-Golay smoother over about 50 ms, at least 5 frames).  For white noise of
  standard deviation sigma the residual has variance sigma^2 (1 - h0), h0 the smoother's centre
  weight (the residual of a projection), so sigma = 1.4826 MAD(residual) / sqrt(1 - h0); the
  median absolute deviation keeps fast genuine movements from inflating it.  Filled samples and
  each sentence's first and last half-window are left out.  Speech movement below about 10 Hz
  passes the cubic almost untouched at marker-system rates (tested on the virtual talker with
  and without noise).  A recording smoothed before export shows almost no such residual.
* ``head_fit_mm``: the rigid head fit's residual per coordinate in a typical frame,
  sqrt(median(res^2) / 3) with res each frame's RMS 3-D residual of the head markers (the
  median: a few frames where a head marker is occluded or the skin slides far would dominate a
  mean): how far markers that should move rigidly (the head markers) stray from a rigid motion, i.e.
  measurement error plus skin sliding over the skull.  It survives low-pass filtering.  0 when
  the dataset has no head markers.

``noise_mm`` is the larger of the two: motion below it cannot be told from measurement error.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np
import scipy.signal

#: The smoother's span (s); the window is the odd number of frames nearest to it, at least 5.
WINDOW_S = 0.05
MAD_TO_SIGMA = 1.4826


@dataclass(frozen=True)
class NoiseLevel:
    high_frequency_mm: float
    head_fit_mm: float
    window_frames: int

    @property
    def noise_mm(self) -> float:
        return max(self.high_frequency_mm, self.head_fit_mm)

    @property
    def source(self) -> str:
        return ("high_frequency" if self.high_frequency_mm >= self.head_fit_mm
                else "head_fit")

    def as_dict(self) -> dict:
        return {**asdict(self), "noise_mm": self.noise_mm, "source": self.source}


def window_frames(rate: float) -> int:
    """The smoother's window at ``rate`` Hz: the odd frame count nearest WINDOW_S, >= 5."""
    w = int(round(WINDOW_S * float(rate)))
    w += 1 - w % 2
    return max(5, w)


def high_frequency_noise(points: np.ndarray, frame_sentence: np.ndarray, rate: float,
                         filled: np.ndarray | None = None) -> tuple[float, int]:
    """sigma per coordinate (module notes) of ``points`` (F, n, 3) whose frames belong to the
    sentences ``frame_sentence`` (F,); ``filled`` (F, n) marks samples left out.  Returns
    (sigma, window); NaN when no sentence is longer than the window."""
    w = window_frames(rate)
    h0 = scipy.signal.savgol_coeffs(w, 3)[w // 2]
    half = w // 2
    parts = []
    for s in np.unique(frame_sentence):
        idx = np.flatnonzero(frame_sentence == s)
        if idx.size <= w:
            continue
        Y = points[idx]
        res = (Y - scipy.signal.savgol_filter(Y, w, 3, axis=0))[half:-half]
        keep = np.ones(res.shape[:2], dtype=bool) if filled is None else \
            ~filled[idx][half:-half]
        parts.append(np.abs(res[keep]).ravel())
    if not parts:
        return float("nan"), w
    mad = float(np.median(np.concatenate(parts)))
    return MAD_TO_SIGMA * mad / float(np.sqrt(1.0 - h0)), w


def estimate_noise(d) -> NoiseLevel:
    """Both estimates for a ``Displacements`` (its A, row_sentence, rate, fill_mask and
    head_residual)."""
    F = d.A.shape[0] // 3
    points = d.A.reshape(F, 3, -1).transpose(0, 2, 1)
    hf, w = high_frequency_noise(points, np.asarray(d.row_sentence)[::3], d.rate, d.fill_mask)
    hr = np.asarray(d.head_residual, dtype=float)
    head = float(np.sqrt(np.median(hr ** 2) / 3.0)) if hr.size else 0.0
    return NoiseLevel(high_frequency_mm=hf, head_fit_mm=head, window_frames=w)
