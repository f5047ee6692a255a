"""The Snakemake side: a study's sheet, settings, outputs, provenance and closing summary.

- :mod:`~facemotion.study.sheet`: the subject sheet and the datasets built on it;
- :mod:`~facemotion.study.settings`: the config's schema and its checks against the data;
- :mod:`~facemotion.study.invocation`: paths given on the command line, a clean failed parse;
- :mod:`~facemotion.study.outputs`: where each rule's outputs and their sidecars go;
- :mod:`~facemotion.study.adapter`: what every workflow script shares (logging, clear errors);
- :mod:`~facemotion.study.provenance` and :mod:`~facemotion.study.manifest`: sidecars and the
  results manifest;
- :mod:`~facemotion.study.sweeps`: parameter sweeps across datasets;
- :mod:`~facemotion.study.summary`: the study's name and its closing summary.

The library below it works without Snakemake; nothing below imports from here.
"""


def __getattr__(name: str):
    """Names of the 0.1 module ``facemotion.study``, now in :mod:`facemotion.study.summary`."""
    from facemotion._deprecated import MOVED_NAMES, lookup

    if name.startswith("__"):
        raise AttributeError(name)
    value = lookup("study", MOVED_NAMES["study"], name)
    globals()[name] = value
    return value
