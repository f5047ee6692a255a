"""The virtual talker: built-in subjects that resemble the recordings of Lucero & Munhall (2008).

57 numbered facial markers ('1'..'57') and six head-band markers ('H1'..'H6', rigid with the
head, round the forehead and temples). Head axes as in the paper (Sec. II): x from the talker's
right to left, y up, z forward (out of the face); millimetres; 120 Hz. The face is about 140 mm
wide and 200 mm tall, its surface curved (z a function of x, y).

Calibration set
---------------
The talker is tuned on a small set of published facts, and on nothing else (``CALIBRATION``):

1. **Marker layout** (Fig. 1's regions and the markers the text names): 2 / 6 right / left
   eyebrow, 11 / 13 right / left upper eyelid, 34 / 38 left / right lip corner, 36 upper-lip
   centre, 40 lower-lip centre, 56 jaw (chin); 42, 43, 47 and 48 on the lower right of the face,
   43 near its right border, 48 and 56 both at the chin and close together (Sec. IV). The other
   numbers are our guess at Fig. 1 (rows from the forehead down, each from the talker's right).
2. **R decays smoothly** (Sec. IV, Fig. 2: "the values decrease smoothly"): on S2a's first 30
   sentences r_50 / r_10 <= 0.5 with no knee and flat tail. This sets the spatially smooth
   tissue motion (below), which replaced independent per-marker skin motion.
3. **S1's r56 / r57 within 3x of 227** (Fig. 2: 22.70 / 0.10), and r57 not zero: marker 13 is
   copied from 11 where it was lost, a "large portion" (Sec. II), not all of it. Each frame of
   13 measured on its own adds about 3 (2 sigma)^2 ~ 0.08 mm^2 to r57^2 (sigma the noise per
   axis; 13's and 11's samples, each relative to its sentence's rest frame), while
   r56^2 ~ 1,000 mm^2 on the first 30 sentences, so 227 leaves room for about one such frame
   (r56 / r57 ~ 115 with one; three or more fall below 227 / 3). In S1 marker 13 is therefore
   tracked in the rest frame that opens each sentence (which anchors its position) and in
   ``S1_TRACKED_13``, one more frame (the second of the first sentence), and lost everywhere
   else; the C3D files carry the lost samples as missing, and the subject sheet asks the
   loading path to fill them by copying 11's displacement in head coordinates after the head
   alignment (``copy_markers: 13=11``), which is how the authors filled them (Sec. II). Which
   of 11 and 13 the QR meets last is then decided by that one frame, the same way by every
   route (``docs/results.md`` says which).
4. **Fig. 9** (S1, sentence 31, a basis of ten markers): marker 56 is a secondary marker,
   predicted with maximum errors of 0.8, 2.0 and 0.9 mm in x, y and z (within 1.5x). The
   basis picks, at each step, the marker whose motion is least explained by the markers before
   it, so 56 stays secondary only if it is not the chin's most extreme point: 56 sits on the
   chin boss, 48 and 57 below it on either side (48 "close together" with 56). The errors set
   the jaw's amplitude (``JAW_RAD_PER_UNIT``: the chin about 4 mm down per unit, 5 mm at the
   largest syllables), the chin's own motion (mentalis, ``chin_raise``: brief raises of the
   chin skin on some labials) and the jaw's lateral deviation (``jaw_lateral``): what the
   lower lip and the other main markers cannot predict at the chin.

Readings of the paper's text: 120 Hz; 57 face and 6 head-band markers; each sentence starts at
rest (Sec. II); S2 is "the set of 50 sentences recorded twice". Positions "accurate within
0.5 mm": the noise is ``NOISE_PER_AXIS_MM`` = 0.08 mm per axis (0.5 mm ~ 6 sigma, a marker
system's jitter); with 0.5 mm = 3 sigma (0.17 mm) the noise floor alone would sit near half of
r_10 and break calibration item 2, which therefore also bounds the noise.

Everything else is a prediction, measured and never tuned towards: Table I, the epsilon-ranks,
Fig. 3's settling after ~25 sentences, Fig. 10's trend.

Motion
------
In head coordinates marker j moves as a sum of articulatory sources, each a time course s_k(t)
at speech rates times a smooth 3-D influence field D_k over the face (Gaussian lobes around the
talker's anatomical landmarks, some negative; a rotation about the jaw joints for the jaw),
plus spatially smooth tissue motion and measurement noise:

    q_j(t) = n_j + sum_k s_k(t) D_k(n_j) + T(n_j, t) + e_j(t)              (marker j)

T is a Gaussian random field over the face surface, independent per axis, with covariance
``TISSUE_RMS_MM``^2 exp(-|p - p'| / ``TISSUE_LENGTH_MM``) in space (an exponential kernel,
whose spectrum decays as a power law, so the diagonal of R decays smoothly instead of ending in
a flat tail) and band-limited in time: the face's motion beyond the named sources, shared by
neighbouring markers. e_j is isotropic Gaussian noise, independent per marker, coordinate and
frame. Then a smooth rigid head motion moves everything (face and head band):

    p_j(t) = R(t) (q_j(t) - c) + c + T_h(t)          (c = ``HEAD_PIVOT``, the upper neck)

with R(t) = exp([w(t)]x) from a rotation vector w (a static pose of about a degree per
sentence plus band-limited motion of 1.5 degrees RMS per axis) and T_h(t) (1 mm pose plus 2 mm
RMS per axis). ``truth['head_motion']`` holds (w, T_h) per frame; ``head_frame_points`` undoes it.

Sources (``SOURCES``): jaw opening (a rotation about the jaw joints: chin about 4 mm down per
unit), lip protrusion, left and right lip-corner retraction, upper-lip raise, lower-lip
depression, left and right brow raise, left and right blinks, cheek raise, lateral deviation of
the jaw, chin raise (mentalis).

Sentences, scripts and sessions
-------------------------------
Every subject reads sentences from one list (the CID Everyday sentences in the paper): sentence i
has a script fixed by ``CORPUS_SEED`` and i (its length in script time and, per source, the
raised-cosine gestures: syllables at 4-6 per second with the jaw opening on each, the lips on
subsets of them, slow brow and cheek raises). A recording session performs the scripts with a
session tempo (+-8 %) and per-sentence tempo, timing jitter and amplitude (per source and per
gesture) of its own; blinks, the jaw's lateral deviation, a little postural drift, the tissue
motion, the noise and the head motion are the session's. Every course is 0 at t = 0 and rises
smoothly, so each sentence starts at rest.

Designs (:mod:`facemotion.virtual.designs`):

* ``S1`` (40 sentences, talker 1, session seed from the sheet): marker 13 tracked in the
  first frame of each sentence and in ``S1_TRACKED_13`` (calibration item 3); the loading path
  copies 11 into the rest.
* ``S2a`` and ``S2b`` (50 sentences each, talker 2): the same 50 scripts recorded twice, in two
  sessions (different session seeds: tempo, timing, amplitudes, blinks, tissue, noise, head
  motion), with the markers re-placed in S2b by 2 mm per coordinate over the face surface.
* ``S``: a clean subject (talker 0 unless given) of ``n_sentences`` sentences.

``talker_seed`` varies the talker (face proportions, asymmetric marker placement, source
strengths) for sweeps over virtual subjects. Everything is deterministic by (design, seed,
talker_seed). ``SimulatedSubject.truth`` is a dict of arrays (source courses per frame, fields,
neutral positions, head motion, missing samples) for ``np.savez_compressed``;
``truth_npz_bytes`` and ``truth_to_npz`` write it as fixed bytes.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from facemotion.errors import InputError
from facemotion.io.recording import Recording
from facemotion.papers.lucero_munhall import REGIONS
from facemotion.virtual.designs import DESIGNS, TALKER_DESIGNS, get_design
from facemotion.virtual.designs import HEAD_LABELS as _HEAD_LABELS

FACE_LABELS = [str(i) for i in range(1, 58)]


HEAD_LABELS = list(_HEAD_LABELS)


NOISE_PER_AXIS_MM = 0.08                          # "accurate within 0.5 mm": ~6 sigma


NOISE_3D_RMS_MM = NOISE_PER_AXIS_MM * np.sqrt(3.0)


#: (sentence index, frame) where S1's marker 13 is measured besides each sentence's rest frame
#: (calibration item 3).
S1_TRACKED_13 = ((0, 1),)
TISSUE_RMS_MM = 0.5                              # calibration item 2 (smooth decay of R)


TISSUE_LENGTH_MM = 130.0


TISSUE_TIME_S = 0.10                              # time scale of the tissue motion


JAW_RAD_PER_UNIT = 0.04                           # jaw opening per unit of its source (rad)


CHIN_RAISE_MM = 3.0                               # mentalis: chin skin up per unit (mm)


CHIN_RAISE_WIDTH_MM = 12.0


CHIN_RAISE_RATE = 0.12                            # fraction of syllables with a chin raise


JAW_LATERAL_SD = 0.4                              # lateral deviation per unit of jaw opening


HEAD_PIVOT = np.array([0.0, -90.0, -80.0])        # the head rotates about the upper neck


S2B_PLACEMENT_MM = 2.0


ONSET_S = 0.15                                    # smooth rise from rest at a sentence's start


CORPUS_SEED = 2008                                # the sentence list every subject reads from


SESSION_TEMPO = 0.08                              # session tempo within +-8 %


#: The published facts the talker is calibrated on (see the module notes); the rest is predicted.
CALIBRATION = (
    "marker layout: Fig. 1 regions; 2/6 brows, 11/13 upper lids, 34/38 left/right lip corners, "
    "36 upper lip, 40 lower lip, 56 jaw; 42, 43, 47, 48 lower right (43 at the right border, "
    "48 and 56 at the chin, close together) (Sec. II, IV)",
    "R's diagonal decreases smoothly: r_50/r_10 <= 0.5, no knee and flat tail (Sec. IV, Fig. 2)",
    "S1 r56/r57 within 3x of 227 (Fig. 2: 22.70/0.10): marker 13 copied from 11 where lost, "
    "measured in each rest frame and one more frame (Sec. II)",
    "Fig. 9: maximum errors 0.8/2.0/0.9 mm (x/y/z) of marker 56, S1, sentence 31, basis of 10",
)


# Marker template (x, y) in mm on a face ~140 mm wide and ~200 mm tall; origin near the
# nose base; x from the talker's right (negative) to left (positive).
_TEMPLATE = {
    # forehead and brows
    1: (-50, 55), 2: (-32, 61), 3: (-14, 57), 4: (0, 72), 5: (14, 57), 6: (32, 61),
    7: (50, 55), 8: (-30, 82), 9: (30, 82),
    # eyes: outer corners, upper lids, nasion, lower lids
    10: (-50, 36), 11: (-32, 42), 12: (0, 36), 13: (32, 42), 14: (50, 36), 15: (-32, 29),
    16: (32, 29),
    # nose
    17: (0, 10), 18: (-14, 3), 19: (14, 3),
    # cheeks, from the upper cheeks down to the nasolabial folds
    20: (-60, 16), 21: (-42, 11), 22: (42, 11), 23: (60, 16), 24: (-62, -9), 25: (-45, -7),
    26: (-28, -4), 27: (28, -4), 28: (45, -7), 29: (62, -9), 30: (-11, -6), 31: (11, -6),
    32: (-38, -23), 33: (38, -23),
    # lips: left corner, upper lip (left, centre, right), right corner, lower lip
    34: (25, -22), 35: (13, -16), 36: (0, -15), 37: (-13, -16), 38: (-25, -22),
    39: (-13, -28), 40: (0, -30), 41: (13, -28),
    # lower face: below the corners, the borders, lower cheeks, jaw line, chin
    42: (-24, -44), 43: (-64, -38), 44: (24, -44), 45: (64, -38), 46: (44, -56),
    47: (-44, -56), 48: (-12, -84), 49: (-54, -64), 50: (-32, -74), 51: (-16, -58),
    52: (16, -58), 53: (32, -74), 54: (54, -64), 55: (0, -62), 56: (0, -76), 57: (12, -84),
}


# Head band (x, y, z): round the forehead and temples, non-collinear.
_HEAD_BAND = np.array([[-72, 72, -25], [-45, 96, 18], [0, 104, 32], [45, 96, 18],
                       [72, 72, -25], [0, 92, -70]], float)


SOURCES = ("jaw_open", "lip_protrusion", "left_corner_retraction", "right_corner_retraction",
           "upper_lip_raise", "lower_lip_depression", "left_brow_raise", "right_brow_raise",
           "left_blink", "right_blink", "cheek_raise", "jaw_lateral", "chin_raise")


_K = {name: k for k, name in enumerate(SOURCES)}


# Anatomical centres of the sources: the talker's landmark under each of these markers in the
# talker's own (session-free) placement.
_ANATOMY = {"left_corner": "34", "right_corner": "38", "upper_lip": "36", "lower_lip": "40",
            "left_lid": "13", "right_lid": "11", "left_lower_lid": "16",
            "right_lower_lid": "15", "left_brow": "6", "right_brow": "2", "nose": "17",
            "left_cheek": "27", "right_cheek": "26", "chin": "56"}


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
    xy_s = xy.copy()
    if placement_jitter_mm:
        prng = np.random.default_rng([talker_seed, 11, placement_seed or 0])
        xy_s += prng.normal(0.0, placement_jitter_mm, xy.shape)
    neutral = np.column_stack([xy_s, _surface_z(xy_s[:, 0], xy_s[:, 1])])
    band = _HEAD_BAND * [sx, sy, 1.0]
    return Talker(list(FACE_LABELS), neutral, band, strengths, base)


def _design_talker(design: str, talker_seed: int | None) -> Talker:
    ts = DESIGNS[design].talker if talker_seed is None else int(talker_seed)
    return make_talker(ts, placement_jitter_mm=S2B_PLACEMENT_MM if design == "S2b" else 0.0,
                       placement_seed=1)


def _check_design(design: str) -> None:
    if design not in TALKER_DESIGNS:
        get_design(design, "virtual subject")  # an unknown design
        raise InputError(f"virtual subject design {design!r} is a dense design: "
                         "facemotion.virtual.dense.simulate_dense simulates it")


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


def region_of(marker: str) -> str:
    """The face region (``REGIONS``) of a marker number of the virtual layout."""
    for name, labels in REGIONS.items():
        if str(marker) in labels:
            return name
    raise InputError(f"marker {marker!r} is not one of the virtual talker's 57 face markers")


def _lobe(p: np.ndarray, c, sx: float, sy: float | None = None) -> np.ndarray:
    """Gaussian radial basis around centre c = (x, y) with widths sx, sy (mm)."""
    sy = sx if sy is None else sy
    return np.exp(-((p[:, 0] - c[0]) ** 2) / (2 * sx**2) - ((p[:, 1] - c[1]) ** 2) / (2 * sy**2))


def influence_fields(neutral: np.ndarray, anatomy: np.ndarray | None = None,
                     jaw_side: np.ndarray | None = None) -> np.ndarray:
    """D (K, n, 3): the displacement of every marker per unit of each source (mm).

    neutral: (n, 3) marker positions where the fields are evaluated; anatomy: (57, 3) the
    talker's landmark markers that centre the sources (default: ``neutral`` itself).
    jaw_side: (n,) the share of the jaw's motion a point follows where it is known (1 on the
    lower lip, 0 on the upper, NaN elsewhere: the smooth step about the mouth line), for a
    mesh whose lips nearly touch (the dense talker, :mod:`facemotion.virtual.dense`).
    """
    p = np.asarray(neutral, float)
    a = p if anatomy is None else np.asarray(anatomy, float)
    c = {k: a[int(v) - 1, :2] for k, v in _ANATOMY.items()}
    D = np.zeros((len(SOURCES), len(p), 3))
    _jaw_fields(D, p, c, jaw_side)
    _lip_fields(D, p, c)
    _upper_face_fields(D, p, c)
    return D


def _jaw_fields(D: np.ndarray, p: np.ndarray, c: dict, jaw_side: np.ndarray | None) -> None:
    """Jaw opening and lateral deviation of the jaw, in D."""
    y, z = p[:, 1], p[:, 2]
    mouth_y = 0.5 * (c["upper_lip"][1] + c["lower_lip"][1])
    # jaw opening: everything below the mouth line rotates down and back about the jaw
    # joints (axis along x through y = 10, z = -40; JAW_RAD_PER_UNIT per unit), the corners half;
    # the skin of the lower cheeks is pulled with it; the upper cheeks rise slightly
    below = 1.0 / (1.0 + np.exp((y - mouth_y) / 3.0))
    if jaw_side is not None:
        side = np.asarray(jaw_side, float)
        below = np.where(np.isfinite(side), side, below)
    stretch = 1.0 / (1.0 + np.exp((y - mouth_y - 14.0) / 6.0)) - below
    theta = JAW_RAD_PER_UNIT
    D[_K["jaw_open"], :, 1] = -theta * (z + 40.0) * (below + 0.25 * stretch)
    D[_K["jaw_open"], :, 2] = 0.6 * theta * (y - 10.0) * below
    for side in ("left_cheek", "right_cheek"):
        D[_K["jaw_open"], :, 1] += 0.7 * _lobe(p, c[side] + [np.sign(c[side][0]) * 14, 14], 12)
    # lateral deviation of the jaw: the mandible (and the lower lip on it) turns about a
    # vertical axis through the jaw joints (x = 0, z = -40), the chin about 1 mm per unit;
    # the skin of the lower cheeks half as much
    yaw = (below + 0.5 * stretch) / 105.0
    D[_K["jaw_lateral"], :, 0] = yaw * (z + 40.0)
    D[_K["jaw_lateral"], :, 2] = -yaw * p[:, 0]


def _lip_fields(D: np.ndarray, p: np.ndarray, c: dict) -> None:
    """Lip protrusion, corner retractions, upper-lip raise, lower-lip depression and chin
    raise, in D."""
    x = p[:, 0]
    mid = np.array([0.0, 0.5 * (c["upper_lip"][1] + c["lower_lip"][1])])
    # lip protrusion: lips and the skin round them forward and towards the midline
    m = _lobe(p, mid, 18, 12)
    D[_K["lip_protrusion"], :, 2] = 4.0 * m
    D[_K["lip_protrusion"], :, 0] = -2.2 * np.tanh(x / 15.0) * m
    # lip-corner retraction (left, right): the corner outward, up and back with the cheek
    # beside it; the lip centres thin a little (negative lobe)
    for k, side in ((_K["left_corner_retraction"], "left_corner"),
                    (_K["right_corner_retraction"], "right_corner")):
        cc = c[side]
        sgn = np.sign(cc[0])
        g = _lobe(p, cc, 8.0)
        broad = _lobe(p, cc + [sgn * 10, 6], 16, 14)
        D[k, :, 0] = sgn * (4.2 * g + 1.0 * broad)
        D[k, :, 1] = 1.6 * g + 0.8 * broad
        D[k, :, 2] = -1.4 * g - 0.6 * _lobe(p, mid, 8)
    # upper-lip raise (with the nostrils and nasolabial folds a little)
    g = _lobe(p, c["upper_lip"], 8, 5)
    D[_K["upper_lip_raise"], :, 1] = 3.5 * g + 0.8 * _lobe(p, c["nose"] + [0, -8], 20, 9)
    D[_K["upper_lip_raise"], :, 2] = 0.8 * g
    # lower-lip depression (everting): the lower lip down and forward; the cheeks rise a
    # little and the skin below the lip goes back (negative lobes)
    k = _K["lower_lip_depression"]
    g = _lobe(p, c["lower_lip"], 12, 6)
    D[k, :, 1] = -3.4 * g
    D[k, :, 2] = 1.4 * g - 0.6 * _lobe(p, c["lower_lip"] + [0, -16], 14, 7)
    for side in ("left_cheek", "right_cheek"):
        D[k, :, 1] += 0.5 * _lobe(p, c[side] + [np.sign(c[side][0]) * 12, -4], 12)
    # chin raise (mentalis): the skin of the chin up and forward, pushing the lower lip up
    k = _K["chin_raise"]
    g = _lobe(p, c["chin"], CHIN_RAISE_WIDTH_MM)
    D[k, :, 1] = CHIN_RAISE_MM * g + 0.8 * _lobe(p, c["lower_lip"], 12, 5)
    D[k, :, 2] = 0.6 * CHIN_RAISE_MM * g + 0.6 * _lobe(p, c["lower_lip"], 12, 5)


def _upper_face_fields(D: np.ndarray, p: np.ndarray, c: dict) -> None:
    """Brow raises, blinks and the cheek raise, in D."""
    # brow raises (left, right): brows and forehead up; the upper lid follows a little
    for k, side, lid in ((_K["left_brow_raise"], "left_brow", "left_lid"),
                         (_K["right_brow_raise"], "right_brow", "right_lid")):
        b = _lobe(p, c[side], 20, 12)
        D[k, :, 1] = 4.2 * b + 1.4 * _lobe(p, c[side] + [-np.sign(c[side][0]) * 4, 22], 22, 10)
        D[k, :, 1] += 0.5 * _lobe(p, c[lid], 6)
        D[k, :, 2] = -0.7 * b
    # blinks (left, right): the upper lid closes (~6.5 mm); the lower lid rises a little and
    # the brow dips slightly
    for k, lid, low, brow in ((_K["left_blink"], "left_lid", "left_lower_lid", "left_brow"),
                              (_K["right_blink"], "right_lid", "right_lower_lid", "right_brow")):
        g = _lobe(p, c[lid], 5)
        D[k, :, 1] = -6.5 * g + 1.2 * _lobe(p, c[low], 4) - 0.4 * _lobe(p, c[brow], 10)
        D[k, :, 2] = 1.0 * g
    # cheek raise (zygomatic, both sides): cheeks up, out and forward, the corners up a little
    k = _K["cheek_raise"]
    for side in ("left_cheek", "right_cheek"):
        g = _lobe(p, c[side] + [np.sign(c[side][0]) * 14, 4], 18, 16)
        D[k, :, 0] += 1.2 * np.sign(c[side][0]) * g
        D[k, :, 1] += 2.2 * g
        D[k, :, 2] += 1.2 * g


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


@dataclass
class Script:
    """One sentence of the corpus: its length (s) and its gestures in script time.

    events: (E, 4) rows (source index, centre s, half-width s, amplitude).
    """

    duration: float
    events: np.ndarray


def sentence_script(index: int, duration: tuple[float, float] = (1.5, 4.0)) -> Script:
    """The script of corpus sentence ``index`` (0-based): the same for every subject/session."""
    rng = np.random.default_rng([CORPUS_SEED, int(index)])
    dur = float(rng.uniform(*duration))
    ev: list[tuple[int, float, float, float]] = []

    def add(src, times, widths, amps):
        for t, w, a in zip(np.atleast_1d(times), np.atleast_1d(widths), np.atleast_1d(amps),
                           strict=True):
            ev.append((src, float(t), float(w), float(a)))

    # syllables at 4-6 per second after a short rest; the jaw opens on each
    syl_rate = rng.uniform(4.0, 6.0)
    syl = np.arange(0.22, max(dur - 0.08, 0.23), 1.0 / syl_rate)
    syl = syl + rng.normal(0, 0.02, syl.size)
    n_syl = syl.size
    width = 1.0 / syl_rate
    jaw_amp = rng.uniform(0.3, 1.3, n_syl)
    add(_K["jaw_open"], syl, np.full(n_syl, 0.6 * width), jaw_amp)

    def on_some(src, p, w_lo, w_hi, a_lo, a_hi):
        pick = rng.random(n_syl) < p
        m = int(pick.sum())
        add(src, syl[pick] + rng.normal(0, 0.03, m), width * rng.uniform(w_lo, w_hi, m),
            rng.uniform(a_lo, a_hi, m))

    on_some(_K["lip_protrusion"], 0.4, 0.9, 1.5, 0.3, 1.2)            # rounded vowels
    spread = rng.random(n_syl) < 0.5                                   # spread vowels
    m = int(spread.sum())
    times = syl[spread] + rng.normal(0, 0.02, m)
    widths = width * rng.uniform(0.8, 1.3, m)
    amps = rng.uniform(0.3, 1.2, m)
    add(_K["left_corner_retraction"], times, widths, amps * rng.uniform(0.6, 1.0, m))
    add(_K["right_corner_retraction"], times + rng.normal(0, 0.02, m), widths,
        amps * rng.uniform(0.6, 1.0, m))
    on_some(_K["left_corner_retraction"], 0.2, 0.7, 1.1, 0.2, 0.8)
    on_some(_K["right_corner_retraction"], 0.2, 0.7, 1.1, 0.2, 0.8)
    on_some(_K["upper_lip_raise"], 0.4, 0.6, 1.0, 0.3, 1.1)
    # the lower lip partly with the jaw, partly on its own
    add(_K["lower_lip_depression"], syl, np.full(n_syl, 0.6 * width), 0.35 * jaw_amp)
    on_some(_K["lower_lip_depression"], 0.4, 0.6, 1.0, 0.3, 1.0)
    on_some(_K["chin_raise"], CHIN_RAISE_RATE, 0.8, 1.2, 0.3, 1.0)     # labials, /u/
    # brows: one to three slow raises per sentence, left and right mostly together
    n_raise = int(rng.integers(1, 4))
    times = rng.uniform(0.35, max(0.4, dur - 0.3), n_raise)
    widths = rng.uniform(0.3, 0.6, n_raise)
    amps = rng.uniform(0.4, 1.0, n_raise)
    add(_K["left_brow_raise"], times, widths, amps * rng.uniform(0.7, 1.0, n_raise))
    add(_K["right_brow_raise"], times + rng.normal(0, 0.03, n_raise), widths,
        amps * rng.uniform(0.7, 1.0, n_raise))
    on_some(_K["cheek_raise"], 0.25, 2.0, 3.0, 0.3, 1.0)               # stressed syllables
    return Script(dur, np.array(ev, float).reshape(-1, 4))


def perform(script: Script, rng: np.random.Generator, rate: float, tempo: float,
            gains: np.ndarray) -> np.ndarray:
    """s (F, K): a session's performance of a script, 0 at the start (rest), smooth onset.

    tempo: speed relative to the script (1.1 = 10 % faster); gains (K,): this sentence's
    amplitude per source. Each gesture moves by a little timing jitter and amplitude of its
    own. Blinks, the jaw's lateral deviation and a postural drift are the session's own.
    """
    F = max(int(round(script.duration / tempo * rate)), 4)
    t = np.arange(F) / rate
    dur = F / rate
    s = np.zeros((F, len(SOURCES)))
    ev = script.events
    src = ev[:, 0].astype(int)
    times = ev[:, 1] / tempo + rng.normal(0.0, 0.012, len(ev))
    widths = ev[:, 2] / tempo
    amps = ev[:, 3] * gains[src] * rng.normal(1.0, 0.08, len(ev))
    for k in np.unique(src):
        sel = src == k
        s[:, k] = _bumps(t, times[sel], widths[sel], amps[sel])
    # the jaw deviates a little to one side or the other on each opening
    jaw = src == _K["jaw_open"]
    s[:, _K["jaw_lateral"]] = _bumps(t, times[jaw], widths[jaw],
                                     amps[jaw] * rng.normal(0.0, JAW_LATERAL_SD, int(jaw.sum())))
    # blinks: 0-2 per sentence, brief (0.15-0.25 s), both eyes nearly together
    n_blink = int(rng.integers(0, 3))
    bt = np.sort(rng.uniform(0.3, max(0.35, dur - 0.15), n_blink))
    if n_blink == 2 and bt[1] - bt[0] < 0.35:                  # no overlapping blinks
        bt[1] = bt[0] + 0.35
    bw = rng.uniform(0.08, 0.13, n_blink)
    ba = rng.uniform(0.8, 1.0, n_blink)
    s[:, _K["left_blink"]] = _bumps(t, bt, bw, ba * rng.uniform(0.93, 1.0, n_blink))
    s[:, _K["right_blink"]] = _bumps(t, bt + rng.normal(0, 0.012, n_blink), bw,
                                     ba * rng.uniform(0.93, 1.0, n_blink))
    # a little band-limited drift (prosody; posture of the lips, brows and cheeks)
    s += _smooth_noise(rng, s.shape, rate, 0.12, 0.06)
    return s * _onset(F, rate)[:, None]


def tissue_factor(points: np.ndarray, length_mm: float | None = None) -> np.ndarray:
    """W (n, n) with W W^T = exp(-|p_i - p_j| / length): the spatial factor of the tissue
    motion (exponential covariance over the face, eigen-decomposition)."""
    length_mm = TISSUE_LENGTH_MM if length_mm is None else length_mm
    p = np.asarray(points, float)
    d = np.linalg.norm(p[:, None, :] - p[None, :, :], axis=-1)
    lam, V = np.linalg.eigh(np.exp(-d / length_mm))
    return V * np.sqrt(np.clip(lam, 0.0, None))[None, :]


@dataclass
class SimulatedSubject:
    """A virtual subject: one ``Recording`` per sentence plus the ground truth (arrays)."""

    design: str
    recordings: list[Recording]
    names: list[str]
    head_markers: list[str]
    truth: dict = field(default_factory=dict)

    def truth_of_sentence(self, number: int, key: str) -> np.ndarray:
        """The rows of a per-frame truth array ('source_courses', 'head_motion', 'missing',
        'lost_13') that belong to sentence ``number``, counting from 1 (the ``_s01`` file is
        sentence 1)."""
        frames = self.truth["sentence_frames"]
        if isinstance(number, bool) or not 1 <= int(number) <= len(frames):
            raise InputError(f"sentence number {number!r} out of range 1..{len(frames)} "
                             "(counting from 1)")
        s = int(number) - 1
        start = int(np.sum(frames[:s]))
        return self.truth[key][start:start + int(frames[s])]

    def sentence_truth(self, s: int, key: str) -> np.ndarray:
        """Deprecated (removed in 0.3): :meth:`truth_of_sentence` of sentence ``s`` counted
        from 0."""
        import warnings

        warnings.warn("SimulatedSubject.sentence_truth(s, ...) counts sentences from 0 and is "
                      "deprecated (removed in 0.3); use truth_of_sentence(number, ...), "
                      "counting from 1", DeprecationWarning, stacklevel=2)
        return self.truth_of_sentence(int(s) + 1, key)


def simulate_subject(design: str, seed: int = 0, n_sentences: int | None = None,
                     talker_seed: int | None = None, rate: float = 120.0,
                     sentence_duration: tuple[float, float] = (1.5, 4.0),
                     head_rotation_deg: float = 1.5, head_translation_mm: float = 2.0,
                     noise_mm: float = NOISE_3D_RMS_MM, tissue_rms_mm: float = TISSUE_RMS_MM,
                     occlusions: bool = True) -> SimulatedSubject:
    """Simulate one subject of a design (S1, S2a, S2b or S); see the module notes.

    seed: the session (performance, tissue, noise, head motion); the sentences' scripts come
    from the corpus (``sentence_script``). talker_seed: None uses the design's talker (S1:
    talker 1; S2a and S2b: talker 2, the same person, S2b with markers re-placed by a few mm;
    S: talker 0). sentence_duration: (low, high) seconds of the scripts, drawn uniformly per
    sentence. head_rotation_deg, head_translation_mm: RMS per axis of the smooth head motion.
    noise_mm: 3-D RMS of the measurement noise. tissue_rms_mm: RMS per axis of the tissue
    motion. occlusions: leave a few samples missing (NaN, written to C3D as invalid), as a
    marker system does when a marker is hidden: in a quarter of the sentences a short gap
    (3-12 frames) and in one in twelve a long one (0.3-0.6 s), each in a random face marker
    other than 11 and 13, never in a sentence's first 10 or last 5 frames (drawn from a
    separate random stream, so they do not change anything else); ``truth['missing']`` marks
    them. In S1, marker 13 is missing after the first frame of every sentence
    (``truth['lost_13']``), whatever ``occlusions`` says.
    """
    n, duration = _checked_settings(design, n_sentences, sentence_duration, rate, noise_mm,
                                    head_rotation_deg, head_translation_mm, tissue_rms_mm)
    talker = _design_talker(design, talker_seed)
    ts = DESIGNS[design].talker if talker_seed is None else int(talker_seed)
    stream = DESIGNS[design].rng_stream
    rng = np.random.default_rng([seed, stream])
    D = influence_fields(talker.neutral, talker.anatomy) * talker.strengths[:, None, None]
    labels = talker.labels + HEAD_LABELS
    n_face = len(talker.labels)
    i11, i13 = talker.labels.index("11"), talker.labels.index("13")
    session = Session(
        labels=labels, rest=np.concatenate([talker.neutral, talker.head_band]), fields=D,
        tissue=tissue_factor(talker.neutral), rate=rate, duration=duration,
        tempo=1.0 + rng.uniform(-SESSION_TEMPO, SESSION_TEMPO), noise_axis=noise_mm / np.sqrt(3.0),
        tissue_rms_mm=tissue_rms_mm, rot_rms=np.deg2rad(head_rotation_deg),
        head_translation_mm=head_translation_mm)
    orng = np.random.default_rng([seed, 99, stream])
    occludable = [j for j in range(n_face) if j not in (i11, i13)]
    recs, parts = [], []
    for s in range(n):
        courses, tempo = perform_sentence(session, s, rng)
        F = courses.shape[0]
        pts = _face_points(session, courses, rng, n_face)
        motion = head_motion(session, F, rng)
        moved = move_head(pts, motion)
        missing = _occlusions(F, len(labels), rate, orng, occludable) if occlusions else (
            np.zeros((F, len(labels)), bool))
        lost = np.zeros(F, bool)
        if design == "S1":              # calibration item 3: 13 a near copy of 11
            lost[1:] = True
            lost[[f for si, f in S1_TRACKED_13 if si == s]] = False
            missing[:, i13] |= lost
        moved[missing] = np.nan
        recs.append(Recording(labels, moved, rate, f"{design}_s{s + 1:02d}"))
        parts.append({"courses": courses, "head": motion, "tempo": tempo, "missing": missing,
                      "lost": lost})
    names = [r.source for r in recs]
    truth = {
        "labels": np.array(labels), "neutral": session.rest, "anatomy": talker.anatomy,
        "sources": np.array(SOURCES), "fields": D, "strengths": talker.strengths,
        "names": np.array(names), "script_index": np.arange(n),
        **_sentence_truth(parts),
        "head_pivot": HEAD_PIVOT.copy(), "missing": np.concatenate([p["missing"] for p in parts]),
        "lost_13": np.concatenate([p["lost"] for p in parts]),
        "noise_per_axis_mm": np.array(session.noise_axis),
        "tissue_rms_mm": np.array(float(tissue_rms_mm)),
        "tissue_length_mm": np.array(TISSUE_LENGTH_MM),
        "rate": np.array(float(rate)), "talker_seed": np.array(ts), "seed": np.array(seed),
    }
    return SimulatedSubject(design, recs, names, list(HEAD_LABELS), truth)


def _checked_settings(design: str, n_sentences, sentence_duration, rate: float,
                      noise_mm: float, head_rotation_deg: float, head_translation_mm: float,
                      tissue_rms_mm: float) -> tuple[int, tuple[float, float]]:
    """The number of sentences and the (low, high) script duration, every setting checked."""
    _check_design(design)
    n = n_sentences if n_sentences is not None else DESIGNS[design].sentences
    if n is None or int(n) < 1:
        raise InputError(f"virtual subject design {design!r}: n_sentences must be >= 1, "
                         f"got {n_sentences}")
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
    if min(noise_mm, head_rotation_deg, head_translation_mm, tissue_rms_mm) < 0:
        raise InputError("virtual subject: noise_mm, tissue_rms_mm, head_rotation_deg and "
                         "head_translation_mm must be >= 0")
    return int(n), (lo, hi)


@dataclass(frozen=True)
class Session:
    """What the sentences of one simulated session share: the markers, their rest positions
    (face, then head band), the sources' fields D (K, face markers, 3), the tissue factor W,
    the session's tempo, and the sizes of the noise, tissue and head motion."""

    labels: list[str]
    rest: np.ndarray
    fields: np.ndarray
    tissue: np.ndarray
    rate: float
    duration: tuple[float, float]
    tempo: float
    noise_axis: float               # per axis (mm)
    tissue_rms_mm: float
    rot_rms: float                  # head rotation, RMS per axis (rad)
    head_translation_mm: float


def perform_sentence(session: Session, s: int, rng: np.random.Generator
                     ) -> tuple[np.ndarray, float]:
    """Sentence ``s`` of the corpus performed in the session: the sources' time courses
    (F, K) and the sentence's tempo."""
    script = sentence_script(s, session.duration)
    tempo = session.tempo * float(np.exp(rng.normal(0.0, 0.04)))
    gains = np.exp(rng.normal(0.0, 0.12, session.fields.shape[0]))
    return perform(script, rng, session.rate, tempo, gains), tempo


def _face_points(session: Session, courses: np.ndarray, rng: np.random.Generator,
                 n_face: int) -> np.ndarray:
    """Every marker (F, M, 3) in the head frame: rest + sources' fields + tissue + noise."""
    F, K = courses.shape
    onset = _onset(F, session.rate)[:, None]
    # tissue motion: smooth in time, spatially correlated over the face (per axis)
    z = _smooth_noise(rng, (F, n_face, 3), session.rate, TISSUE_TIME_S, 1.0)
    tissue = np.matmul(session.tissue, z) * (session.tissue_rms_mm * onset[:, :, None])  # W z
    pts = np.broadcast_to(session.rest, (F, len(session.labels), 3)).copy()
    pts[:, :n_face] += (courses @ session.fields.reshape(K, -1)).reshape(F, n_face, 3) + tissue
    pts += rng.normal(0.0, session.noise_axis, pts.shape)              # measurement noise
    return pts


def head_motion(session: Session, F: int, rng: np.random.Generator) -> np.ndarray:
    """A sentence's rigid head motion (F, 6): rotation vector (rad), translation (mm), each a
    static pose plus smooth motion."""
    rotvec = rng.normal(0.0, 0.6 * session.rot_rms, 3) + _smooth_noise(
        rng, (F, 3), session.rate, 0.35, session.rot_rms)
    trans = rng.normal(0.0, 0.5 * session.head_translation_mm, 3) + _smooth_noise(
        rng, (F, 3), session.rate, 0.35, session.head_translation_mm)
    return np.concatenate([rotvec, trans], axis=1)


def move_head(points: np.ndarray, motion: np.ndarray) -> np.ndarray:
    """Points (F, M, 3) of the head frame moved by the head motion (rows of ``head_motion``):
    p = R (q - c) + c + T, the inverse of :func:`head_frame_points`."""
    from scipy.spatial.transform import Rotation  # here: not for synth.REGIONS

    R = Rotation.from_rotvec(motion[:, :3]).as_matrix()
    return np.matmul(points - HEAD_PIVOT, R.transpose(0, 2, 1)) + (HEAD_PIVOT + motion[:, None, 3:])


def _occlusions(F: int, n_markers: int, rate: float, orng: np.random.Generator,
                occludable: list[int]) -> np.ndarray:
    """(F, markers) bool: a short gap in a quarter of the sentences, a long one in one in
    twelve, each in a random occludable marker, away from the sentence's ends."""
    missing = np.zeros((F, n_markers), bool)
    for prob, (g0, g1) in ((0.25, (3, 12)), (1 / 12, (0.3 * rate, 0.6 * rate))):
        g = int(orng.integers(int(g0), int(g1) + 1))
        if orng.random() < prob and F - 5 - g > 10:
            start = int(orng.integers(10, F - 5 - g))
            missing[start:start + g, int(orng.choice(occludable))] = True
    return missing


def _sentence_truth(parts: list[dict]) -> dict:
    """The per-sentence truth arrays of a session, the sentences one after another."""
    return {"sentence_frames": np.array([len(p["courses"]) for p in parts]),
            "tempo": np.array([p["tempo"] for p in parts]),
            "source_courses": np.concatenate([p["courses"] for p in parts]),
            "head_motion": np.concatenate([p["head"] for p in parts])}


def head_frame_points(points: np.ndarray, head_motion: np.ndarray) -> np.ndarray:
    """Undo the planted head motion (rows of ``truth['head_motion']``, one per frame) on
    points (frames, markers, 3): q = R^T (p - c - T) + c."""
    from scipy.spatial.transform import Rotation  # here: not for synth.REGIONS

    R = Rotation.from_rotvec(head_motion[:, :3]).as_matrix()
    p = np.asarray(points, float) - HEAD_PIVOT - head_motion[:, None, 3:]
    return np.einsum("fji,fnj->fni", R, p) + HEAD_PIVOT


def truth_npz_bytes(subject: SimulatedSubject) -> bytes:
    """The ground truth as deterministic ``.npz`` bytes (written beside the data)."""
    from facemotion.io.npz import npz_bytes

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
