"""aerodelta: extend a simulator's aero database into the stall regime from flight test data.

The numerics run in the Rust engine ``aero_core`` (module ``aerodelta._core``);
this package handles files, schemas, units, orchestration, reports and the CLI.
"""

from __future__ import annotations

import importlib

from aerodelta._core import __version__
from aerodelta.aircraft import Aircraft
from aerodelta.campaign import (
    CampaignInfo,
    effect_library,
    generate_campaign,
    qualified_model_tables,
    replay,
    rolloff_draws,
    simulate_campaign,
)
from aerodelta.channel_map import ChannelMap
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
from aerodelta.fit import FitConfig, FitResult, fit, validate_model
from aerodelta.ingest import IngestResult, ingest
from aerodelta.lsq import OLSResults, ols
from aerodelta.model import DeltaModel
from aerodelta.partition import AlphaBins, partition_alpha
from aerodelta.rolloff import detect_rolloff, rolloff_statistics
from aerodelta.spline import SmoothingSpline, smoothing_spline
from aerodelta.table import Table
from aerodelta.validate import Finding, ValidationReport

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "Aircraft",
    "AlphaBins",
    "CampaignInfo",
    "ChannelMap",
    "DataError",
    "DaveModel",
    "DeltaModel",
    "Finding",
    "FitConfig",
    "FitResult",
    "IngestResult",
    "InvalidInputError",
    "NoConvergenceError",
    "OLSResults",
    "OutOfRangeError",
    "ParseError",
    "ReportResult",
    "SmoothingSpline",
    "Table",
    "TooLittleDataError",
    "ValidationReport",
    "__version__",
    "build_report",
    "check_daveml",
    "detect_rolloff",
    "effect_library",
    "fit",
    "generate_campaign",
    "ingest",
    "load_daveml",
    "ols",
    "partition_alpha",
    "qualified_model_tables",
    "replay",
    "rolloff_draws",
    "rolloff_statistics",
    "simulate_campaign",
    "smoothing_spline",
    "validate_model",
    "write_daveml",
    "write_example_model",
]


def __getattr__(name: str) -> object:
    # the report pulls in matplotlib: imported on first use, not with the package
    if name in ("build_report", "ReportResult"):
        return getattr(importlib.import_module("aerodelta.report"), name)
    raise AttributeError(f"module 'aerodelta' has no attribute {name!r}")
