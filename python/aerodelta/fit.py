"""Δ-model identification end to end (thesis Sections 3.3-3.6).

Per flap setting and per coefficient (Cl, Cn, CY): the qualified-model error
``z = C_meas - C_qualified`` (Eq. 3.5) is regressed bin by bin in angle of attack on the
regressors of the postulated Δ model (Eq. 3.14, 3.21, 3.22 by default) by equation-error least
squares (Eq. 3.10); each parameter of each bin carries conventional and coloured-residual
standard errors and is marked not identifiable (low excitation, collinearity, too few points)
instead of silently kept; identified bins are smoothed against alpha with a ``csaps`` spline
(Eq. 3.13, p = 0.4), clipped 10 deg past stall and blended in between ``alpha_l`` and
``alpha_u`` (Eq. 3.12). The result is an extended model, ``C_ext = C_qual + w(alpha) dC``.

Angles in the regressors are in degrees (``beta_deg``, ``da_deg``, ...), so each Δ derivative
is per degree; non-dimensional rates ``phat``, ``rhat`` are per radian of ``pb/2V``.
"""

from __future__ import annotations

import hashlib
import math
import sys
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
from tqdm import tqdm

from aerodelta import _core
from aerodelta._core import __version__
from aerodelta.exceptions import DataError
from aerodelta.model import SCHEMA, DeltaModel

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

COEFFICIENTS = ("Cl", "Cn", "CY")

#: Default Δ-model structures: thesis Eq. 3.14 (Cl), 3.21 (Cn) and 3.22 (CY). ``deadband(da, 2)``
#: is the aileron dead-band spline of Eq. 3.15-3.16; ``ds_deg`` the combined roll spoiler.
DEFAULT_STRUCTURES: dict[str, list[tuple[str, str]]] = {
    "Cl": [
        ("dCl_0", "1"),
        ("dCl_beta", "beta_deg"),
        ("dCl_p", "phat"),
        ("dCl_r", "rhat"),
        ("dCl_da", "deadband(da_deg, 2)"),
        ("dCl_dr", "dr_deg"),
        ("dCl_ct", "ct_left + ct_right"),
        ("dCl_ctdiff", "ct_diff"),
        ("dCl_ds", "ds_deg"),
        ("dCl_betadot", "betadot_dps"),
        ("dCl_alphadot_ds", "alphadot_dps * ds_deg"),
    ],
    "Cn": [
        ("dCn_0", "1"),
        ("dCn_beta", "beta_deg"),
        ("dCn_p", "phat"),
        ("dCn_r", "rhat"),
        ("dCn_da", "deadband(da_deg, 2)"),
        ("dCn_dr", "dr_deg"),
        ("dCn_ct", "ct_left + ct_right"),
        ("dCn_ctdiff", "ct_diff"),
        ("dCn_ds", "ds_deg"),
    ],
    "CY": [
        ("dCY_0", "1"),
        ("dCY_beta", "beta_deg"),
        ("dCY_p", "phat"),
        ("dCY_r", "rhat"),
        ("dCY_da", "deadband(da_deg, 2)"),
        ("dCY_dr", "dr_deg"),
        ("dCY_ct", "ct_left + ct_right"),
        ("dCY_ds", "ds_deg"),
        ("dCY_alphadot_beta", "alphadot_dps * beta_deg"),
        ("dCY_betadot", "betadot_dps"),
        ("dCY_alphadot_betadot", "alphadot_dps * betadot_dps"),
        ("dCY_beta_ds", "beta_deg * ds_deg"),
    ],
}


@dataclass(frozen=True)
class FitConfig:
    """Settings of :func:`fit` (all optional; defaults follow the thesis).

    Attributes
    ----------
    structures
        Regressors per coefficient: ``{"Cl": [(name, expression), ...], ...}``.
    width_deg
        Nominal alpha bin width, deg (Section 3.3.1: 0.2).
    min_points_per_param
        Points per parameter required in a bin (thesis: about 10).
    min_maneuvers
        Distinct maneuvers required in a bin.
    max_width_deg
        Widest bin allowed when merging sparse bins, deg (``None``: no cap).
    colored
        Report standard errors corrected for coloured residuals.
    min_excitation
        A regressor whose in-bin spread is below this fraction of its spread over the flap's
        data is "low excitation" in that bin and its parameter is not identified there.
    p
        Smoothing parameter of Eq. 3.13 (alpha in deg).
    weighted
        Weight bins by 1/SE² in the smoothing spline.
    grid_step_deg
        Table spacing of the smoothed parameters, deg.
    past_stall_deg
        Tables are clipped this far past the stall alpha and held beyond (Section 3.4: 10).
    stall_alpha_deg
        Stall alpha per flap, deg; detected from the data (maximum of C_L) when absent.
    alpha_l_deg, alpha_u_deg
        Blending limits of Eq. 3.12, deg (one value for all flaps, or per flap).
    min_identified_bins
        A parameter identified in fewer bins is set to zero (the qualified model is kept).
    """

    structures: Mapping[str, Sequence[tuple[str, str]]] = field(
        default_factory=lambda: {k: list(v) for k, v in DEFAULT_STRUCTURES.items()}
    )
    width_deg: float = 0.2
    min_points_per_param: int = 10
    min_maneuvers: int = 2
    max_width_deg: float | None = 4.0
    colored: bool = True
    min_excitation: float = 0.05
    p: float = 0.4
    weighted: bool = False
    grid_step_deg: float = 0.5
    past_stall_deg: float = 10.0
    stall_alpha_deg: Mapping[float, float] = field(default_factory=dict)
    alpha_l_deg: float | Mapping[float, float] = 8.0
    alpha_u_deg: float | Mapping[float, float] = 10.0
    min_identified_bins: int = 4

    @classmethod
    def from_toml(cls, path: str | Path) -> FitConfig:
        """Read a configuration file.

        The file may hold the scalar settings at top level and a ``[structures]`` table of
        ``coefficient = [["name", "expression"], ...]``; ``[stall_alpha_deg]`` maps flap
        (as a string key) to alpha.
        """
        p = Path(path)
        try:
            raw = tomllib.loads(p.read_text())
        except (OSError, tomllib.TOMLDecodeError) as e:
            raise DataError(f"{p}: cannot read the fit configuration: {e}") from e
        kwargs: dict[str, Any] = {}
        known = set(cls.__dataclass_fields__)
        for k, v in raw.items():
            if k not in known:
                raise DataError(f"{p}: unknown setting '{k}'; valid settings are {sorted(known)}")
            if k == "structures":
                kwargs[k] = {c: [tuple(t) for t in terms] for c, terms in v.items()}
            elif k == "stall_alpha_deg":
                kwargs[k] = {float(f): float(a) for f, a in v.items()}
            else:
                kwargs[k] = v
        return cls(**kwargs)


def _per_flap(value: float | Mapping[float, float], flap: float, name: str) -> float:
    if isinstance(value, Mapping):
        if flap not in value:
            raise DataError(f"{name}: no value for flap {flap:g}; give one per flap setting")
        return float(value[flap])
    return float(value)


def model_frame(data: pl.DataFrame) -> pl.DataFrame:
    """The ingested data with CG-referred angles as ``alpha_deg``/``beta_deg``.

    The ingestion keeps the vane angles as ``alpha_deg``/``beta_deg`` and adds the CG values
    ``alpha_cg_deg``/``beta_cg_deg``; the model (and a simulator using it) works at the CG.
    """
    out = data
    for a in ("alpha", "beta"):
        cg = f"{a}_cg_deg"
        if cg in out.columns:
            out = out.drop(f"{a}_deg").rename({cg: f"{a}_deg"})
    return out


def qualified_coefficients(data: pl.DataFrame, qualified: str = "auto") -> pl.DataFrame:
    """The simulator's coefficients along the records: ``Cl_qual``, ``Cn_qual``, ``CY_qual``.

    Parameters
    ----------
    data
        A :func:`model_frame` of ingested records.
    qualified
        ``"columns"``: the records' ``Cl_sim``, ``Cn_sim``, ``CY_sim`` (a black-box simulator);
        ``"adx37"``: the built-in representative aircraft's qualified model evaluated at the
        measured states; ``"auto"``: columns when present, else ``"adx37"``.
    """
    sim_cols = [f"{c}_sim" for c in COEFFICIENTS]
    if qualified == "auto":
        qualified = "columns" if all(c in data.columns for c in sim_cols) else "adx37"
    if qualified == "columns":
        missing = [c for c in sim_cols if c not in data.columns]
        if missing:
            raise DataError(
                f"qualified='columns' but the records lack {missing}; add the simulator's "
                "predictions or use qualified='adx37'"
            )
        return data.select([pl.col(f"{c}_sim").alias(f"{c}_qual") for c in COEFFICIENTS])
    if qualified != "adx37":
        raise DataError(f"qualified='{qualified}': use 'auto', 'columns' or 'adx37'")
    names = [
        "alpha_deg", "beta_deg", "phat", "qhat", "rhat", "alphadot_dps", "betadot_dps",
        "da_deg", "de_deg", "dr_deg", "dsl_deg", "dsr_deg", "flap_deg", "ct_left", "ct_right",
        "tas_mps",
    ]  # fmt: skip
    cols = {}
    for n in names:
        if n in data.columns:
            cols[n] = np.ascontiguousarray(data[n].cast(pl.Float64).fill_null(0.0).to_numpy())
        elif n in ("dsl_deg", "dsr_deg", "de_deg"):
            cols[n] = np.zeros(data.height)
    cl, cn, cy = _core.qualified_lateral_adx37(cols)
    return pl.DataFrame({"Cl_qual": cl, "Cn_qual": cn, "CY_qual": cy})


def stall_alpha(data: pl.DataFrame, bin_deg: float = 0.5, min_points: int = 50) -> float:
    """Stall angle of attack, deg: the alpha bin of maximum mean lift coefficient.

    ``C_L = -C_Z cos(alpha) + C_X sin(alpha)`` from the measured body coefficients.
    """
    a = np.radians(data["alpha_deg"].to_numpy())
    cl = -data["CZ_meas"].to_numpy() * np.cos(a) + data["CX_meas"].to_numpy() * np.sin(a)
    df = pl.DataFrame({"b": np.floor(data["alpha_deg"].to_numpy() / bin_deg), "cl": cl})
    g = (
        df.drop_nans()
        .group_by("b")
        .agg(pl.col("cl").mean().alias("cl"), pl.len().alias("n"))
        .filter(pl.col("n") >= min_points)
        .sort("cl", descending=True)
    )
    if g.height == 0:
        raise DataError("cannot detect the stall alpha: no alpha bin holds enough points")
    return float((g["b"][0] + 0.5) * bin_deg)


@dataclass(frozen=True)
class FitResult:
    """The outcome of :func:`fit`: the model and every per-bin estimate behind it.

    Attributes
    ----------
    model
        The Δ model (save it with ``result.model.save(path)``).
    bins
        One row per coefficient, flap and alpha bin: edges (deg), points, maneuvers, R²,
        condition number, residual std, note.
    params
        One row per coefficient, flap, bin and parameter: estimate, standard errors
        (conventional and corrected for coloured residuals), t, partial F, excitation, VIF,
        ``identifiable`` and a ``note`` saying why not.
    consistency
        Adjacent-bin consistency per coefficient, flap and parameter (Section 3.3.4).
    smoothed
        The smoothed parameter tables per coefficient, flap and parameter.
    stall_alpha_deg
        Stall alpha used per flap, deg.
    """

    model: DeltaModel
    bins: pl.DataFrame
    params: pl.DataFrame
    consistency: pl.DataFrame
    smoothed: pl.DataFrame
    stall_alpha_deg: dict[float, float]

    def summary(self) -> pl.DataFrame:
        """Per-parameter table (statsmodels-like), sorted by coefficient, flap, alpha."""
        return self.params.sort(["coefficient", "flap_deg", "alpha_lo_deg", "param"])

    def identified_fraction(self) -> pl.DataFrame:
        """Share of fitted bins in which each parameter is identified, per coefficient/flap."""
        return (
            self.params.group_by(["coefficient", "flap_deg", "param"])
            .agg(pl.col("identifiable").mean().alias("identified_fraction"))
            .sort(["coefficient", "flap_deg", "param"])
        )


def _maneuver_codes(data: pl.DataFrame) -> np.ndarray:
    return np.ascontiguousarray(
        data["maneuver_id"].cast(pl.Utf8).cast(pl.Categorical).to_physical().to_numpy(),
        dtype=np.uint64,
    )


def fit(
    data: pl.DataFrame,
    *,
    qualified: str = "auto",
    config: FitConfig | None = None,
    progress: bool = False,
) -> FitResult:
    """Identify the Δ model from ingested flight records.

    Parameters
    ----------
    data
        Output of :func:`aerodelta.ingest` (``.data``): measured coefficients ``*_meas``,
        CG angles, rates, controls, ``flap_deg`` and ``maneuver_id``.
    qualified
        Where the simulator's coefficients come from (see :func:`qualified_coefficients`).
    config
        Settings (defaults follow the thesis).
    progress
        Show a progress bar on stderr.

    Returns
    -------
    FitResult
    """
    cfg = config or FitConfig()
    for c in cfg.structures:
        if c not in COEFFICIENTS:
            raise DataError(f"structures: unknown coefficient '{c}'; use {list(COEFFICIENTS)}")
    df = model_frame(data)
    needed = ["alpha_deg", "flap_deg", "maneuver_id"] + [f"{c}_meas" for c in cfg.structures]
    missing = [c for c in needed if c not in df.columns]
    if missing:
        raise DataError(f"fit: the data lack {missing}; run aerodelta.ingest first")
    df = pl.concat([df, qualified_coefficients(df, qualified)], how="horizontal")
    flaps = sorted(float(f) for f in df["flap_deg"].unique().drop_nulls())
    bins_rows: list[dict[str, Any]] = []
    param_rows: list[dict[str, Any]] = []
    cons_rows: list[dict[str, Any]] = []
    smooth_rows: list[dict[str, Any]] = []
    stall: dict[float, float] = {}
    tables: dict[str, dict[str, dict[float, tuple[np.ndarray, np.ndarray]]]] = {}

    tasks = [(f, c) for f in flaps for c in cfg.structures]
    bar = None
    if progress:
        bar = tqdm(total=len(tasks), desc="fit", unit="fit", file=sys.stderr)
    for flap in flaps:
        d = df.filter(pl.col("flap_deg") == flap)
        stall[flap] = float(cfg.stall_alpha_deg.get(flap, stall_alpha(d)))
        alpha_max = stall[flap] + cfg.past_stall_deg
        # every numeric column as float64 once per flap; each coefficient takes its rows
        full = {
            c: d[c].cast(pl.Float64).fill_null(np.nan).to_numpy()
            for c in d.columns
            if d[c].dtype.is_numeric() and c != "maneuver_id"
        }
        codes = _maneuver_codes(d)
        for coef in cfg.structures:
            regs = [(str(n), str(e)) for n, e in cfg.structures[coef]]
            z_all = full[f"{coef}_meas"] - full[f"{coef}_qual"]
            keep = np.isfinite(z_all) & np.isfinite(full["alpha_deg"])
            cols = {c: np.ascontiguousarray(v[keep]) for c, v in full.items()}
            z = np.ascontiguousarray(z_all[keep])
            out = _core.identify_bins(
                regs, cols, z, cols["alpha_deg"], np.ascontiguousarray(codes[keep]),
                cfg.width_deg, cfg.min_points_per_param, cfg.min_maneuvers, cfg.max_width_deg,
                cfg.colored, cfg.min_excitation, cfg.p, cfg.weighted, cfg.grid_step_deg,
                alpha_max, cfg.min_identified_bins,
            )  # fmt: skip
            names: list[str] = out["names"]
            nb, npar = len(out["alpha_lo"]), len(names)
            shape = (nb, npar)
            est = np.asarray(out["params"]).reshape(shape)
            se = np.asarray(out["std_err"]).reshape(shape)
            sec = np.asarray(out["std_err_colored"]).reshape(shape)
            pf = np.asarray(out["partial_f"]).reshape(shape)
            exc = np.asarray(out["excitation"]).reshape(shape)
            vif = np.asarray(out["vif"]).reshape(shape)
            ident = np.asarray(out["identifiable"], dtype=bool).reshape(shape)
            notes = np.asarray(out["notes"], dtype=object).reshape(shape)
            for b in range(nb):
                bins_rows.append(
                    {
                        "coefficient": coef, "flap_deg": flap,
                        "alpha_lo_deg": out["alpha_lo"][b], "alpha_hi_deg": out["alpha_hi"][b],
                        "n": int(out["n"][b]), "n_maneuvers": int(out["n_maneuvers"][b]),
                        "r2": out["r2"][b], "condition_number": out["condition_number"][b],
                        "residual_std": out["residual_std"][b], "note": out["bin_note"][b],
                    }
                )  # fmt: skip
                for j, name in enumerate(names):
                    param_rows.append(
                        {
                            "coefficient": coef, "flap_deg": flap, "param": name,
                            "regressor": regs[j][1],
                            "alpha_lo_deg": out["alpha_lo"][b], "alpha_hi_deg": out["alpha_hi"][b],
                            "estimate": est[b, j], "std_err": se[b, j],
                            "std_err_colored": sec[b, j],
                            "t": est[b, j] / se[b, j] if se[b, j] > 0 else math.nan,
                            "partial_f": pf[b, j], "excitation": exc[b, j], "vif": vif[b, j],
                            "identifiable": bool(ident[b, j]), "note": str(notes[b, j]),
                        }
                    )  # fmt: skip
            for j, name in enumerate(names):
                cons_rows.append(
                    {
                        "coefficient": coef, "flap_deg": flap, "param": name,
                        "scatter": out["consistency_scatter"][j],
                        "step_z": out["consistency_step_z"][j],
                        "pairs": out["consistency_pairs"][j],
                    }
                )  # fmt: skip
            for name, grid, values, used, note in out["smoothed"]:
                tables.setdefault(coef, {}).setdefault(name, {})[flap] = (
                    np.asarray(grid),
                    np.asarray(values),
                )
                for a, v in zip(grid, values, strict=True):
                    smooth_rows.append(
                        {
                            "coefficient": coef, "flap_deg": flap, "param": name,
                            "alpha_deg": a, "value": v, "bins_used": used, "note": note,
                        }
                    )  # fmt: skip
            if bar is not None:
                bar.update(1)
    if bar is not None:
        bar.close()

    spec = _model_spec(cfg, flaps, tables, stall, data)
    return FitResult(
        model=DeltaModel.from_spec(spec, "fitted model"),
        bins=pl.DataFrame(bins_rows),
        params=pl.DataFrame(param_rows),
        consistency=pl.DataFrame(cons_rows),
        smoothed=pl.DataFrame(smooth_rows),
        stall_alpha_deg=stall,
    )


def _data_hash(data: pl.DataFrame) -> str:
    h = hashlib.sha256()
    h.update(str(data.shape).encode())
    for c in sorted(data.columns):
        h.update(c.encode())
        s = data[c]
        if s.dtype.is_numeric():
            h.update(
                np.ascontiguousarray(s.cast(pl.Float64).fill_null(np.nan).to_numpy()).tobytes()
            )
        else:
            h.update("\x1f".join(map(str, s.to_list())).encode())
    return h.hexdigest()


def _model_spec(
    cfg: FitConfig,
    flaps: list[float],
    tables: dict[str, dict[str, dict[float, tuple[np.ndarray, np.ndarray]]]],
    stall: dict[float, float],
    data: pl.DataFrame,
) -> dict[str, Any]:
    coefficients: dict[str, Any] = {}
    for coef, params in tables.items():
        terms = []
        regs = dict(cfg.structures[coef])
        for name, per_flap in params.items():
            grid = np.unique(np.concatenate([g for g, _ in per_flap.values()]))
            # np.interp holds the end values: each flap's table is reproduced at its own nodes
            rows = [
                np.interp(grid, *per_flap[f]).tolist() if f in per_flap else [0.0] * len(grid)
                for f in flaps
            ]
            terms.append(
                {"name": name, "regressor": regs[name], "alpha_deg": grid.tolist(), "values": rows}
            )
        coefficients[coef] = {
            "terms": terms,
            "alpha_l_deg": [_per_flap(cfg.alpha_l_deg, f, "alpha_l_deg") for f in flaps],
            "alpha_u_deg": [_per_flap(cfg.alpha_u_deg, f, "alpha_u_deg") for f in flaps],
        }
    return {
        "schema": SCHEMA,
        "flaps_deg": flaps,
        "alpha_channel": "alpha_deg",
        "flap_channel": "flap_deg",
        "coefficients": coefficients,
        "provenance": {
            "library": f"aerodelta {__version__}",
            "data_sha256": _data_hash(data),
            "rows": data.height,
            "maneuvers": int(data["maneuver_id"].n_unique()),
            "stall_alpha_deg": {str(k): v for k, v in stall.items()},
            "config": {
                k: (v if not isinstance(v, Mapping) else {str(a): b for a, b in v.items()})
                for k, v in cfg.__dict__.items()
                if k != "structures"
            }
            | {"structures": {c: [list(t) for t in s] for c, s in cfg.structures.items()}},
        },
    }


def theil_inequality(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Theil inequality coefficient ``rms(y - ŷ) / (rms(y) + rms(ŷ))`` (0 perfect, 1 useless)."""
    ok = np.isfinite(measured) & np.isfinite(predicted)
    y, yh = measured[ok], predicted[ok]
    den = np.sqrt(np.mean(y**2)) + np.sqrt(np.mean(yh**2))
    return float(np.sqrt(np.mean((y - yh) ** 2)) / den) if den > 0 else math.nan


def validate_model(
    model: DeltaModel, data: pl.DataFrame, *, qualified: str = "auto"
) -> pl.DataFrame:
    """Qualified vs extended model against measured coefficients, per coefficient.

    Returns a frame with RMS error and Theil inequality coefficient (TIC) of the qualified and of
    the extended model (``C_qual + w dC``), and their ratio, on the given records (use maneuvers
    held out of the fit).
    """
    df = model_frame(data)
    df = pl.concat([df, qualified_coefficients(df, qualified)], how="horizontal")
    ev = model.evaluate(df)
    rows = []
    for c in model.coefficients:
        meas = df[f"{c}_meas"].to_numpy()
        qual = df[f"{c}_qual"].to_numpy()
        ext = qual + ev[f"d{c}_blended"].to_numpy()
        ok = np.isfinite(meas) & np.isfinite(ext)
        rows.append(
            {
                "coefficient": c,
                "rms_qualified": float(np.sqrt(np.mean((meas[ok] - qual[ok]) ** 2))),
                "rms_extended": float(np.sqrt(np.mean((meas[ok] - ext[ok]) ** 2))),
                "tic_qualified": theil_inequality(meas, qual),
                "tic_extended": theil_inequality(meas, ext),
            }
        )
    return pl.DataFrame(rows).with_columns(
        (pl.col("tic_extended") / pl.col("tic_qualified")).alias("tic_ratio")
    )
