"""The project's errors: one base class, and the error of input that cannot be run.

Every error the package raises on purpose derives from `LubrigError`; its message is one line
for the user, naming the bad value and what would be valid. The command line (cli/main.py)
prints such an error (and an OSError) as that one line with exit status 2, and lets any other
exception show its traceback: that is a bug, not a user's mistake.

`InputError` is a value that cannot be run (a ValueError too, so ``except ValueError`` keeps
working); the packages' own errors (ParameterError, BagError, SpecError, ...) derive from
`LubrigError` and, where they are about values, from ValueError as well.
"""

from __future__ import annotations


class LubrigError(Exception):
    """Base of every error lubrig_ros raises on purpose; the message is one user-facing line."""


class InputError(LubrigError, ValueError):
    """A value that cannot be run: the message names it and what would be valid."""
