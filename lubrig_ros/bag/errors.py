"""Errors of the bag package."""

from lubrig_ros.core.errors import LubrigError


class BagError(LubrigError):
    """A bag cannot be written, read or repaired; the message is one user-facing line."""
