"""Exceptions raised by aerodelta.

Every error derives from :class:`AerodeltaError`. The engine's error kinds map one
to one onto the classes below; ``DataError`` is raised by the Python ingestion
layer and names the file, channel and rows at fault.
"""

from __future__ import annotations

from aerodelta._core import (
    AerodeltaError,
    AeroIOError,
    InvalidInputError,
    NoConvergenceError,
    OutOfRangeError,
    ParseError,
    TooLittleDataError,
)


class DataError(AerodeltaError):
    """Flight test data refused by validation (file, channel and rows in the message)."""


__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "DataError",
    "InvalidInputError",
    "NoConvergenceError",
    "OutOfRangeError",
    "ParseError",
    "TooLittleDataError",
]
