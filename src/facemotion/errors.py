"""Errors raised on bad input: each message names the file, marker, argument or setting at
fault."""

TOKEN_CHARS = 16


class FacemotionError(Exception):
    """Base class of every error the package raises on purpose."""


class InputError(FacemotionError, ValueError):
    """Bad input data or settings; the message says which and what is wrong."""


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
