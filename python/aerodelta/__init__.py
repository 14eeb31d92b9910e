"""aerodelta: extend a simulator's aero database into the stall regime from flight test data.

The numerics run in the Rust engine ``aero_core`` (module ``aerodelta._core``);
this package handles files, schemas, units, orchestration, reports and the CLI.
"""

from __future__ import annotations

import importlib

from aerodelta._core import __version__
from aerodelta.aircraft import Aircraft
from aerodelta.buffet import BuffetResult, buffet_identification, compare_frequencies
from aerodelta.campaign import (
    CampaignInfo,
    campaign_plan,
    effect_library,
    generate_campaign,
    qualified_model_tables,
    replay,
    rolloff_draws,
    simulate_campaign,
)
from aerodelta.channel_map import ChannelMap
from aerodelta.closed_loop import ClosedLoopResult, closed_loop_replay
from aerodelta.daveml import (
    DaveModel,
    check_daveml,
    load_daveml,
    write_daveml,
    write_example_model,
)
from aerodelta.diagnosis import DiagnoseConfig, Diagnosis, diagnose
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
from aerodelta.export import export_extended_daveml, export_qualified_daveml
from aerodelta.fit import FitConfig, FitResult, fit, validate_model
from aerodelta.ingest import IngestResult, ingest
from aerodelta.jsbsim import export_jsbsim, jsbsim_xml
from aerodelta.lsq import OLSResults, ols
from aerodelta.model import DeltaModel
from aerodelta.partition import AlphaBins, partition_alpha
from aerodelta.rolloff import (
    compare_with_records,
    detect_rolloff,
    rolloff_statistics,
)
from aerodelta.rolloff import monte_carlo as rolloff_monte_carlo
from aerodelta.spline import SmoothingSpline, smoothing_spline
from aerodelta.stall import stall_identification, stall_summary, validity_range
from aerodelta.table import Table
from aerodelta.truth import band_check, campaign_effects, true_parameter
from aerodelta.validate import Finding, ValidationReport

__all__ = [
    "AeroIOError",
    "AerodeltaError",
    "Aircraft",
    "AlphaBins",
    "BuffetResult",
    "CampaignInfo",
    "ChannelMap",
    "ClosedLoopResult",
    "DataError",
    "DaveModel",
    "DeltaModel",
    "DiagnoseConfig",
    "Diagnosis",
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
    "band_check",
    "buffet_identification",
    "build_report",
    "campaign_effects",
    "campaign_plan",
    "check_daveml",
    "closed_loop_replay",
    "compare_frequencies",
    "compare_with_records",
    "detect_rolloff",
    "diagnose",
    "effect_library",
    "export_extended_daveml",
    "export_jsbsim",
    "export_qualified_daveml",
    "fit",
    "generate_campaign",
    "ingest",
    "jsbsim_xml",
    "load_daveml",
    "ols",
    "partition_alpha",
    "qualified_model_tables",
    "replay",
    "rolloff_draws",
    "rolloff_monte_carlo",
    "rolloff_statistics",
    "simulate_campaign",
    "smoothing_spline",
    "stall_identification",
    "stall_summary",
    "true_parameter",
    "validate_model",
    "validity_range",
    "write_daveml",
    "write_example_model",
]


def __getattr__(name: str) -> object:
    # the report pulls in matplotlib: imported on first use, not with the package
    if name in ("build_report", "ReportResult"):
        return getattr(importlib.import_module("aerodelta.report"), name)
    raise AttributeError(f"module 'aerodelta' has no attribute {name!r}")
