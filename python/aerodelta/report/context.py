"""What every report section reads: the records with measured, qualified and extended
coefficients side by side, the model, its per-bin estimates and the held-out list."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta.exceptions import DataError
from aerodelta.fit import COEFFICIENTS, model_frame, qualified_coefficients
from aerodelta.model import DeltaModel, check_params
from aerodelta.qualified import for_model, resolve


@dataclass
class ReportContext:
    """Inputs of the report, prepared once.

    Attributes
    ----------
    model
        The fitted Δ model.
    data
        :func:`aerodelta.fit.model_frame` of the ingested records plus ``<C>_qual`` and
        ``<C>_ext`` (= qualified + blended Δ, roll-off off) for each modelled coefficient.
    params
        Per-bin estimates (``model.params.parquet``), or ``None``.
    coefficients
        Coefficients both in the model and the data.
    held_out
        Maneuvers not used in the fit.
    qualified
        Source of the qualified coefficients: ``"columns"``, ``"adx37"`` or a DAVE-ML path.
    diagnosis
        The parsed ``diagnosis.json`` (schema ``aerodelta.diagnosis/1``), or ``None``.
    """

    model: DeltaModel
    data: pl.DataFrame
    params: pl.DataFrame | None
    coefficients: list[str]
    held_out: list[str]
    qualified: str
    diagnosis: dict[str, Any] | None = None
    stall_alpha_deg: dict[float, float] = field(default_factory=dict)

    @property
    def flaps(self) -> list[float]:
        """Flap settings present in the data, deg."""
        return sorted(float(f) for f in self.data["flap_deg"].unique().drop_nulls())


def resolve_qualified(data: pl.DataFrame, qualified: str, model: DeltaModel | None = None) -> str:
    """The qualified model to compare with: ``qualified`` when named; for ``"auto"`` the one
    the fit recorded (``provenance.qualified``; a DAVE-ML file must be named again), else
    :func:`aerodelta.qualified.resolve`'s choice (refused for data neither carrying ``*_sim``
    columns nor flown on the virtual aircraft)."""
    spec = model.to_spec() if model else {}
    q = str(for_model(spec, qualified, "name it again for the report (--qualified FILE.dml)"))
    return resolve(data, "auto").source if q == "auto" else q


def build_context(
    model: DeltaModel,
    data: pl.DataFrame,
    *,
    params: pl.DataFrame | None = None,
    held_out: Sequence[str] = (),
    qualified: str = "auto",
    diagnosis: dict[str, Any] | None = None,
) -> ReportContext:
    """Evaluate the qualified and extended models along the records (thesis Section 4.1).

    The extended coefficient is ``C_ext = C_qual + w(alpha) ΔC`` (Eq. 3.12) without the
    stochastic roll-off, as the thesis compares time histories to check the deterministic part.
    """
    need = ["maneuver_id", "t", "alpha_deg", "flap_deg"]
    missing = [c for c in need if c not in data.columns]
    if missing:
        raise DataError(f"report: the data lack {missing}; pass the output of aerodelta ingest")
    df = model_frame(data)
    mode = resolve_qualified(df, qualified, model)
    q = qualified_coefficients(df, mode)
    ev = model.evaluate(df)
    coefs = [c for c in COEFFICIENTS if c in model.coefficients and f"{c}_meas" in df.columns]
    cols = []
    for c in coefs:
        cols.append(q[f"{c}_qual"])
        cols.append((q[f"{c}_qual"] + ev[f"d{c}_blended"]).alias(f"{c}_ext"))
        cols.append(ev[f"w_{c}"])
    df = df.with_columns(cols).with_columns(pl.col("maneuver_id").cast(pl.Utf8))
    ids = set(df["maneuver_id"].unique().to_list())
    unknown = sorted(set(held_out) - ids)
    if unknown:
        raise DataError(f"report: held-out maneuvers {unknown[:5]} are not in the data")
    stall = (model.to_spec().get("provenance") or {}).get("stall_alpha_deg") or {}
    return ReportContext(
        model=model,
        data=df,
        params=params,
        coefficients=coefs,
        held_out=sorted(set(held_out)),
        qualified=mode,
        diagnosis=diagnosis,
        stall_alpha_deg={float(k): float(v) for k, v in stall.items()},
    )


def load_params(model_path: Path) -> pl.DataFrame | None:
    """The per-bin estimates written beside a model file (``<model>.params.parquet``)."""
    p = model_path.with_suffix(".params.parquet")
    if not p.exists():
        return None
    check_params(model_path, p)
    return pl.read_parquet(p)
