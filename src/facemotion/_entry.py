"""The ``facemotion`` command's entry point: ``--version`` answers without importing the
numerical stack (numpy, pandas, SciPy) or the command line; everything else goes to
:func:`facemotion.cli.main`."""

from __future__ import annotations

import sys


def main(argv: list[str] | None = None) -> None:
    args = sys.argv[1:] if argv is None else list(argv)
    if args in (["--version"], ["-V"]):
        from facemotion._version import __version__

        print(f"facemotion, version {__version__}")
        sys.exit(0)
    from facemotion.cli import main as cli_main

    cli_main(argv)


if __name__ == "__main__":
    main()
