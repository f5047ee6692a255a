"""Errors raised on bad input: each message names the file, marker or setting at fault."""


class FacemotionError(Exception):
    """Base class of every error the package raises on purpose."""


class InputError(FacemotionError, ValueError):
    """Bad input data or settings; the message says which and what is wrong."""
