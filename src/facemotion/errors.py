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
    beyond such a token: at most ``limit`` characters, non-printable ones escaped, '...' when cut.
    """
    text = str(value)
    cut = len(text) > limit
    text = text[:limit]
    text = "".join(c if c.isprintable() else repr(c)[1:-1] for c in text)
    return repr(text + "...") if cut else repr(text)
