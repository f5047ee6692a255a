"""What every workflow script shares: logging to the rule's log, provenance, clear errors.

A script is a thin adapter::

    from facemotion.snakemake_adapter import run_step

    def main(sm, log, prov):
        ...  # read sm.input, call facemotion, write sm.output with provenance

    run_step(snakemake, main)
"""

from __future__ import annotations

import logging
import os
import sys
from collections.abc import Callable
from pathlib import Path

from facemotion.errors import FacemotionError
from facemotion.provenance import Provenance


def _flatten(files) -> list[str]:
    out: list[str] = []
    for f in files:
        if isinstance(f, (list, tuple)):
            out.extend(_flatten(f))
        else:
            out.append(str(f))
    return out


def figure_paths(output, key: str = "png") -> list[str]:
    """A figure's files from a rule's outputs: the PNG named ``key`` (``png``, ``traj_png``)
    and the other formats of the ``figures.formats`` setting, named ``key`` with ``more`` for
    ``png`` (``more``, ``traj_more``; declared with ``fig_more()`` in common.smk)."""
    more = key[: -len("png")] + "more"
    extra = list(output[more]) if more in output.keys() else []
    return [str(output[key]), *map(str, extra)]


def provenance_for(sm, extra_inputs=()) -> Provenance:
    """Provenance of a Snakemake job: rule name, its params (the config used), its inputs."""
    params = {k: v for k, v in sm.params.items()} if hasattr(sm.params, "items") else {}
    wildcards = {k: v for k, v in sm.wildcards.items()} if hasattr(sm.wildcards, "items") else {}
    config = {"wildcards": wildcards, "params": params}
    files = [f for f in _flatten(sm.input) if os.path.isfile(f)] + list(extra_inputs)
    return Provenance(step=sm.rule, config=config, inputs=files)


def setup_logging(sm) -> logging.Logger:
    log = logging.getLogger("facemotion")
    log.setLevel(logging.INFO)
    for h in list(log.handlers):
        log.removeHandler(h)
    logs = _flatten(sm.log) if sm.log else []
    if logs:
        Path(logs[0]).parent.mkdir(parents=True, exist_ok=True)
        handler: logging.Handler = logging.FileHandler(logs[0], mode="w")
    else:
        handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(logging.Formatter("%(levelname)s %(message)s"))
    log.addHandler(handler)
    return log


def run_step(sm, main: Callable) -> None:
    """Run ``main(sm, log, prov)``; a FacemotionError becomes one clear line and exit 1.

    Outputs are written atomically by the provenance module, and Snakemake removes the
    outputs of a failed job, so nothing half-written is left behind.
    """
    import matplotlib

    matplotlib.use("Agg")
    log = setup_logging(sm)
    try:
        main(sm, log, provenance_for(sm))
    except FacemotionError as exc:
        msg = f"facemotion: {sm.rule}: {exc}"
        log.error(msg)
        print(msg, file=sys.stderr)
        sys.exit(1)
    log.info("done")
