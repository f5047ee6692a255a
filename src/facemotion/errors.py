"""Errors raised on bad input: each message names the file, marker, argument or setting at
fault."""

TOKEN_CHARS = 16


class FacemotionError(Exception):
    """Base class of every error the package raises on purpose."""


class InputError(FacemotionError, ValueError):
    """Bad input data or settings; the message says which and what is wrong."""


class MissingFileError(InputError, FileNotFoundError):
    """A file that does not exist: both a facemotion error (``InputError``) and Python's
    ``FileNotFoundError``, so either ``except`` catches it."""


def token(value, limit: int = TOKEN_CHARS) -> str:
    """A short, quoted, printable form of a value read from a file, for an error message.

    Messages name the file and the place (line, column, frame); they never echo a file's content
    beyond such a token: a value of at most ``limit`` characters, quoted, non-printable ones
    escaped; a longer one is only described by its length.
    """
    text = str(value)
    if len(text) > limit:  # not a label or a unit: say what it is, never show its start
        return f"a text of {len(text)} characters"
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return repr(text)


def exception_detail(exc: BaseException, limit: int = 80) -> str:
    """The first line of a library's exception, for a message: its type, and its text with
    every quoted part shown as a :func:`token` (libraries quote the bytes they could not read,
    which may be anything in the file)."""
    import re

    text = (str(exc).strip().splitlines() or [""])[0]
    text = re.sub(r"'[^']*'|\"[^\"]*\"", lambda m: token(m.group()[1:-1]), text)
    if len(text) > limit:
        text = text[:limit] + " ..."
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__
