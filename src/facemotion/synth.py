"""The virtual talker: built-in subjects that resemble the recordings of Lucero & Munhall (2008).

57 numbered facial markers ('1'..'57', keeping the paper's numbers for the markers it names:
2 right eyebrow, 6 left eyebrow, 11 right upper eyelid, 13 left upper eyelid, 34 left lip
corner, 36 upper-lip centre, 38 right lip corner, 40 lower-lip centre, 56 jaw/chin) over
forehead, brows, eyelids, nose, cheeks, lips, chin and jaw, and six head-band markers
('H1'..'H6', rigid with the head, round the forehead and temples). Head axes as in the paper:
x from the talker's right to left, y up, z forward (out of the face); millimetres; 120 Hz.
The face is about 140 mm wide and 200 mm tall, its surface curved (z a function of x, y).

Motion in head coordinates is a sum of articulatory sources, each a time course s_k(t) at
speech rates times a smooth 3-D influence field D_k over the face (Gaussian lobes around
the talker's anatomical landmarks, some negative; a rotation about the jaw joints for the jaw):

    q_j(t) = n_j + sum_k s_k(t) D_k(n_j) + l_j(t) + e_j(t)              (marker j)

l_j is a small marker-specific smooth skin motion (band-limited, 0.55-0.65 mm RMS per
coordinate, about 1.0-1.1 mm 3-D, independent of everything else, so that every clean marker
keeps its own component above the 0.5 mm tolerance of the QR analysis) and e_j the
measurement noise: isotropic Gaussian with 0.5 mm 3-D RMS, i.e. 0.5/sqrt(3) = 0.29 mm per
coordinate (``NOISE_PER_AXIS_MM``), independent per marker, coordinate and frame. Then a
smooth rigid head motion moves everything (face and head band):

    p_j(t) = R(t) (q_j(t) - c) + c + T(t)          (c = ``HEAD_PIVOT``, the upper neck)

with R(t) = exp([w(t)]x) from a rotation vector w (a static pose of about a degree per
sentence plus band-limited motion of 1.5 degrees RMS per axis) and T(t) (1 mm pose plus 2 mm
RMS per axis). ``truth['head_motion']`` holds (w, T) per frame; ``head_frame_points`` undoes it.

Sources (``SOURCES``): jaw opening (chin about 10 mm per unit, up to ~13 mm), lip protrusion,
left and right lip-corner retraction, upper-lip raise, lower-lip depression (lower lip down,
cheeks slightly up), left and right brow raise, left and right blinks (upper lid 5-7.5 mm
down, lower lid a little up), cheek raise. Time courses are sums of raised-cosine bumps on
syllables at 4-6 per second (jaw; lips on subsets of the syllables, the lower lip partly with
the jaw, both corners together on spread vowels), slower bumps for brows and cheeks, brief
ones for blinks (left and right mostly together, not exactly), plus a little band-limited
drift; every course and the skin motion is 0 at t = 0 and rises smoothly, so each sentence
starts at rest.

Designs (``DESIGNS``):

* ``S1`` (40 sentences, talker 1): marker 13 is missing in most of the recording and was
  filled, as the paper's authors did, by copying marker 11: in head coordinates, before the
  head motion, q_13(t) = q_11(t) + (n_13 - n_11) with 11's measured (noisy) position, on the
  samples flagged in ``Recording.filled``. ``fill_fraction`` (0.9) of the sentences are filled
  whole, the others (spread evenly over the recording) from their start to 30-70 % of their
  length (13 picked up again part-way through): about 94-96 % of the samples.
  Every talker's right upper-lid marker 11 sits on the more mobile part of the lid (a
  stronger blink and skin motion than 13), so the QR ranks the measured 11 before its copy 13,
  and 13 is the marker that falls below the tolerance, as in the paper.
* ``S2a`` and ``S2b`` (50 sentences each, talker 2): the same talker (same face, landmarks,
  fields and source strengths) in two sessions: different sentences (different random time
  courses) and markers re-placed in S2b by 2 mm per coordinate over the face surface.
* ``S``: a clean subject (talker 0 unless given) of ``n_sentences`` sentences.

``talker_seed`` varies the talker (face proportions, asymmetric marker placement, source
strengths, skin-motion levels) for sweeps over virtual subjects. Everything is deterministic
by (design, seed, talker_seed). ``SimulatedSubject.truth`` is a dict of arrays (source courses
per frame, fields, neutral positions, head motion, fill masks) for ``np.savez_compressed``;
``truth_npz_bytes`` and ``truth_to_npz`` write it as fixed bytes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial.transform import Rotation

from facemotion.errors import InputError
from facemotion.recording import Recording

DESIGNS = {"S1": 40, "S2a": 50, "S2b": 50, "S": None}
DESIGN_TALKERS = {"S1": 1, "S2a": 2, "S2b": 2, "S": 0}
FACE_LABELS = [str(i) for i in range(1, 58)]
HEAD_LABELS = [f"H{i}" for i in range(1, 7)]
NOISE_3D_RMS_MM = 0.5
NOISE_PER_AXIS_MM = NOISE_3D_RMS_MM / np.sqrt(3.0)
HEAD_PIVOT = np.array([0.0, -90.0, -80.0])   # the head rotates about the upper neck
S2B_PLACEMENT_MM = 2.0
ONSET_S = 0.15                               # smooth rise from rest at a sentence's start

# Marker template (x, y) in mm on a face ~140 mm wide and ~200 mm tall; origin near the
# nose base; x from the talker's right (negative) to left (positive).
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
# Head band (x, y, z): round the forehead and temples, non-collinear.
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
# Anatomical centres of the sources: the talker's landmark under each of these markers in the
# talker's own (session-free) placement.
_ANATOMY = {"left_corner": "34", "right_corner": "38", "upper_lip": "36", "lower_lip": "40",
            "left_lid": "13", "right_lid": "11", "left_lower_lid": "16",
            "right_lower_lid": "15", "left_brow": "6", "right_brow": "2", "nose": "17",
            "left_cheek": "27", "right_cheek": "26"}


def _surface_z(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """A curved face: rounded forehead and cheeks, a nose, protruding lips and chin."""
    z = 70.0 - 0.010 * x**2 - 0.0015 * (y + 10) ** 2
    z += 22.0 * np.exp(-(x**2 + (y - 8) ** 2) / 180.0)             # nose
    z += 6.0 * np.exp(-(x**2 / 500.0 + (y + 22) ** 2 / 120.0))     # lips
    z += 4.0 * np.exp(-(x**2 / 300.0 + (y + 80) ** 2 / 150.0))     # chin
    return z


@dataclass
class Talker:
    """A virtual talker: face geometry and source strengths (deterministic by talker seed).

    neutral: this session's marker placement; anatomy: the talker's own landmarks (the source
    centres, the same in every session).
    """

    labels: list[str]
    neutral: np.ndarray            # (57, 3) face markers, head coordinates, mm
    head_band: np.ndarray          # (6, 3)
    strengths: np.ndarray          # (K,) source amplitude multipliers
    local_rms_mm: np.ndarray       # (57,) per-coordinate RMS of each marker's own skin motion
    anatomy: np.ndarray            # (57, 3) the talker's base placement (source centres)


def make_talker(talker_seed: int = 0, placement_jitter_mm: float = 0.0,
                placement_seed: int | None = None) -> Talker:
    """The talker of ``talker_seed``; ``placement_jitter_mm`` re-places the markers (a session)."""
    rng = np.random.default_rng([talker_seed, 7])
    sx, sy = rng.uniform(0.9, 1.1, 2)
    xy = np.array([_TEMPLATE[i] for i in range(1, 58)], float) * [sx, sy]
    xy += rng.normal(0.0, 1.5, xy.shape)         # the talker's own (asymmetric) placement
    base = np.column_stack([xy, _surface_z(xy[:, 0], xy[:, 1])])
    strengths = rng.uniform(0.8, 1.2, len(SOURCES))
    local = rng.uniform(0.55, 0.65, 57)
    # the right lid marker 11 is on the more mobile part of the lid (see the module notes)
    kl, kr = SOURCES.index("left_blink"), SOURCES.index("right_blink")
    strengths[kl] = rng.uniform(0.85, 1.0)
    strengths[kr] = 1.12 * strengths[kl]
    local[FACE_LABELS.index("11")], local[FACE_LABELS.index("13")] = 0.9, 0.55
    xy_s = xy.copy()
    if placement_jitter_mm:
        prng = np.random.default_rng([talker_seed, 11, placement_seed or 0])
        xy_s += prng.normal(0.0, placement_jitter_mm, xy.shape)
    neutral = np.column_stack([xy_s, _surface_z(xy_s[:, 0], xy_s[:, 1])])
    band = _HEAD_BAND * [sx, sy, 1.0]
    return Talker(list(FACE_LABELS), neutral, band, strengths, local, base)


def _design_talker(design: str, talker_seed: int | None) -> Talker:
    ts = DESIGN_TALKERS[design] if talker_seed is None else int(talker_seed)
    return make_talker(ts, placement_jitter_mm=S2B_PLACEMENT_MM if design == "S2b" else 0.0,
                       placement_seed=1)


def _check_design(design: str) -> None:
    if design not in DESIGNS:
        raise InputError(f"virtual subject design {design!r} unknown "
                         f"(use one of {', '.join(DESIGNS)})")


def marker_layout(seed: int | None = None, design: str = "S2a",
                  ) -> tuple[list[str], np.ndarray, dict[str, list[str]]]:
    """Labels ('1'..'57', 'H1'..'H6'), neutral positions (63, 3) in head coordinates (mm) and
    named regions (the face regions plus 'head_band') of a talker.

    seed: the talker seed (None: the design's own talker); design: whose session placement
    (S2b's markers sit a few mm from S2a's).
    """
    _check_design(design)
    t = _design_talker(design, seed)
    regions = {k: list(v) for k, v in REGIONS.items()}
    regions["head_band"] = list(HEAD_LABELS)
    return t.labels + HEAD_LABELS, np.concatenate([t.neutral, t.head_band]), regions


def _lobe(p: np.ndarray, c, sx: float, sy: float | None = None) -> np.ndarray:
    """Gaussian radial basis around centre c = (x, y) with widths sx, sy (mm)."""
    sy = sx if sy is None else sy
    return np.exp(-((p[:, 0] - c[0]) ** 2) / (2 * sx**2) - ((p[:, 1] - c[1]) ** 2) / (2 * sy**2))


def influence_fields(neutral: np.ndarray, anatomy: np.ndarray | None = None) -> np.ndarray:
    """D (K, n, 3): the displacement of every marker per unit of each source (mm).

    neutral: (n, 3) marker positions where the fields are evaluated; anatomy: (57, 3) the
    talker's landmark markers that centre the sources (default: ``neutral`` itself).
    """
    p = np.asarray(neutral, float)
    a = p if anatomy is None else np.asarray(anatomy, float)
    c = {k: a[int(v) - 1, :2] for k, v in _ANATOMY.items()}
    x, y, z = p[:, 0], p[:, 1], p[:, 2]
    D = np.zeros((len(SOURCES), len(p), 3))
    mouth_y = 0.5 * (c["upper_lip"][1] + c["lower_lip"][1])
    mid = np.array([0.0, mouth_y])
    # jaw opening: everything below the mouth line rotates down and back about the jaw
    # joints (axis along x through y = 10, z = -40; 4 degrees per unit), the corners half;
    # the skin of the lower cheeks is pulled with it; the upper cheeks rise slightly
    below = 1.0 / (1.0 + np.exp((y - mouth_y) / 3.0))
    stretch = 1.0 / (1.0 + np.exp((y - mouth_y - 14.0) / 6.0)) - below
    theta = 0.07
    D[0, :, 1] = -theta * (z + 40.0) * (below + 0.25 * stretch)
    D[0, :, 2] = 0.6 * theta * (y - 10.0) * below
    for side in ("left_cheek", "right_cheek"):
        D[0, :, 1] += 0.7 * _lobe(p, c[side] + [np.sign(c[side][0]) * 14, 14], 12)
    # lip protrusion: lips and the skin round them forward and towards the midline
    m = _lobe(p, mid, 18, 12)
    D[1, :, 2] = 4.0 * m
    D[1, :, 0] = -2.2 * np.tanh(x / 15.0) * m
    # lip-corner retraction (left, right): the corner outward, up and back with the cheek
    # beside it; the lip centres thin a little (negative lobe)
    for k, side in ((2, "left_corner"), (3, "right_corner")):
        cc = c[side]
        sgn = np.sign(cc[0])
        g = _lobe(p, cc, 8.0)
        broad = _lobe(p, cc + [sgn * 10, 6], 16, 14)
        D[k, :, 0] = sgn * (4.2 * g + 1.0 * broad)
        D[k, :, 1] = 1.6 * g + 0.8 * broad
        D[k, :, 2] = -1.4 * g - 0.6 * _lobe(p, mid, 8)
    # upper-lip raise (with the nostrils and nasolabial folds a little)
    g = _lobe(p, c["upper_lip"], 8, 5)
    D[4, :, 1] = 3.5 * g + 0.8 * _lobe(p, c["nose"] + [0, -8], 20, 9)
    D[4, :, 2] = 0.8 * g
    # lower-lip depression (everting): the lower lip down and forward; the cheeks rise a
    # little and the skin below the lip goes back (negative lobes)
    g = _lobe(p, c["lower_lip"], 12, 6)
    D[5, :, 1] = -3.4 * g
    D[5, :, 2] = 1.4 * g - 0.6 * _lobe(p, c["lower_lip"] + [0, -16], 14, 7)
    for side in ("left_cheek", "right_cheek"):
        D[5, :, 1] += 0.5 * _lobe(p, c[side] + [np.sign(c[side][0]) * 12, -4], 12)
    # brow raises (left, right): brows and forehead up; the upper lid follows a little
    for k, side, lid in ((6, "left_brow", "left_lid"), (7, "right_brow", "right_lid")):
        b = _lobe(p, c[side], 20, 12)
        D[k, :, 1] = 4.2 * b + 1.4 * _lobe(p, c[side] + [-np.sign(c[side][0]) * 4, 22], 22, 10)
        D[k, :, 1] += 0.5 * _lobe(p, c[lid], 6)
        D[k, :, 2] = -0.7 * b
    # blinks (left, right): the upper lid closes (~6.5 mm); the lower lid rises a little and
    # the brow dips slightly
    for k, lid, low, brow in ((8, "left_lid", "left_lower_lid", "left_brow"),
                              (9, "right_lid", "right_lower_lid", "right_brow")):
        g = _lobe(p, c[lid], 5)
        D[k, :, 1] = -6.5 * g + 1.2 * _lobe(p, c[low], 4) - 0.4 * _lobe(p, c[brow], 10)
        D[k, :, 2] = 1.0 * g
    # cheek raise (zygomatic, both sides): cheeks up, out and forward, the corners up a little
    for side in ("left_cheek", "right_cheek"):
        g = _lobe(p, c[side] + [np.sign(c[side][0]) * 14, 4], 18, 16)
        D[10, :, 0] += 1.2 * np.sign(c[side][0]) * g
        D[10, :, 1] += 2.2 * g
        D[10, :, 2] += 1.2 * g
    return D


def _bumps(t: np.ndarray, times, widths, amps) -> np.ndarray:
    """Sum of raised-cosine bumps centred at ``times`` with half-widths ``widths``."""
    u = (t[:, None] - np.asarray(times, float)[None, :]) / np.asarray(widths, float)[None, :]
    b = np.where(np.abs(u) < 1, 0.5 * (1 + np.cos(np.pi * np.clip(u, -1, 1))), 0.0)
    return b @ np.asarray(amps, float)


def _onset(n_frames: int, rate: float) -> np.ndarray:
    """Smoothstep from 0 at t = 0 to 1 at ONSET_S."""
    u = np.clip(np.arange(n_frames) / (ONSET_S * rate), 0.0, 1.0)
    return u * u * (3.0 - 2.0 * u)


def _smooth_noise(rng, shape, rate: float, sigma_s: float, rms: float) -> np.ndarray:
    """Band-limited noise along axis 0 with the given RMS: a sum of Gaussian kernels of width
    ``sigma_s`` on knots every ``sigma_s`` (from before the start to after the end) with
    independent standard-normal weights, i.e. Gaussian-smoothed white noise."""
    n = shape[0]
    t = np.arange(n) / rate
    knots = np.arange(-3.0 * sigma_s, n / rate + 3.0 * sigma_s, sigma_s)
    basis = np.exp(-0.5 * ((t[:, None] - knots[None, :]) / sigma_s) ** 2)
    w = rng.standard_normal((knots.size, int(np.prod(shape[1:], dtype=int))))
    x = basis @ w
    x *= rms / max(float(np.sqrt(np.mean(x**2))), 1e-12)
    return x.reshape(shape)


def source_courses(rng: np.random.Generator, n_frames: int, rate: float) -> np.ndarray:
    """s (F, K): source time courses of one sentence, 0 at the start (rest), smooth onset."""
    t = np.arange(n_frames) / rate
    dur = n_frames / rate
    s = np.zeros((n_frames, len(SOURCES)))
    # syllables at 4-6 per second after a short rest; the jaw opens on each
    syl_rate = rng.uniform(4.0, 6.0)
    syl = np.arange(0.22, max(dur - 0.08, 0.23), 1.0 / syl_rate)
    syl = syl + rng.normal(0, 0.02, syl.size)
    n_syl = syl.size
    width = 1.0 / syl_rate
    s[:, 0] = _bumps(t, syl, np.full(n_syl, 0.6 * width), rng.uniform(0.3, 1.3, n_syl))

    def on_some(p: float, w_lo: float, w_hi: float, a_lo: float, a_hi: float) -> np.ndarray:
        pick = rng.random(n_syl) < p
        m = int(pick.sum())
        return _bumps(t, syl[pick] + rng.normal(0, 0.03, m), width * rng.uniform(w_lo, w_hi, m),
                      rng.uniform(a_lo, a_hi, m))

    s[:, 1] = on_some(0.4, 0.9, 1.5, 0.3, 1.2)                   # rounded vowels
    spread = rng.random(n_syl) < 0.5                             # spread vowels: both corners
    m = int(spread.sum())
    times = syl[spread] + rng.normal(0, 0.02, m)
    widths = width * rng.uniform(0.8, 1.3, m)
    amps = rng.uniform(0.3, 1.2, m)
    s[:, 2] = _bumps(t, times, widths, amps * rng.uniform(0.6, 1.0, m))
    s[:, 2] += on_some(0.2, 0.7, 1.1, 0.2, 0.8)
    s[:, 3] = _bumps(t, times + rng.normal(0, 0.02, m), widths, amps * rng.uniform(0.6, 1.0, m))
    s[:, 3] += on_some(0.2, 0.7, 1.1, 0.2, 0.8)
    s[:, 4] = on_some(0.4, 0.6, 1.0, 0.3, 1.1)                   # upper lip
    s[:, 5] = 0.35 * s[:, 0] + on_some(0.4, 0.6, 1.0, 0.3, 1.0)  # lower lip, partly with the jaw
    # brows: one to three slow raises per sentence, left and right mostly together
    n_raise = int(rng.integers(1, 4))
    times = rng.uniform(0.35, max(0.4, dur - 0.3), n_raise)
    widths = rng.uniform(0.3, 0.6, n_raise)
    amps = rng.uniform(0.4, 1.0, n_raise)
    s[:, 6] = _bumps(t, times, widths, amps * rng.uniform(0.7, 1.0, n_raise))
    s[:, 7] = _bumps(t, times + rng.normal(0, 0.03, n_raise), widths,
                     amps * rng.uniform(0.7, 1.0, n_raise))
    # blinks: 0-2 per sentence, brief (0.15-0.25 s), both eyes nearly together
    n_blink = int(rng.integers(0, 3))
    bt = np.sort(rng.uniform(0.3, max(0.35, dur - 0.15), n_blink))
    if n_blink == 2 and bt[1] - bt[0] < 0.35:                  # no overlapping blinks
        bt[1] = bt[0] + 0.35
    bw = rng.uniform(0.08, 0.13, n_blink)
    ba = rng.uniform(0.8, 1.0, n_blink)
    s[:, 8] = _bumps(t, bt, bw, ba * rng.uniform(0.93, 1.0, n_blink))
    s[:, 9] = _bumps(t, bt + rng.normal(0, 0.012, n_blink), bw,
                     ba * rng.uniform(0.93, 1.0, n_blink))
    # cheek raise: slow, on a few stressed syllables
    s[:, 10] = on_some(0.25, 2.0, 3.0, 0.3, 1.0)
    # a little band-limited drift (prosody; posture of the lips, brows and cheeks)
    s += _smooth_noise(rng, s.shape, rate, 0.12, 0.06)
    return s * _onset(n_frames, rate)[:, None]


@dataclass
class SimulatedSubject:
    """A virtual subject: one ``Recording`` per sentence plus the ground truth (arrays)."""

    design: str
    recordings: list[Recording]
    names: list[str]
    head_markers: list[str]
    truth: dict = field(default_factory=dict)

    def sentence_truth(self, s: int, key: str) -> np.ndarray:
        """The rows of a per-frame truth array ('source_courses', 'head_motion', 'filled',
        'filled_13') that belong to sentence ``s`` (0-based)."""
        frames = self.truth["sentence_frames"]
        start = int(np.sum(frames[:s]))
        return self.truth[key][start:start + int(frames[s])]


def simulate_subject(design: str, seed: int = 0, n_sentences: int | None = None,
                     talker_seed: int | None = None, rate: float = 120.0,
                     sentence_duration: tuple[float, float] = (1.5, 4.0),
                     head_rotation_deg: float = 1.5, head_translation_mm: float = 2.0,
                     noise_mm: float = NOISE_3D_RMS_MM, fill_fraction: float = 0.9,
                     occlusions: bool = True) -> SimulatedSubject:
    """Simulate one subject of a design (S1, S2a, S2b or S); see the module notes.

    talker_seed: None uses the design's talker (S1: talker 1; S2a and S2b: talker 2, the same
    person, S2b with markers re-placed by a few mm; S: talker 0). sentence_duration: (low,
    high) seconds, drawn uniformly per sentence. head_rotation_deg, head_translation_mm: RMS
    per axis of the smooth head motion. noise_mm: 3-D RMS of the measurement noise.
    fill_fraction: S1 only, the fraction of sentences whose marker 13 is filled whole by
    copying marker 11 (the others are filled over their first 30-70 %). occlusions: leave
    a few samples missing (NaN, written to C3D as invalid), as a marker system does when a
    marker is hidden: in a quarter of the sentences a short gap (3-12 frames) and in one in
    twelve a long one (0.3-0.6 s), each in a random face marker other than 11 and 13, never in
    a sentence's first 10 or last 5 frames (drawn from a separate random stream, so they do not
    change anything else); ``truth['missing']`` marks them.
    """
    _check_design(design)
    n = n_sentences if n_sentences is not None else DESIGNS[design]
    if n is None or int(n) < 1:
        raise InputError(f"virtual subject design {design!r}: n_sentences must be >= 1, "
                         f"got {n_sentences}")
    n = int(n)
    try:
        lo, hi = (float(v) for v in sentence_duration)
    except (TypeError, ValueError):
        raise InputError(f"virtual subject: sentence_duration {sentence_duration!r} must be "
                         "two numbers (low, high) in seconds") from None
    if not 0 < lo <= hi:
        raise InputError(f"virtual subject: sentence_duration {sentence_duration} must "
                         "satisfy 0 < low <= high")
    if not np.isfinite(rate) or rate <= 0:
        raise InputError(f"virtual subject: rate must be positive, got {rate}")
    if not 0.0 <= fill_fraction <= 1.0:
        raise InputError(f"virtual subject: fill_fraction must be in [0, 1], got {fill_fraction}")
    if min(noise_mm, head_rotation_deg, head_translation_mm) < 0:
        raise InputError("virtual subject: noise_mm, head_rotation_deg and head_translation_mm "
                         "must be >= 0")
    talker = _design_talker(design, talker_seed)
    ts = DESIGN_TALKERS[design] if talker_seed is None else int(talker_seed)
    rng = np.random.default_rng([seed, 1 + list(DESIGNS).index(design)])
    K = len(SOURCES)
    D = influence_fields(talker.neutral, talker.anatomy) * talker.strengths[:, None, None]
    labels = talker.labels + HEAD_LABELS
    n_face = len(talker.labels)
    i11, i13 = talker.labels.index("11"), talker.labels.index("13")
    # which S1 sentences have marker 13 filled from 11: whole sentences, plus partial gaps
    fill_whole = np.zeros(n, bool)
    fill_part = np.zeros(n, bool)
    if design == "S1":
        # the others are spread evenly over the recording (one per stratum), so that any
        # long run of sentences has some measured samples of 13
        n_part = n - int(round(fill_fraction * n))
        fill_whole[:] = True
        if n_part:
            edges = np.linspace(0, n, n_part + 1).astype(int)
            fill_part[[int(rng.integers(a, b)) for a, b in zip(edges[:-1], edges[1:],
                                                                 strict=True)]] = True
            fill_whole &= ~fill_part
    noise_axis = noise_mm / np.sqrt(3.0)
    rest = np.concatenate([talker.neutral, talker.head_band])
    rot_rms = np.deg2rad(head_rotation_deg)
    orng = np.random.default_rng([seed, 99, 1 + list(DESIGNS).index(design)])
    occludable = [j for j in range(n_face) if j not in (i11, i13)]
    recs, names, truth_s, truth_head, truth_fill, truth_miss = [], [], [], [], [], []
    for s in range(n):
        F = max(int(round(rng.uniform(lo, hi) * rate)), 4)
        courses = source_courses(rng, F, rate)
        local = _smooth_noise(rng, (F, n_face, 3), rate, 0.08, 1.0)
        local *= talker.local_rms_mm[:, None] * _onset(F, rate)[:, None, None]
        pts = np.broadcast_to(rest, (F, len(labels), 3)).copy()
        pts[:, :n_face] += (courses @ D.reshape(K, -1)).reshape(F, n_face, 3) + local
        pts += rng.normal(0.0, noise_axis, pts.shape)              # measurement noise
        filled = np.zeros((F, len(labels)), bool)
        if fill_whole[s]:
            filled[:, i13] = True
        elif fill_part[s]:                 # 13 picked up again part-way through
            filled[:int(rng.uniform(0.3, 0.7) * F), i13] = True
        rows = filled[:, i13]
        # the authors' fill: 13 copies 11's measured displacement from its neutral pose
        pts[rows, i13] = pts[rows, i11] + (talker.neutral[i13] - talker.neutral[i11])
        # rigid head motion: a static pose plus smooth motion (rotation vector, mm)
        rotvec = rng.normal(0.0, 0.6 * rot_rms, 3) + _smooth_noise(rng, (F, 3), rate, 0.35,
                                                                   rot_rms)
        trans = rng.normal(0.0, 0.5 * head_translation_mm, 3) + _smooth_noise(
            rng, (F, 3), rate, 0.35, head_translation_mm)
        R = Rotation.from_rotvec(rotvec).as_matrix()
        moved = np.matmul(pts - HEAD_PIVOT, R.transpose(0, 2, 1)) + (HEAD_PIVOT + trans[:, None])
        missing = np.zeros((F, len(labels)), bool)
        if occlusions:
            for prob, (g0, g1) in ((0.25, (3, 12)), (1 / 12, (0.3 * rate, 0.6 * rate))):
                g = int(orng.integers(int(g0), int(g1) + 1))
                if orng.random() < prob and F - 5 - g > 10:
                    start = int(orng.integers(10, F - 5 - g))
                    missing[start:start + g, int(orng.choice(occludable))] = True
            moved[missing] = np.nan
        name = f"{design}_s{s + 1:02d}"
        recs.append(Recording(labels, moved, rate, name, filled))
        truth_miss.append(missing)
        names.append(name)
        truth_s.append(courses)
        truth_head.append(np.concatenate([rotvec, trans], axis=1))
        truth_fill.append(filled)
    filled_all = np.concatenate(truth_fill)
    truth = {
        "labels": np.array(labels), "neutral": rest, "anatomy": talker.anatomy,
        "sources": np.array(SOURCES), "fields": D, "strengths": talker.strengths,
        "local_rms_mm": talker.local_rms_mm, "names": np.array(names),
        "sentence_frames": np.array([len(c) for c in truth_s]),
        "source_courses": np.concatenate(truth_s), "head_motion": np.concatenate(truth_head),
        "head_pivot": HEAD_PIVOT.copy(), "filled": filled_all,
        "missing": np.concatenate(truth_miss),
        "filled_13": filled_all[:, i13].copy(), "noise_per_axis_mm": np.array(noise_axis),
        "rate": np.array(float(rate)), "talker_seed": np.array(ts), "seed": np.array(seed),
    }
    return SimulatedSubject(design, recs, names, list(HEAD_LABELS), truth)


def head_frame_points(points: np.ndarray, head_motion: np.ndarray) -> np.ndarray:
    """Undo the planted head motion (rows of ``truth['head_motion']``, one per frame) on
    points (frames, markers, 3): q = R^T (p - c - T) + c."""
    R = Rotation.from_rotvec(head_motion[:, :3]).as_matrix()
    p = np.asarray(points, float) - HEAD_PIVOT - head_motion[:, None, 3:]
    return np.einsum("fji,fnj->fni", R, p) + HEAD_PIVOT


def truth_npz_bytes(subject: SimulatedSubject) -> bytes:
    """The ground truth as deterministic ``.npz`` bytes (written beside the data)."""
    from facemotion.provenance import npz_bytes

    return npz_bytes(subject.truth)


def truth_to_npz(subject: SimulatedSubject, path: str | os.PathLike) -> None:
    """Write the ground truth as a compressed ``.npz`` (a temporary file, then a rename)."""
    path = os.fspath(path)
    tmp = f"{path}.tmp{os.getpid()}"
    try:
        with open(tmp, "wb") as fh:
            fh.write(truth_npz_bytes(subject))
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.remove(tmp)
