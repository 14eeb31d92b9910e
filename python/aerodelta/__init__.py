"""aerodelta: extend a simulator's aero database into the stall regime from flight test data.

The numerics run in the Rust engine ``aero_core`` (module ``aerodelta._core``);
this package handles files, schemas, units, orchestration, reports and the CLI.
"""

from __future__ import annotations

from aerodelta._core import __version__
from aerodelta.aircraft import Aircraft
from aerodelta.channel_map import ChannelMap
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
from aerodelta.ingest import IngestResult, ingest
from aerodelta.table import Table
from aerodelta.validate import Finding, ValidationReport

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "Aircraft",
    "ChannelMap",
    "DataError",
    "Finding",
    "IngestResult",
    "InvalidInputError",
    "NoConvergenceError",
    "OutOfRangeError",
    "ParseError",
    "Table",
    "TooLittleDataError",
    "ValidationReport",
    "__version__",
    "ingest",
]
