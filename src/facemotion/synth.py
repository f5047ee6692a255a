"""The virtual talker: built-in subjects that resemble the recordings of Lucero & Munhall (2008).

57 numbered facial markers ('1'..'57', keeping the paper's numbers for the markers it names:
2 right eyebrow, 6 left eyebrow, 11 right upper eyelid, 13 left upper eyelid, 34 left lip
corner, 36 upper-lip centre, 38 right lip corner, 40 lower-lip centre, 56 jaw/chin) and six
head-band markers ('H1'..'H6'). Head axes as in the paper: x from the talker's right to left,
y up, z forward; millimetres; 120 Hz.

Motion (in head coordinates) is a sum of articulatory sources, each a time course at speech
rates times a smooth 3-D influence field over the face (Gaussian lobes, some negative):

    p_j(t) = n_j + sum_k s_k(t) D_k(n_j) + l_j(t)                        (face marker j)

where l_j is a small marker-specific smooth skin motion (independent of everything else, so
that every clean marker keeps an independent component above the 0.5 mm tolerance). Then a
smooth rigid head motion of a few degrees and millimetres moves everything, and measurement
noise is added: isotropic Gaussian, 0.5 mm 3-D RMS (0.5/sqrt(3) = 0.29 mm per coordinate).

Designs: S1 (40 sentences; marker 13 missing in most of the recording and filled, as the
paper's authors did, by copying marker 11: in head coordinates the displacement of 13 from its
neutral position equals 11's measured displacement, before the head motion is applied),
S2a and S2b (50 sentences each: the same talker in two sessions, different sentences, marker
placement differing by a few mm), and S (a clean subject of any size). Everything is
deterministic by seed; the ground truth is returned beside the recordings.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import gaussian_filter1d
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.recording import Recording

DESIGNS = {"S1": 40, "S2a": 50, "S2b": 50, "S": None}
HEAD_LABELS = [f"H{i}" for i in range(1, 7)]
NOISE_3D_RMS_MM = 0.5
NOISE_PER_AXIS_MM = NOISE_3D_RMS_MM / np.sqrt(3.0)

# Marker template (x, y) in mm on a face ~140 mm wide and ~200 mm tall; origin near the
# mouth; x from the talker's right (negative) to left (positive).
_TEMPLATE = {
    1: (-50, 55), 2: (-32, 61), 3: (-14, 57), 4: (0, 72), 5: (14, 57), 6: (32, 61),
    7: (50, 55), 8: (-30, 82), 9: (30, 82), 10: (-50, 36), 11: (-32, 42), 12: (0, 36),
    13: (32, 42), 14: (50, 36), 15: (-32, 29), 16: (32, 29), 17: (0, 10), 18: (-14, 3),
    19: (14, 3), 20: (-60, 16), 21: (-42, 11), 22: (42, 11), 23: (60, 16), 24: (-62, -9),
    25: (-45, -7), 26: (-28, -4), 27: (28, -4), 28: (45, -7), 29: (62, -9), 30: (-11, -6),
    31: (11, -6), 32: (-38, -23), 33: (38, -23), 34: (25, -22), 35: (13, -16), 36: (0, -15),
    37: (-13, -16), 38: (-25, -22), 39: (-13, -28), 40: (0, -30), 41: (13, -28),
    42: (-20, -42), 43: (0, -45), 44: (20, -42), 45: (-58, -31), 46: (-48, -46),
    47: (48, -46), 48: (58, -31), 49: (-45, -63), 50: (-28, -71), 51: (-12, -61),
    52: (12, -61), 53: (28, -71), 54: (45, -63), 55: (-14, -81), 56: (0, -86), 57: (14, -81),
}
_HEAD_BAND = np.array([[-72, 72, -25], [-45, 96, 18], [0, 104, 32], [45, 96, 18],
                       [72, 72, -25], [0, 92, -70]], float)
REGIONS = {
    "forehead": ["4", "8", "9"], "brows": ["1", "2", "3", "5", "6", "7"],
    "eyelids": ["10", "11", "12", "13", "14", "15", "16"], "nose": ["17", "18", "19"],
    "cheeks": [str(i) for i in range(20, 34)] + ["45", "46", "47", "48"],
    "lips": [str(i) for i in range(34, 42)],
    "chin_jaw": [str(i) for i in range(42, 45)] + [str(i) for i in range(49, 58)],
}
SOURCES = ("jaw_open", "lip_protrusion", "left_corner_retraction", "right_corner_retraction",
           "upper_lip_raise", "lower_lip_depression", "left_brow_raise", "right_brow_raise",
           "left_blink", "right_blink", "cheek_raise")


def _surface_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A curved face: rounded cheeks, a nose, protruding lips and chin."""
    z = 70.0 - 0.010 * x**2 - 0.0015 * (y + 10) ** 2
    z += 22.0 * np.exp(-(x**2 + (y - 8) ** 2) / 180.0)             # nose
    z += 6.0 * np.exp(-(x**2 / 500.0 + (y + 22) ** 2 / 120.0))     # lips
    z += 4.0 * np.exp(-(x**2 / 300.0 + (y + 80) ** 2 / 150.0))     # chin
    return z


@dataclass
class Talker:
    """A virtual talker: face geometry and source strengths (deterministic by talker seed)."""

    labels: list[str]
    neutral: np.ndarray            # (57, 3) face markers, head coordinates, mm
    head_band: np.ndarray          # (6, 3)
    strengths: np.ndarray          # (K,) source amplitude multipliers
    local_rms_mm: float = 0.45     # per-axis RMS of the marker-specific skin motion


def make_talker(talker_seed: int = 0, placement_jitter_mm: float = 0.0,
                placement_seed: int | None = None) -> Talker:
    rng = np.random.default_rng([talker_seed, 7])
    sx, sy = rng.uniform(0.9, 1.1, 2)
    xy = np.array([_TEMPLATE[i] for i in range(1, 58)], float)
    xy *= [sx, sy]
    xy += rng.normal(0.0, 1.5, xy.shape)         # the talker's own (asymmetric) placement
    if placement_jitter_mm:
        prng = np.random.default_rng([talker_seed, 11, placement_seed or 0])
        xy += prng.normal(0.0, placement_jitter_mm, xy.shape)
    neutral = np.column_stack([xy, _surface_z(xy[:, 0], xy[:, 1])])
    strengths = rng.uniform(0.75, 1.25, len(SOURCES))
    return Talker([str(i) for i in range(1, 58)], neutral, _HEAD_BAND * [sx, sy, 1.0],
                  strengths)


def marker_layout(talker_seed: int = 0) -> tuple[list[str], np.ndarray, dict]:
    """Labels, neutral positions (57, 3) in head coordinates and named face regions."""
    t = make_talker(talker_seed)
    return t.labels, t.neutral, REGIONS


def _lobe(p: np.ndarray, cx: float, cy: float, sx: float, sy: float | None = None) -> np.ndarray:
    sy = sx if sy is None else sy
    return np.exp(-((p[:, 0] - cx) ** 2) / (2 * sx**2) - ((p[:, 1] - cy) ** 2) / (2 * sy**2))


def influence_fields(neutral: np.ndarray) -> np.ndarray:
    """D (K, n, 3): the displacement of every marker per unit of each source (mm)."""
    p = neutral
    x, y = p[:, 0], p[:, 1]
    n = len(p)
    D = np.zeros((len(SOURCES), n, 3))
    # jaw opening: the lower face rotates down and back about the jaw joint (more further
    # below); the skin of the cheeks stretches with it (a broad, weaker pull), while the
    # upper cheeks rise slightly (negative lobe)
    below = 1.0 / (1.0 + np.exp((y + 15.0) / 10.0))
    w = below * (0.85 + 0.15 * np.clip((-30.0 - y) / 55.0, 0.0, 1.0))
    D[0, :, 1] = -10.0 * w - 0.8 * _lobe(p, 0, -30, 8)
    D[0, :, 2] = -3.5 * w
    D[0, :, 1] += 0.8 * _lobe(p, -45, 12, 14) + 0.8 * _lobe(p, 45, 12, 14)
    # lip protrusion: lips and the skin around them forward and towards the midline
    m = _lobe(p, 0, -24, 22, 16)
    D[1, :, 2] = 5.0 * m
    D[1, :, 0] = -2.5 * np.tanh(x / 15.0) * m
    # lip-corner retraction (left, right): the corner outward and up, the cheek with it;
    # the lip centre thins
    for k, side in ((2, 1.0), (3, -1.0)):
        c = _lobe(p, 26 * side, -20, 17, 14)
        D[k, :, 0] = 4.5 * side * c
        D[k, :, 1] = 2.2 * c
        D[k, :, 2] = -1.2 * c - 0.8 * _lobe(p, 0, -22, 9)
    # upper-lip raise (with the nostrils and the nasolabial folds), lower-lip depression
    # (everting, pulling the skin below it)
    D[4, :, 1] = 3.5 * _lobe(p, 0, -14, 14, 8) + 1.2 * _lobe(p, 0, 0, 22, 10)
    D[4, :, 2] = 0.8 * _lobe(p, 0, -14, 14, 8)
    D[5, :, 1] = -3.5 * _lobe(p, 0, -32, 14, 10)
    D[5, :, 2] = 1.5 * _lobe(p, 0, -30, 12, 7) - 0.8 * _lobe(p, 0, -48, 16, 8)
    # brow raises (left, right): brows and forehead up; the upper lid follows a little
    for k, side in ((6, 1.0), (7, -1.0)):
        b = _lobe(p, 30 * side, 64, 24, 16)
        D[k, :, 1] = 4.0 * b + 1.5 * _lobe(p, 26 * side, 84, 26, 12)
        D[k, :, 2] = -0.8 * b
    # blinks (left, right): the upper lid closes; the lower lid rises slightly
    for k, side in ((8, 1.0), (9, -1.0)):
        D[k, :, 1] = -6.0 * _lobe(p, 32 * side, 42, 5) + 1.2 * _lobe(p, 32 * side, 29, 4)
        D[k, :, 2] = 1.0 * _lobe(p, 32 * side, 42, 5)
    # cheek raise (zygomatic, both sides): cheeks up and out, corners up
    for side in (1.0, -1.0):
        c = _lobe(p, 42 * side, 0, 22, 20)
        D[10, :, 0] += 1.5 * side * c
        D[10, :, 1] += 2.5 * c
        D[10, :, 2] += 1.5 * c
    return D


def _bumps(rng, t: np.ndarray, times: np.ndarray, widths: np.ndarray,
           amps: np.ndarray) -> np.ndarray:
    """Sum of raised-cosine bumps centred at ``times``."""
    out = np.zeros_like(t)
    for c, w, a in zip(times, widths, amps, strict=True):
        u = (t - c) / w
        inside = np.abs(u) < 1
        out[inside] += a * 0.5 * (1 + np.cos(np.pi * u[inside]))
    return out


def source_courses(rng: np.random.Generator, n_frames: int, rate: float) -> np.ndarray:
    """s (F, K): source time courses of one sentence, zero at the start (rest)."""
    t = np.arange(n_frames) / rate
    dur = n_frames / rate
    K = len(SOURCES)
    s = np.zeros((n_frames, K))
    # syllables at 4-6 per second, starting after a short rest
    syl_rate = rng.uniform(4.0, 6.0)
    syl = np.arange(0.25, dur - 0.1, 1.0 / syl_rate)
    syl = syl + rng.normal(0, 0.02, syl.size)
    width = 1.0 / syl_rate
    s[:, 0] = _bumps(rng, t, syl, np.full(syl.size, width), rng.uniform(0.3, 1.3, syl.size))
    for k in range(1, 6):  # lip gestures on a random subset of syllables
        pick = rng.random(syl.size) < 0.45
        s[:, k] = _bumps(rng, t, syl[pick] + rng.normal(0, 0.03, pick.sum()),
                         np.full(pick.sum(), width * rng.uniform(0.8, 1.4)),
                         rng.uniform(0.3, 1.2, pick.sum()))
    # brows: one or two slow raises per sentence, left and right mostly together
    n_raise = rng.integers(1, 3)
    times = rng.uniform(0.4, max(0.5, dur - 0.3), n_raise)
    widths = rng.uniform(0.3, 0.6, n_raise)
    amps = rng.uniform(0.4, 1.0, n_raise)
    s[:, 6] = _bumps(rng, t, times, widths, amps * rng.uniform(0.7, 1.0, n_raise))
    s[:, 7] = _bumps(rng, t, times + rng.normal(0, 0.03, n_raise), widths,
                     amps * rng.uniform(0.7, 1.0, n_raise))
    # blinks: 0-2 per sentence, brief, both eyes nearly together
    n_blink = rng.integers(0, 3)
    bt = rng.uniform(0.3, max(0.35, dur - 0.2), n_blink)
    bw = rng.uniform(0.08, 0.13, n_blink)
    s[:, 8] = _bumps(rng, t, bt, bw, rng.uniform(0.8, 1.0, n_blink))
    s[:, 9] = _bumps(rng, t, bt + rng.normal(0, 0.015, n_blink), bw,
                     rng.uniform(0.8, 1.0, n_blink))
    # cheek raise: slow, on a few stressed syllables
    pick = rng.random(syl.size) < 0.25
    s[:, 10] = _bumps(rng, t, syl[pick], np.full(pick.sum(), 2.5 * width),
                      rng.uniform(0.3, 1.0, pick.sum()))
    # smooth onset from rest
    s *= np.clip(t / 0.15, 0, 1)[:, None] ** 2
    return s


def _smooth_noise(rng, shape, rate: float, sigma_s: float, rms: float) -> np.ndarray:
    """Band-limited noise along axis 0 with the given RMS, rising smoothly from zero at the
    start (over 0.15 s), so that every sentence starts at rest."""
    x = gaussian_filter1d(rng.standard_normal(shape), sigma_s * rate, axis=0, mode="reflect")
    x *= rms / max(float(np.sqrt(np.mean(x**2))), 1e-12)
    ramp = np.clip(np.arange(shape[0]) / (0.15 * rate), 0.0, 1.0) ** 2
    return x * ramp.reshape((-1,) + (1,) * (x.ndim - 1))


@dataclass
class SimulatedSubject:
    design: str
    recordings: list[Recording]
    names: list[str]
    head_markers: list[str]
    truth: dict = field(default_factory=dict)


def simulate_subject(design: str, seed: int = 0, n_sentences: int | None = None,
                     talker_seed: int | None = None, rate: float = 120.0,
                     sentence_duration: tuple[float, float] = (1.5, 4.0),
                     head_rotation_deg: float = 2.5, head_translation_mm: float = 3.0,
                     noise_mm: float = NOISE_3D_RMS_MM, fill_fraction: float = 0.92,
                     ) -> SimulatedSubject:
    """Simulate one subject of a design (S1, S2a, S2b or S).

    talker_seed: None uses the design's talker (S1: talker 1; S2a and S2b: talker 2, the same
    person, S2b with markers re-placed by a few mm). fill_fraction: S1 only, the fraction of
    sentences whose marker 13 is filled by copying marker 11 (plus partial gaps in others).
    """
    if design not in DESIGNS:
        raise InputError(f"virtual subject design {design!r} unknown "
                         f"(use one of {', '.join(DESIGNS)})")
    n = n_sentences if n_sentences is not None else DESIGNS[design]
    if n is None or n < 1:
        raise InputError(f"virtual subject design {design!r}: n_sentences must be >= 1")
    lo, hi = sentence_duration
    if not 0 < lo <= hi:
        raise InputError(f"virtual subject: sentence_duration {sentence_duration} must "
                         "satisfy 0 < low <= high")
    if talker_seed is None:
        talker_seed = 1 if design == "S1" else 2
    talker = make_talker(talker_seed, placement_jitter_mm=2.0 if design == "S2b" else 0.0,
                         placement_seed=1)
    rng = np.random.default_rng([seed, 1 + list(DESIGNS).index(design)])
    D = influence_fields(talker.neutral) * talker.strengths[:, None, None]   # (K, n, 3)
    labels = talker.labels + HEAD_LABELS
    i11, i13 = talker.labels.index("11"), talker.labels.index("13")
    # which S1 sentences have marker 13 filled from 11: whole sentences, plus partial gaps
    fill_whole = np.zeros(n, bool)
    fill_part = np.zeros(n, bool)
    if design == "S1":
        order = rng.permutation(n)
        n_whole = int(round(fill_fraction * n))
        fill_whole[order[:n_whole]] = True
        fill_part[order[n_whole:n_whole + max(1, (n - n_whole) // 2)]] = True
    noise_axis = noise_mm / np.sqrt(3.0)
    pivot = np.array([0.0, -90.0, -80.0])   # the head rotates about the upper neck
    recs, names, truth_s, truth_head, truth_fill = [], [], [], [], []
    for s in range(n):
        F = int(round(rng.uniform(lo, hi) * rate))
        F = max(F, 4)
        courses = source_courses(rng, F, rate)
        local = _smooth_noise(rng, (F, len(talker.neutral), 3), rate, 0.08,
                              talker.local_rms_mm)
        face = talker.neutral + np.einsum("fk,knc->fnc", courses, D) + local
        head = np.broadcast_to(talker.head_band, (F, 6, 3))
        pts = np.concatenate([face, head], axis=1)
        pts = pts + rng.normal(0.0, noise_axis, pts.shape)            # measurement noise
        filled = np.zeros((F, len(labels)), bool)
        if fill_whole[s]:
            filled[:, i13] = True
        elif fill_part[s]:
            g = int(rng.uniform(0.4, 0.8) * F)
            start = int(rng.integers(1, max(2, F - g)))
            filled[start:start + g, i13] = True
        if filled[:, i13].any():
            rows = filled[:, i13]
            # the authors' fill: 13 copies 11's measured displacement from its neutral pose
            pts[rows, i13] = pts[rows, i11] + (talker.neutral[i13] - talker.neutral[i11])
        # rigid head motion (smooth, a few degrees and millimetres), starting at rest pose
        rotvec = np.deg2rad(head_rotation_deg) * _smooth_noise(rng, (F, 3), rate, 0.35, 1.0)
        trans = head_translation_mm * _smooth_noise(rng, (F, 3), rate, 0.35, 1.0)
        R = Rotation.from_rotvec(rotvec)
        moved = np.einsum("fij,fnj->fni", R.as_matrix(), pts - pivot) + pivot + trans[:, None]
        name = f"{design}_s{s + 1:02d}"
        recs.append(Recording(labels, moved, rate, name, filled))
        names.append(name)
        truth_s.append(courses)
        truth_head.append(np.concatenate([rotvec, trans], axis=1))
        truth_fill.append(filled[:, i13])
    truth = {
        "labels": np.array(labels), "neutral": np.concatenate([talker.neutral,
                                                             talker.head_band]),
        "sources": np.array(SOURCES), "fields": D, "strengths": talker.strengths,
        "sentence_frames": np.array([len(c) for c in truth_s]),
        "source_courses": np.concatenate(truth_s), "head_motion": np.concatenate(truth_head),
        "filled_13": np.concatenate(truth_fill), "noise_per_axis_mm": np.array(noise_axis),
        "talker_seed": np.array(talker_seed), "seed": np.array(seed),
    }
    return SimulatedSubject(design, recs, names, list(HEAD_LABELS), truth)


def truth_npz_bytes(subject: SimulatedSubject) -> bytes:
    """The ground truth as deterministic ``.npz`` bytes (written beside the data)."""
    from facemotion.provenance import npz_bytes

    return npz_bytes(subject.truth)
