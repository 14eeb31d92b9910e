"""aerodelta: extend a simulator's aero database into the stall regime from flight test data.

The numerics run in the Rust engine ``aero_core`` (module ``aerodelta._core``);
this package handles files, schemas, units, orchestration, reports and the CLI.
"""

from __future__ import annotations

from aerodelta._core import __version__
from aerodelta.exceptions import (
    AerodeltaError,
    AeroIOError,
    DataError,
    InvalidInputError,
    NoConvergenceError,
    OutOfRangeError,
    ParseError,
    TooLittleDataError,
)
from aerodelta.lsq import OLSResults, ols
from aerodelta.table import Table

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "DataError",
    "InvalidInputError",
    "NoConvergenceError",
    "OLSResults",
    "OutOfRangeError",
    "ParseError",
    "Table",
    "TooLittleDataError",
    "__version__",
    "ols",
]
