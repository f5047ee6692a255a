"""C3D files, read and written through ezc3d, with their declared layout checked first.

A C3D file shorter than its header declares would otherwise read back with frames silently
missing; :func:`check_c3d_size` compares the file's size with the layout its header and
parameters declare."""

from __future__ import annotations

import errno
import logging
import struct
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from facemotion.errors import InputError, token
from facemotion.io.atomic import atomic_path
from facemotion.io.base import check_readable, unit_scale
from facemotion.io.recording import Recording, finite_samples

_C3D_PROCESSORS = {84: "Intel", 85: "DEC", 86: "MIPS"}


C3D_MAX_FRAMES = 65535  # ezc3d writes the frame count as a 16-bit word


@dataclass
class C3DLayout:
    """What a C3D file's header (and parameters) declare about its data section."""

    processor: str          # Intel, DEC or MIPS (byte order and float format)
    points: int             # 3-D points per frame
    analog_per_frame: int   # analog samples per 3-D frame (all channels)
    first_frame: int
    last_frame: int
    frames: int
    float_storage: bool     # POINT:SCALE < 0: 4-byte floats, else 2-byte integers
    data_start: int         # byte offset of the data section

    @property
    def data_bytes(self) -> int:
        """Bytes of the data section: frames x (4 words per point + analog samples)."""
        word = 4 if self.float_storage else 2
        return self.frames * (4 * self.points + self.analog_per_frame) * word

    @property
    def size(self) -> int:
        """The smallest file size that holds every declared frame."""
        return self.data_start + self.data_bytes


def _c3d_float(raw: bytes, processor: str) -> float:
    if processor == "DEC":  # VAX F-float: 16-bit words swapped, exponent bias 2 more than IEEE
        return struct.unpack("<f", raw[2:4] + raw[0:2])[0] / 4.0
    return struct.unpack(">f" if processor == "MIPS" else "<f", raw)[0]


def _c3d_parameter(section: bytes, processor: str, group: str, name: str):
    """First value of parameter GROUP:NAME from a C3D parameter section (None if absent)."""
    end = ">" if processor == "MIPS" else "<"
    pos, groups, params = 4, {}, {}
    while pos + 2 <= len(section):
        nchars, ident = struct.unpack("bb", section[pos:pos + 2])
        if nchars == 0:
            break
        # names as written: ezc3d matches them exactly, so a damaged letter is no match
        key = section[pos + 2:pos + 2 + abs(nchars)].decode("latin-1").strip()
        off_at = pos + 2 + abs(nchars)
        if off_at + 2 > len(section):
            break
        (offset,) = struct.unpack(end + "h", section[off_at:off_at + 2])
        body = off_at + 2
        if ident < 0:
            groups[key] = -ident
        elif body + 2 <= len(section):
            dtype, ndim = struct.unpack("bb", section[body:body + 2])
            params[(ident, key)] = (dtype, section[body + 2 + ndim:body + 2 + ndim + 4])
        if offset <= 0:
            break
        pos = off_at + offset
    found = params.get((groups.get(group.upper()), name.upper()))
    if found is None:
        return None
    dtype, raw = found
    if dtype == 2 and len(raw) >= 2:
        return struct.unpack(end + "H", raw[:2])[0]
    if dtype == 4 and len(raw) >= 4:
        return _c3d_float(raw[:4], processor)
    if dtype == 1 and raw:
        return raw[0]
    return None


def _entry_problem(section: bytes, pos: int, end: str) -> tuple[str | None, int, int, str]:
    """One entry of a parameter section at ``pos``: (what is wrong or None, its group or
    parameter id, the next entry's position or 0 after the last, its name)."""
    nchars, ident = struct.unpack("bb", section[pos:pos + 2])
    name = section[pos + 2:pos + 2 + abs(nchars)].decode("latin-1")
    off_at = pos + 2 + abs(nchars)
    if off_at + 2 > len(section):
        return "runs past the section", ident, 0, name
    (offset,) = struct.unpack(end + "h", section[off_at:off_at + 2])
    nxt = off_at + offset if offset > 0 else 0
    limit = nxt or len(section)
    if offset < 0 or limit > len(section):
        return "points past the section", ident, nxt, name
    body = off_at + 2
    if ident > 0:  # a parameter: type, dimensions, data, then its description
        if body + 2 > limit:
            return "is cut", ident, nxt, name
        dtype, ndim = struct.unpack("bb", section[body:body + 2])
        if dtype not in (-1, 1, 2, 4) or not 0 <= ndim <= 7 or body + 2 + ndim > limit:
            return f"has type {dtype} and {ndim} dimensions", ident, nxt, name
        count = int(np.prod(list(section[body + 2:body + 2 + ndim]), dtype=np.int64))
        body += 2 + ndim + abs(dtype) * count
    if body + 1 > limit:
        return "has no room for its data and description", ident, nxt, name
    (desc,) = struct.unpack("b", section[body:body + 1])
    if desc < 0 or body + 1 + desc > limit:
        return "has a description longer than its room", ident, nxt, name
    return None, ident, nxt, name


def check_c3d_parameters(path, section: bytes, processor: str) -> None:
    """InputError naming the damaged entry if the parameter section's chain of groups and
    parameters is not whole: every entry within the section, its type, dimensions, data and
    description within its own room, and every parameter in a group the section defines
    (ezc3d trusts these bytes; a damaged one can crash the process)."""
    end = ">" if processor == "MIPS" else "<"
    pos, groups, params = 4, set(), []
    while pos + 2 <= len(section) and section[pos] != 0:
        problem, ident, nxt, name = _entry_problem(section, pos, end)
        if problem:
            raise InputError(f"{path}: C3D parameter section is damaged: the entry at byte "
                             f"{pos} ({token(name.strip())}) {problem}")
        if ident < 0:
            groups.add(-ident)
        else:
            params.append((ident, name, pos))
        if not nxt:
            break
        pos = nxt
    for ident, name, at in params:
        if ident not in groups:
            raise InputError(f"{path}: C3D parameter section is damaged: parameter "
                             f"{token(name.strip())} at byte {at} belongs to group {ident}, "
                             "which the section does not define")


def c3d_layout(path) -> C3DLayout:
    """Read the layout a C3D file declares: its 512-byte header, and POINT:FRAMES when the
    header's 16-bit frame numbers cannot hold the count (the C3D User Guide's convention)."""
    p = Path(path)
    with open(p, "rb") as fh:
        head = fh.read(512)
        if len(head) < 512 or head[1] != 0x50:
            raise InputError(f"{p}: not a C3D file (no valid 512-byte header)")
        if head[0] < 2:
            raise InputError(f"{p}: C3D header is damaged: its parameter section would start "
                             f"in block {head[0]}, inside the header")
        fh.seek((head[0] - 1) * 512)
        section = fh.read(255 * 512)
    if len(section) < 4 or section[3] not in _C3D_PROCESSORS:
        raise InputError(f"{p}: C3D parameter section is missing or cut short "
                         f"(processor type byte {section[3] if len(section) > 3 else None})")
    section = section[:max(section[2], 1) * 512]
    processor = _C3D_PROCESSORS[section[3]]
    if processor != "MIPS":  # ezc3d refuses every MIPS (SGI) file before reading further
        check_c3d_parameters(p, section, processor)
    end = ">" if processor == "MIPS" else "<"
    points, analog, first, last = struct.unpack(end + "4H", head[2:10])
    # sign of the scale factor (a float in the processor's format; only its sign bit matters)
    sign_byte = {"Intel": head[15], "DEC": head[13], "MIPS": head[12]}[processor]
    float_storage = bool(sign_byte & 0x80)
    (start_block,) = struct.unpack(end + "H", head[16:18])
    frames = last - first + 1
    if last == 0xFFFF or frames <= 0:
        declared = _c3d_parameter(section, processor, "POINT", "FRAMES")
        if declared is not None:
            frames = int(declared)
    return C3DLayout(processor, points, analog, first, last, max(frames, 0), float_storage,
                     (max(start_block, 1) - 1) * 512)


def _header_disagreement(p: Path, layout: C3DLayout) -> str | None:
    """Where the 512-byte header contradicts the parameter section (POINT:USED,
    POINT:DATA_START, POINT:FRAMES, POINT:SCALE's sign), or None: a damaged header, which a
    size check alone would take for a file cut short."""
    with open(p, "rb") as fh:
        head = fh.read(512)
        fh.seek((head[0] - 1) * 512)
        section = fh.read(255 * 512)
    section = section[:max(section[2], 1) * 512]

    def param(name):
        return _c3d_parameter(section, layout.processor, "POINT", name)

    checks = [("number of points", layout.points, param("USED")),
              ("data start block", layout.data_start // 512 + 1, param("DATA_START"))]
    if layout.last_frame != 0xFFFF:
        checks.append(("number of frames", layout.frames, param("FRAMES")))
    used = _c3d_parameter(section, layout.processor, "ANALOG", "USED")
    a_rate = _c3d_parameter(section, layout.processor, "ANALOG", "RATE")
    p_rate = param("RATE")
    if used is None and layout.analog_per_frame:
        checks.append(("analog samples per frame", layout.analog_per_frame,
                       "none: no ANALOG:USED"))
    elif used == 0:
        checks.append(("analog samples per frame", layout.analog_per_frame, 0))
    elif used is not None and a_rate and p_rate and a_rate == a_rate and p_rate == p_rate:
        ratio = a_rate / p_rate  # whole in a sound file: analog samples per 3-D frame
        checks.append(("analog samples per frame", layout.analog_per_frame,
                       int(used) * ratio if ratio != round(ratio) else int(used) * int(ratio)))
    rate = param("RATE")
    header_rate = _c3d_float(head[20:24], layout.processor)
    if rate is not None and rate == rate and header_rate == header_rate and header_rate > 0 \
            and header_rate != rate:  # the same 32-bit float, written twice
        checks.append(("frame rate", f"{header_rate:g}", f"{rate:g}"))
    scale = param("SCALE")
    if scale is not None and scale == scale:
        checks.append(("storage (float or integer)",
                       "float" if layout.float_storage else "integer",
                       "float" if scale < 0 else "integer"))
        # the header's copy of POINT:SCALE (words 7-8), in the processor's float format
        header_scale = _c3d_float(head[12:16], layout.processor)
        if header_scale == header_scale and header_scale != scale:
            checks.append(("point scale", f"{header_scale:g}", f"{scale:g}"))
    for what, header, parameter in checks:
        if parameter is not None and header != parameter:
            return (f"its header's {what} ({header}) disagrees with its parameter section "
                    f"({parameter}): the header is damaged")
    return None


def check_c3d_size(path) -> C3DLayout:
    """InputError if the file is shorter than its header declares (cut in the data section,
    or its last bytes lost); ezc3d would otherwise read it with frames silently missing. A
    header that contradicts the parameter section is said to be damaged, not the file cut."""
    p = Path(path)
    layout = c3d_layout(p)
    size = p.stat().st_size
    if size < layout.size or (size - layout.size > 512
                              and size - layout.size >= layout.data_bytes // max(layout.frames, 1)
                              and layout.data_bytes):
        damaged = _header_disagreement(p, layout)
        if damaged:
            raise InputError(f"{p}: C3D file cannot be read: {damaged}")
    if size < layout.size:
        per_frame = max(layout.data_bytes // max(layout.frames, 1), 1)
        whole = max(size - layout.data_start, 0) // per_frame
        raise InputError(
            f"{p}: C3D file is cut short: its header declares frames {layout.first_frame}-"
            f"{layout.first_frame + layout.frames - 1} ({layout.frames} frames) of "
            f"{layout.points} points and {layout.analog_per_frame} analog samples per frame in "
            f"{'float' if layout.float_storage else 'integer'} storage, {layout.size} bytes, "
            f"but the file has {size} bytes (only {whole} whole frames)")
    per_frame = layout.data_bytes // max(layout.frames, 1)
    # writers pad the data to whole 512-byte blocks (ezc3d adds a whole block when it is full)
    if per_frame and size - layout.size > 512 and size - layout.size >= per_frame:
        raise InputError(
            f"{p}: C3D file holds {size - layout.size} bytes after the {layout.frames} frames "
            f"its header declares (about {(size - layout.size) // per_frame} more frames): the "
            "header's frame count is wrong (e.g. more than 65535 frames)")
    return layout


def open_c3d(p: Path):
    """The file read by ezc3d (header, parameters and data), or InputError naming it.

    ezc3d takes the path as UTF-8 text; a file whose name is other bytes (a POSIX name in
    Latin-1, say) is opened through a link with a plain name in a temporary folder."""
    import ezc3d

    try:
        str(p).encode("utf-8")
        name_ok = True
    except UnicodeEncodeError:
        name_ok = False
    try:
        if name_ok:
            return ezc3d.c3d(str(p))
        import os
        import tempfile

        with tempfile.TemporaryDirectory(prefix="facemotion-c3d-") as tmp:
            link = Path(tmp) / "take.c3d"
            os.symlink(os.fsencode(p.resolve()), os.fsencode(link))
            return ezc3d.c3d(str(link))
    except Exception as e:  # ezc3d raises RuntimeError/IOError with terse messages
        raise InputError(f"{p}: cannot read as C3D ({type(e).__name__}: "
                         f"{str(e).splitlines()[0][:80] if str(e) else 'no detail'})") from None


def point_units(declared: list[str], units: str | None, p) -> tuple[str, str, float]:
    """(units, where they came from: "file" or "sheet", scale to mm): POINT:UNITS when the
    file declares them, else the subject sheet's; neither is an error naming the file."""
    if declared and declared[0]:
        used, source = declared[0], "file"
    elif units is not None:
        used, source = units, "sheet"
    else:
        raise InputError(f"{p}: POINT:UNITS is missing; give the units in the subject sheet")
    return used, source, unit_scale(
        used, f"{p} ({'POINT:UNITS' if source == 'file' else 'sheet units'})")


def read_c3d(path, units: str | None = None) -> Recording:
    """Read the 3-D points of a C3D file with ezc3d.

    Labels come from POINT:LABELS (whitespace stripped), the rate from POINT:RATE and the units
    from POINT:UNITS (``units`` only for a file without them). The file's size is checked
    against its header first (:func:`check_c3d_size`). Points that POINT:ANGLES, FORCES,
    MOMENTS, POWERS, SCALARS, REACTIONS or MODELED_MARKERS list are not markers and are left
    out, with a log line (:mod:`facemotion.io.c3d_points`). Coordinates are taken at the
    32-bit precision C3D stores (floats, or 16-bit integers times a 32-bit scale), so the
    integer and real variants of one trial read identically. A sample is missing (NaN) if its
    residual is negative (C3D's "invalid" flag), if any coordinate is NaN, or if it is exactly
    (0, 0, 0) with a residual that is not positive (the exporters' other way of writing
    "no data").
    """
    from facemotion.io.c3d_points import describe_dropped, non_marker_points

    p = check_readable(path)
    damaged = _header_disagreement(p, check_c3d_size(p))
    if damaged:  # the data section's size fits; the values may still be right
        logging.getLogger("facemotion").warning("%s: %s", p, damaged)
    c = open_c3d(p)
    point = c["parameters"]["POINT"]
    data = np.asarray(c["data"]["points"], dtype=float)  # (4, markers, frames)
    n = data.shape[1]
    labels = [str(x).strip() for x in point["LABELS"]["value"]] if "LABELS" in point else []
    # Files with more than 255 points continue the labels in LABELS2, LABELS3, ...
    k = 2
    while len(labels) < n and f"LABELS{k}" in point:
        labels += [str(x).strip() for x in point[f"LABELS{k}"]["value"]]
        k += 1
    if len(labels) < n:
        raise InputError(f"{p}: POINT:LABELS has {len(labels)} labels for {n} points")
    labels = labels[:n]
    not_markers = non_marker_points(point, labels)
    if not_markers:
        logging.getLogger("facemotion").info(
            "%s: left out %d points that are not markers (%s)", p, len(not_markers),
            describe_dropped(not_markers))
    kept = [i for i, lab in enumerate(labels) if lab not in not_markers]
    if not kept:
        raise InputError(f"{p}: no marker points (all {n} points are "
                         f"{', '.join(sorted(set(not_markers.values())))})")
    labels = [labels[i] for i in kept]
    empty = [kept[i] for i, lab in enumerate(labels) if not lab]
    if empty:
        raise InputError(f"{p}: point(s) {empty[:5]} have an empty label in POINT:LABELS")
    rate_v = np.ravel(point["RATE"]["value"]) if "RATE" in point else np.array([])
    rate = float(rate_v[0]) if rate_v.size else float(c["header"]["points"]["frame_rate"])
    u = point["UNITS"]["value"] if "UNITS" in point else []
    u = [str(x).strip() for x in u] if not isinstance(u, str) else [u.strip()]
    used, source, scale = point_units(u, units, p)
    # (frames, markers, 3); float32 first: the precision the file stores (see the docstring)
    xyz = data[:3, kept].astype(np.float32).astype(float).transpose(2, 1, 0) * scale
    meta = c["data"].get("meta_points", {})
    if "residuals" in meta and np.size(meta["residuals"]):
        residual = np.asarray(meta["residuals"], dtype=float)[0, kept].T  # (frames, markers)
    else:
        residual = np.zeros(xyz.shape[:2])
    invalid = (residual < 0) | ~finite_samples(xyz)
    invalid |= (xyz[..., 0] == 0) & (xyz[..., 1] == 0) & (xyz[..., 2] == 0) & ~(residual > 0)
    xyz[invalid] = np.nan
    return Recording(labels, xyz, rate, source=str(p), units=used, units_source=source)


def c3d_parameters(path: Path, layout: C3DLayout) -> dict[str, dict[str, dict]]:
    """The parameter section of an Intel C3D file as ``{GROUP: {NAME: {"value": [...]}}}``
    (ezc3d's shape): character arrays as lists of strings (trailing spaces stripped, as
    ezc3d gives them), numbers as flat lists."""
    with open(path, "rb") as fh:
        head = fh.read(512)
        fh.seek((head[0] - 1) * 512)
        section = fh.read(255 * 512)
    section = section[:max(section[2], 1) * 512]
    groups: dict[int, str] = {}
    params: list[tuple[int, str, dict]] = []
    pos = 4
    while pos + 2 <= len(section) and section[pos] != 0:
        nchars, ident = struct.unpack("bb", section[pos:pos + 2])
        name = section[pos + 2:pos + 2 + abs(nchars)].decode("latin-1").strip().upper()
        off_at = pos + 2 + abs(nchars)
        (offset,) = struct.unpack("<h", section[off_at:off_at + 2])
        if ident < 0:
            groups[-ident] = name
        else:
            params.append((ident, name, {"value": _value(section, off_at + 2)}))
        if offset <= 0:
            break
        pos = off_at + offset
    out: dict[str, dict[str, dict]] = {g: {} for g in groups.values()}
    for ident, name, entry in params:
        if ident in groups:
            out[groups[ident]][name] = entry
    return out


def _value(section: bytes, body: int) -> list:
    """A parameter's data (the entry's type byte at ``body``)."""
    dtype, ndim = struct.unpack("bb", section[body:body + 2])
    dims = list(section[body + 2:body + 2 + ndim])
    start = body + 2 + ndim
    count = int(np.prod(dims, dtype=np.int64)) if ndim else 1
    raw = section[start:start + abs(dtype) * count]
    if dtype == -1:
        if ndim <= 1:
            return [raw.decode("latin-1").rstrip()]
        width = dims[0]
        if width == 0:
            return [""] * int(np.prod(dims[1:], dtype=np.int64))
        return [raw[i:i + width].decode("latin-1").rstrip() for i in range(0, len(raw), width)]
    kind = {1: "<u1", 2: "<i2", 4: "<f4"}.get(dtype)
    return [] if kind is None else np.frombuffer(raw, dtype=kind).tolist()


def _marker_points(p: Path, layout: C3DLayout, point: dict) -> tuple[list[str], np.ndarray]:
    """The markers' labels and their points' indices (POINT:LABELS, LABELS2, ...; the points
    other POINT parameters list as not markers left out, logged)."""
    from facemotion.io.c3d_points import describe_dropped, non_marker_points

    labels = list(point.get("LABELS", {}).get("value", []))
    k = 2
    while len(labels) < layout.points and f"LABELS{k}" in point:
        labels += point[f"LABELS{k}"]["value"]
        k += 1
    if len(labels) < layout.points:
        raise InputError(f"{p}: POINT:LABELS has {len(labels)} labels for {layout.points} "
                         "points")
    labels = [str(x).strip() for x in labels[:layout.points]]
    not_markers = non_marker_points(point, labels)
    if not_markers:
        logging.getLogger("facemotion").info(
            "%s: left out %d points that are not markers (%s)", p, len(not_markers),
            describe_dropped(not_markers))
    kept = np.array([i for i, lab in enumerate(labels) if lab not in not_markers], dtype=int)
    if kept.size == 0:
        raise InputError(f"{p}: no marker points (all {layout.points} points are "
                         f"{', '.join(sorted(set(not_markers.values())))})")
    labels = [labels[i] for i in kept]
    empty = [int(kept[i]) for i, lab in enumerate(labels) if not lab]
    if empty:
        raise InputError(f"{p}: point(s) {empty[:5]} have an empty label in POINT:LABELS")
    return labels, kept


def c3d_labels(path) -> list[str]:
    """The marker labels of an Intel C3D file, from its parameter section alone."""
    p = check_readable(path)
    layout = check_c3d_size(p)
    if layout.processor != "Intel":
        raise InputError(f"{p}: C3D written for a {layout.processor} processor; the block "
                         "reader reads Intel files only (read it whole)")
    return _marker_points(p, layout, c3d_parameters(p, layout).get("POINT", {}))[0]


def read_c3d_labels(path) -> list[str]:
    """The marker labels of a C3D file as :func:`read_c3d` gives them: from the parameter
    section alone for an Intel file (:func:`c3d_labels`), else from the file read whole."""
    p = check_readable(path)
    if c3d_layout(p).processor == "Intel":
        return c3d_labels(p)
    return read_c3d(p).labels


def write_c3d(path, rec: Recording, flag_filled: bool = False,
              descriptions: list[str] | None = None) -> None:
    """Write the points of ``rec`` to a C3D file (mm; residual -1 where a sample is NaN).

    flag_filled: mark ``rec.filled`` samples as computed, by the C3D convention for residuals
    (0: valid but interpolated or computed; > 0: measured): filled samples get residual 0, the
    others 1.0, a placeholder (the measured residuals are not known here).  Without it every
    valid sample has residual 0.  descriptions: POINT:DESCRIPTIONS, one per marker."""
    import ezc3d

    if rec.n_frames == 0:
        raise InputError(f"{path}: a recording without frames cannot be written to C3D")
    if rec.n_frames > C3D_MAX_FRAMES:
        raise InputError(f"{path}: {rec.n_frames} frames cannot be written to C3D (ezc3d "
                         f"writes at most {C3D_MAX_FRAMES}); write TRC or CSV")
    c = ezc3d.c3d()
    c["parameters"]["POINT"]["RATE"]["value"] = [float(rec.rate)]
    c["parameters"]["POINT"]["LABELS"]["value"] = tuple(rec.labels)
    c["parameters"]["POINT"]["UNITS"]["value"] = ["mm"]
    pts = np.ones((4, rec.n_markers, rec.n_frames))
    pts[:3] = rec.points.transpose(2, 1, 0)
    bad = ~np.isfinite(rec.points).all(axis=2).T  # (markers, frames)
    pts[:3, bad] = np.nan
    c["data"]["points"] = pts
    residuals = np.zeros((1, rec.n_markers, rec.n_frames))
    if flag_filled:
        residuals[0] = np.where(rec.filled.T, 0.0, 1.0)
    residuals[0, bad] = -1.0
    if descriptions is not None:
        if len(descriptions) != rec.n_markers:
            raise InputError(f"{path}: {len(descriptions)} descriptions for {rec.n_markers} "
                             "markers")
        c["parameters"]["POINT"]["DESCRIPTIONS"]["value"] = tuple(descriptions)
    c["data"]["meta_points"]["residuals"] = residuals
    c["data"]["meta_points"]["camera_masks"] = np.zeros((7, rec.n_markers, rec.n_frames),
                                                        dtype=bool)
    with atomic_path(path, suffix=".c3d") as tmp:  # ezc3d adds .c3d otherwise
        c.write(str(tmp))
        # ezc3d does not report a failed write (disk full, file-size limit): check the size
        try:
            check_c3d_size(tmp)
        except InputError:
            raise OSError(errno.EIO, "the written C3D file is incomplete (disk full or file-size "
                          "limit?)", str(path)) from None
