"""Errors of the bag package."""


class BagError(Exception):
    """A bag cannot be written, read or repaired; the message is one user-facing line."""
