"""aerodelta: extend a simulator's aero database into the stall regime from flight test data.

The numerics run in the Rust engine ``aero_core`` (module ``aerodelta._core``);
this package handles files, schemas, units, orchestration, reports and the CLI.
"""

from __future__ import annotations

from aerodelta._core import __version__
from aerodelta.campaign import (
    CampaignInfo,
    effect_library,
    generate_campaign,
    qualified_model_tables,
    replay,
    rolloff_draws,
    simulate_campaign,
)
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
from aerodelta.table import Table

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "CampaignInfo",
    "DataError",
    "InvalidInputError",
    "NoConvergenceError",
    "OutOfRangeError",
    "ParseError",
    "Table",
    "TooLittleDataError",
    "__version__",
    "effect_library",
    "generate_campaign",
    "qualified_model_tables",
    "replay",
    "rolloff_draws",
    "simulate_campaign",
]
