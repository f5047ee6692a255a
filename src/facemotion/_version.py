"""The package's version: the one place it is written (pyproject.toml, the sidecars, the command
line and CITATION.cff read it or are checked against it)."""

__version__ = "0.2.0"
