"""The layout checks the vendor readers share, written to run on a whole file or block by block.

Each check takes a block of data lines - their 1-based line numbers and the values read from
them - and what the lines before the block left (the previous frame number, the index of the
block's first frame), so a reader that streams a long take in blocks runs the same checks on
each block as a reader that holds the whole file. Each raises one InputError naming the file,
the line and what is wrong; none quotes more of the file than a number.
"""

from __future__ import annotations

import numpy as np

from facemotion.errors import InputError


def check_field_counts(path, line_numbers, n_fields, expected: int, what: str,
                       allow_more: bool = False) -> None:
    """Every data line has ``expected`` fields (more only when ``allow_more``): a line with a
    field missing would move every later value to another axis or marker."""
    n_fields = np.asarray(n_fields)
    bad = np.flatnonzero((n_fields < expected) | ((n_fields > expected) & (not allow_more)))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{path}: line {int(line_numbers[i])} has {int(n_fields[i])} fields but "
                         f"{what} has {expected}: a field is missing or the line is cut (a "
                         "missing sample is an empty field)")


def check_frame_numbers(path, line_numbers, frames, previous: float | None = None,
                        column: str = "Frame") -> None:
    """Frame numbers step by exactly 1 from line to line (and from ``previous``, the last
    frame number before the block): a line removed, repeated or swapped is an error."""
    frames = np.asarray(frames, dtype=float)
    bad = np.flatnonzero(~np.isfinite(frames) | (frames != np.round(frames)))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: {column} must be a whole number")
    before = np.concatenate([[frames[0] - 1 if previous is None else previous], frames[:-1]])
    jump = np.flatnonzero(frames - before != 1)
    if jump.size:
        i = int(jump[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: {column} {frames[i]:g} does not "
                         f"follow {before[i]:g} (a frame is missing, repeated or out of "
                         "order)")


def check_time_grid(path, line_numbers, times, rate: float, t0: float, first_index: int = 0,
                    column: str = "Time", rate_name: str = "the header's rate",
                    rounding_s: float = 0.0) -> None:
    """Times lie on the grid ``t0 + k / rate`` (k counting from ``first_index``, the block's
    first frame in the take) within a quarter of a frame plus ``rounding_s`` (the writer's
    rounding of the time): a frame missing, repeated or reordered, or a time column at another
    rate than the header declares, is an error naming the line."""
    times = np.asarray(times, dtype=float)
    bad = np.flatnonzero(~np.isfinite(times))
    if bad.size:
        i = int(bad[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: {column} must be a number")
    grid = t0 + (first_index + np.arange(times.size)) / rate
    off = np.flatnonzero(np.abs(times - grid) > 0.25 / rate + rounding_s)
    if off.size:
        i = int(off[0])
        raise InputError(f"{path}: line {int(line_numbers[i])}: {column} {times[i]:.6g} s is off "
                         f"the grid of {rate_name}, {rate:g} Hz (expected {grid[i]:.6g} s): a "
                         "frame is missing, repeated or out of order, or the rate is wrong")


def check_frame_count(path, declared: int, found: int, key: str) -> None:
    """The header's frame count equals the data lines read (else the file is cut or grown)."""
    if declared != found:
        cut = " (the file looks cut short)" if found < declared else ""
        raise InputError(f"{path}: {key} is {declared} but there are {found} data lines{cut}")
