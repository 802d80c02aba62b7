"""Exceptions for user-facing failures.

Every problem caused by the user's input (a missing column, an unparseable value, too few
samples, an ill-conditioned fit) is raised as an :class:`AeromagError` whose message is one
line naming the file, column or row, and what to do.  The command line turns these into a
one-line message on stderr and a non-zero exit status, without a traceback.
"""

from __future__ import annotations


class AeromagError(Exception):
    """A user-facing error: one line, naming the file/column/row and the remedy."""

    def __init__(self, message: str) -> None:
        # Keep the message on one line whatever the caller passed.
        super().__init__(" ".join(str(message).split()))


class InputError(AeromagError, ValueError):
    """The input file, column map, plan or option values are not usable."""


class FitError(AeromagError, ValueError):
    """The compensation fit cannot be made (too few samples, ill-conditioned, ...)."""


class ConfigError(InputError):
    """An option value out of range; names the parameter (the command line names its flag).

    Attributes
    ----------
    parameter : str
        The keyword (``band_hz``, ``terms``...).
    value : object
        The value given.
    reason : str
        What the value must be.
    """

    def __init__(self, parameter: str, value: object, reason: str) -> None:
        self.parameter = parameter
        self.value = value
        self.reason = reason
        super().__init__(f"{parameter}={value!r}: {reason}")
