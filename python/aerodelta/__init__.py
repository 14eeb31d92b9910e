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
from aerodelta.daveml import (
    DaveModel,
    check_daveml,
    load_daveml,
    write_daveml,
    write_example_model,
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
from aerodelta.model import DeltaModel
from aerodelta.partition import AlphaBins, partition_alpha
from aerodelta.spline import SmoothingSpline, smoothing_spline
from aerodelta.table import Table

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "AlphaBins",
    "CampaignInfo",
    "DataError",
    "DaveModel",
    "DeltaModel",
    "InvalidInputError",
    "NoConvergenceError",
    "OutOfRangeError",
    "ParseError",
    "SmoothingSpline",
    "Table",
    "TooLittleDataError",
    "__version__",
    "check_daveml",
    "effect_library",
    "generate_campaign",
    "load_daveml",
    "partition_alpha",
    "qualified_model_tables",
    "replay",
    "rolloff_draws",
    "simulate_campaign",
    "smoothing_spline",
    "write_daveml",
    "write_example_model",
]
