"""Write the virtual lip talker's tracked points as a TRC file, with its ground truth."""

import numpy as np

from facemotion.io.npz import npz_bytes
from facemotion.io.trc import write_trc
from facemotion.lips.virtual import make_virtual_talker
from facemotion.study.adapter import run_step
from facemotion.study.provenance import write_artifact


def main(sm, log, prov):
    spec = sm.params.lip["subject"]
    talker = make_virtual_talker(n_frames=spec.get("frames", 150), seed=spec.get("seed", 0))
    write_trc(sm.output.tracks, talker.recording)
    arrays = {"truth": talker.truth, "activations": talker.activations.to_numpy(),
              "gestures": np.array(list(talker.activations.columns)),
              "nodes": talker.mesh.nodes, "tracked": np.array(talker.tracked_labels)}
    write_artifact(sm.output.truth, npz_bytes(arrays), "lip_truth", prov,
                   also=[sm.output.tracks])
    log.info("virtual lip talker: %d frames, %d tracked points", talker.recording.n_frames,
             len(talker.tracked_labels))


run_step(snakemake, main)  # noqa: F821
