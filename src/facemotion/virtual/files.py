"""A virtual subject written as real files, one per sentence, with its ground truth.

The study reads virtual subjects by the same readers as a lab's recordings: the 57-marker
talker as C3D files, the dense talker as TRC, C3D or OpenFace CSV plus its face mesh.
"""

from __future__ import annotations

import logging
import os
from pathlib import Path

from facemotion.virtual.designs import get_design

log = logging.getLogger("facemotion")


def write_virtual_subject(out_dir: str | os.PathLike, subject_id: str, design: str, *,
                          fmt: str = "c3d", seed: int = 0, n_sentences: int | None = None,
                          talker_seed: int | None = None,
                          sentence_duration: tuple[float, float] | None = None,
                          shared_data: str | os.PathLike | None = None
                          ) -> tuple[list[Path], bytes]:
    """Simulate a subject of ``design`` and write its sentences as
    ``out_dir/{subject_id}_sNN.<suffix>`` in ``fmt``; returns the files and the ground truth's
    npz bytes (:func:`facemotion.virtual.talker.truth_npz_bytes`)."""
    from facemotion.io.registry import get_format
    from facemotion.virtual.talker import simulate_subject, truth_npz_bytes

    spec = get_design(design)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    kwargs = {"seed": seed, "n_sentences": n_sentences, "talker_seed": talker_seed}
    if sentence_duration:
        kwargs["sentence_duration"] = tuple(sentence_duration)
    if spec.dense:  # TRC, C3D or OpenFace CSV, and the placed mesh.obj
        from facemotion.virtual.dense import simulate_dense, write_dense_subject

        subject = simulate_dense(design, shared_data=shared_data, **kwargs)
        paths = write_dense_subject(subject, out, subject_id, fmt)
        for path in paths:
            log.info("wrote %s", path.name)
        return paths, truth_npz_bytes(subject)
    subject = simulate_subject(design, **kwargs)
    writer = get_format(fmt).write
    paths = []
    for i, (rec, name) in enumerate(zip(subject.recordings, subject.names, strict=True)):
        paths.append(out / f"{subject_id}_s{i + 1:02d}.{spec.suffix(fmt)}")
        writer(paths[-1], rec)
        log.info("wrote sentence %d/%d (%s)", i + 1, len(subject.names), name)
    return paths, truth_npz_bytes(subject)
