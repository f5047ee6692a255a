"""Which points of a C3D file are markers.

Vicon (Nexus, Plug-in Gait) and other exporters store model outputs as C3D points beside the
markers and list them in POINT parameters named for their kind: ANGLES, FORCES, MOMENTS,
POWERS, SCALARS, REACTIONS and MODELED_MARKERS (computed, not measured, positions). Newer
files also name these groups in POINT:TYPE_GROUPS. A point listed in any of them is not a
marker; everything else is.
"""

from __future__ import annotations

import numpy as np

NON_MARKER_GROUPS = ("ANGLES", "FORCES", "MOMENTS", "POWERS", "SCALARS", "REACTIONS",
                     "MODELED_MARKERS")


def _strings(value) -> list[str]:
    if isinstance(value, str):
        return [value.strip()]
    return [str(x).strip() for x in np.ravel(np.asarray(value, dtype=object))]


def non_marker_groups(point: dict) -> list[str]:
    """POINT parameters that list non-marker points (the fixed set, plus TYPE_GROUPS')."""
    groups = list(NON_MARKER_GROUPS)
    if "TYPE_GROUPS" in point:
        for name in _strings(point["TYPE_GROUPS"].get("value", [])):
            key = name.upper()
            if key and key != "MARKERS" and key in point and key not in groups:
                groups.append(key)
    return groups


def non_marker_points(point: dict, labels: list[str]) -> dict[str, str]:
    """``{label: kind}`` for each of ``labels`` that a POINT group lists as not a marker."""
    kind_of: dict[str, str] = {}
    present = set(labels)
    for group in non_marker_groups(point):
        if group not in point:
            continue
        for name in _strings(point[group].get("value", [])):
            if name and name in present and name not in kind_of:
                kind_of[name] = group.lower()
    return kind_of


def describe_dropped(kind_of: dict[str, str], limit: int = 6) -> str:
    """'angles: LHipAngles, RHipAngles; forces: LGroundReactionForce' (for the log)."""
    by_kind: dict[str, list[str]] = {}
    for label, kind in kind_of.items():
        by_kind.setdefault(kind, []).append(label)
    parts = []
    for kind, names in by_kind.items():
        more = f", ... ({len(names)} in all)" if len(names) > limit else ""
        parts.append(f"{kind}: {', '.join(names[:limit])}{more}")
    return "; ".join(parts)
