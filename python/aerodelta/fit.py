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

import json
import math
import numbers
import re
import sys
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any, TypeVar

import numpy as np
import polars as pl
from tqdm import tqdm

from aerodelta import _core
from aerodelta._core import __version__
from aerodelta._fingerprint import data_sha256
from aerodelta._groups import Groups, maneuver_keys
from aerodelta._threads import engine_threads
from aerodelta._toml import read_toml
from aerodelta.exceptions import DataError
from aerodelta.model import SCHEMA, DeltaModel
from aerodelta.qualified import describe, for_model, resolve
from aerodelta.smoother_match import through_smoother

COEFFICIENTS = ("Cl", "Cn", "CY")

T = TypeVar("T")

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


#: Trial regressors of the structure selection, per coefficient ``C``: named ``dC_<suffix>``.
#: The union of the thesis structures (Eq. 3.14, 3.21, 3.22) and of Klein's trial pool
#: for lateral stall modelling (thesis Section 2.2: beta, p, r, delta_a, delta_r, beta^2,
#: beta^3). Klein's products with alpha (beta*alpha, p*alpha^2, alpha^3, ...) are left out:
#: alpha is nearly constant inside a 0.2 deg bin, so each is collinear with its alpha-free
#: term; the bin-by-bin fit gives every parameter its alpha dependence instead. ``|beta|``
#: joins them for tables with a kink at beta = 0 (piecewise linear in beta, as JSBSim's and
#: DAVE-ML's breakpoint tables are: the DHC-6's Clb(beta, alpha) changes slope at zero by a
#: factor of five): with it, ``beta`` keeps the mean of the two one-sided slopes, the
#: derivative at zero a central difference gives, and the intercept the value at zero;
#: otherwise the kink leaks into the intercept and into terms correlated with |beta| (rates in
#: wing rock). The stepwise regression's collinearity guard keeps it and ``beta^2`` from
#: entering together. The order is the priority of :func:`fit`'s collinearity rule (a term
#: collinear with an earlier one leaves the structure first): ``|beta|`` comes before
#: ``beta^2`` (correlation about 0.95), since :attr:`FitConfig.beta_kink` keeps it with
#: ``beta``.
CANDIDATE_TERMS: list[tuple[str, str]] = [
    ("0", "1"),
    ("beta", "beta_deg"),
    ("p", "phat"),
    ("r", "rhat"),
    ("da", "deadband(da_deg, 2)"),
    ("dr", "dr_deg"),
    ("ct", "ct_left + ct_right"),
    ("ctdiff", "ct_diff"),
    ("ds", "ds_deg"),
    ("betadot", "betadot_dps"),
    ("alphadot_ds", "alphadot_dps * ds_deg"),
    ("alphadot_beta", "alphadot_dps * beta_deg"),
    ("alphadot_betadot", "alphadot_dps * betadot_dps"),
    ("beta_ds", "beta_deg * ds_deg"),
    ("beta_abs", "abs(beta_deg)"),
    ("beta2", "beta_deg^2"),
    ("beta3", "beta_deg^3"),
]

#: Companion terms of the selection (:attr:`FitConfig.beta_kink`), as regressor expressions
#: without spaces: when it keeps the first, it adds the second if that costs less than one
#: standard error of held-out error.
BETA_KINK: tuple[tuple[str, str], ...] = (("beta_deg", "abs(beta_deg)"),)

#: Default candidate pools of the structure selection.
DEFAULT_CANDIDATES: dict[str, list[tuple[str, str]]] = {
    c: [(f"d{c}_{k}", e) for k, e in CANDIDATE_TERMS] for c in ("Cl", "Cn", "CY")
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
    min_excitation_snr
        Nor one whose in-bin spread is below this multiple of its noise floor (the white noise
        its second differences imply within each maneuver, ``aero_core::identify::
        noise_floor``): a control held still through the whole campaign moves only by its
        sensor noise, which the relative rule above cannot see. It reads the time structure of
        each maneuver's samples (rows in time order, as ingested); for regressors drawn
        independently at every row (not flight data), set it to 0.
    min_maneuvers_identified
        A bin with fewer maneuvers fits its parameters but marks them not identified: they
        would carry those maneuvers' own errors (sensor biases, gusts), and a bootstrap over
        so few maneuvers cannot measure their spread (on 20 virtual campaigns, the bins with 3
        maneuvers or fewer held the truth inside their bootstrap bands about half the time).
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
    max_vif
        Collinearity limit (Klein & Morelli 2006, Section 5.4.1: 10). A regressor whose
        variance inflation factor in a bin exceeds it is not identified there, with a note
        naming the regressors its estimate trades against ("collinear with 'dCl_p' ..."):
        its estimate would split one effect between collinear terms (at high alpha β̇ carries
        nearly the same information as p̂ sin α − r̂ cos α). The stepwise selection lets no
        candidate enter a bin that would take a selected term past it. ``None``: only the
        condition-index rule (near-exact dependencies).
    selection
        Structure selection per coefficient and flap (:mod:`aero_core::select`):
        ``"stepwise"`` (forward stepwise regression with partial F, Klein & Morelli 2006
        Section 5.4.2), ``"mof"`` (multivariate orthogonal functions with the predicted squared
        error, Morelli 1995) or ``None`` to fit ``structures`` as given. The number of
        regressors kept is chosen by cross-validation over maneuvers.
    candidates
        Trial regressors per coefficient for the selection (``None``: :data:`DEFAULT_CANDIDATES`).
    f_in, f_out
        Partial F to enter and to stay in the stepwise regression (SIDPAC: 4), after scaling by
        the bin's coloured-residual variance inflation.
    min_selected_bins
        A candidate selected in fewer bins of a flap is not kept for that flap.
    min_maneuvers_selection
        A flap with fewer maneuvers fits ``structures`` as given instead of selecting: with
        ``cv_folds`` folds of two or three maneuvers the cross-validated errors of competing
        structures differ by less than their scatter, and the one-standard-error rule then
        keeps the intercept alone (measured on 40-maneuver campaigns, 8 per flap: held-out
        C_l TIC ratios of 0.57-1.04 with selection, 0.30-0.55 with the thesis structure). The
        ``structure`` table says so in its ``note``.
    cv_folds
        Folds of whole maneuvers of the cross-validation.
    seed
        Seed of the fold assignment and of the bootstrap.
    bootstrap
        Bootstrap replicates over maneuvers for confidence bands (0: none, the fast default;
        100-200 give stable 95 % bands).
    band_level
        Confidence level of the bands.
    bootstrap_selection
        With a selection, each bootstrap replicate selects the structure again on its
        resampled maneuvers (``aero_core::bootstrap::Reselect``): a kept term the replicate
        drops is zero there, so the bands carry the selection's own uncertainty (a band
        computed for a structure chosen on the same data lacks it). Over 20 virtual campaigns
        the per-bin bands then held the truth in 92 %, 92 % and 91 % of the identified bins
        (C_l, C_n, C_Y; seeds 201-220), against 78 %, 85 % and 89 % with ``False`` (the chosen
        structure refitted in every replicate); it costs about 11 s for 100 replicates of a
        200-maneuver campaign on 2 cores, against 1 s without a bootstrap
        (``benchmarks/bench_fit.py``, ``docs/identification.md``).
    band_hz
        Band-limited equation error (``aero_core::band``), off by default: the qualified-model
        error and every regressor are low-passed at this cut-off, Hz (one value, or one per
        coefficient), with one zero-phase filter per maneuver before the bins are fitted. The
        measured coefficients come from rates smoothed at 2-4 Hz (Eq. 3.2-3.4), while the
        controls and the qualified model along them keep their high band, and the difference
        reads as a Δ correlated with the controls. Measured on 20 virtual campaigns (truth
        inside the per-bin 95 % bootstrap bands, alpha >= 8 deg): with the thesis structures
        (``selection=None``) 2.5 Hz on C_n took the coverage from 89.7 % to 91.7 % (ΔC_n_δr
        82.7 % to 90.9 %); with the stepwise selection it lowered it (88.1 % to 85.0 %, the
        selection then keeping more terms); at 2.5 Hz C_l loses the band its roll damping is
        identified from (the standard error of ΔC_l_p doubled). Needs the time column ``t``.
    nested_cv
        Score the structure selection by nested cross-validation: the whole selection reruns
        once per fold on the other folds' maneuvers, and the structure it chooses predicts the
        fold (``cross_validation`` row ``selected_outer``). The selection's own folds chose the
        structure, so their score of it is optimistic; this one is not. Costs ``cv_folds``
        more selections per flap and coefficient.
    chain_calibration
        Pass the qualified model through the measurement chain before it is subtracted
        (:func:`calibrate_chain`): the measured coefficients come from central differences of
        sampled, smoothed rates and from sensors with their own timing, so they are the true
        coefficient seen through a short filter (a time skew τ and a second-order smoothing
        κ), while the qualified model is evaluated at each sample's instant. The difference,
        ``(H - 1) C_qual``, scales with the whole aircraft's coefficient, not with the Δ, and
        correlates with every regressor that moves quickly (β̇, p̂, the aileron): on the JSBSim
        DHC-6 it was what the selection kept as ΔC_n_β̇ and ΔC_l_δa. τ and κ are estimated per
        coefficient where the qualified model is trusted (alpha below ``alpha_l_deg``) by
        regressing ``C_meas - C_qual`` on ``[1, dC_qual/dt, d²C_qual/dt²]`` (beside the
        structure's regressors when ``selection`` is ``None``), and
        ``C_qual + τ dC_qual/dt + κ d²C_qual/dt²`` replaces ``C_qual`` in every bin, the
        cross-validation and the bootstrap. Needs the time column ``t``; each estimate is
        listed in the notes. Measured on JSBSim report seeds 401-410 (``docs/identification.md``):
        DHC-6 zero-truth terms significant in 31 % → 10 % (C_l) and 26 % → 3.7 % (C_n) of their
        bins, F-15 ΔC_l_p 1.13 → 1.08 × its truth.
    smoother_match
        Pass the qualified model, maneuver by maneuver, through the smoother weights the
        ingestion applied to the channel each measured coefficient comes from (C_Y: ``ay``,
        C_l: ``p``, C_n: ``r``; :mod:`aerodelta.smoother_match`), before the chain calibration:
        the measurement lost what lies above its channel's data-chosen cut-off (about 2 Hz for
        a noisy lateral accelerometer), the model evaluated along the records did not, and the
        difference of a fast transient reads as a Δ. Maneuvers ingested without smoothing, or
        changed since, are left at full band (counted in the notes).
    beta_kink
        When the selection keeps ``beta``, add ``|beta|`` if the structure with it predicts the
        held-out maneuvers within one standard error of the one without (:data:`BETA_KINK`,
        ``aero_core::select::SelectOptions::companions``; in the reselecting bootstrap's
        replicates and the nested cross-validation alike). Flight
        simulator tables are piecewise linear in β with a breakpoint at zero (the JSBSim
        DHC-6's Clb changes slope there by a factor of five); without ``|beta|`` the kink goes
        into the intercept and the slope. When most samples have |β| < 1 deg the held-out
        error barely sees it, so the selection's prediction score drops ``|beta|`` while the
        reported ΔC_l_0 misses its truth (development seeds 1-20 of the DHC-6: 60 % of flap-20
        bins inside their 95 % intervals without the rule, 71 % with it). Where the aircraft
        has no kink, ``|beta|`` only adds variance and the one-standard-error test keeps it out.
        A bin that cannot identify ``|beta|`` (one-sided sideslip: collinear with ``beta``)
        says so in its note.
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
    min_excitation_snr: float = 3.0
    min_maneuvers_identified: int = 5
    p: float = 0.4
    weighted: bool = False
    grid_step_deg: float = 0.5
    past_stall_deg: float = 10.0
    stall_alpha_deg: Mapping[float, float] = field(default_factory=dict)
    alpha_l_deg: float | Mapping[float, float] = 8.0
    alpha_u_deg: float | Mapping[float, float] = 10.0
    min_identified_bins: int = 4
    max_vif: float | None = 10.0
    selection: str | None = "stepwise"
    candidates: Mapping[str, Sequence[tuple[str, str]]] | None = None
    f_in: float = 4.0
    f_out: float = 4.0
    min_selected_bins: int = 4
    min_maneuvers_selection: int = 15
    cv_folds: int = 5
    seed: int = 0
    bootstrap: int = 0
    band_level: float = 0.95
    bootstrap_selection: bool = True
    band_hz: float | Mapping[str, float] | None = None
    nested_cv: bool = True
    chain_calibration: bool = True
    smoother_match: bool = True
    beta_kink: bool = True

    def __post_init__(self) -> None:
        """Refuse a setting of the wrong type (a TOML string where a number belongs, a
        float count, a negative count) with one line naming it."""
        for name in _INT_SETTINGS:
            v = getattr(self, name)
            if isinstance(v, bool) or not isinstance(v, numbers.Integral) or v < 0:
                raise DataError(
                    f"fit setting {name} = {v!r}: give a whole number >= 0 (default "
                    f"{self.__dataclass_fields__[name].default!r})"
                )
        for name in _FLOAT_SETTINGS:
            v = getattr(self, name)
            if v is None and name in _OPTIONAL_SETTINGS:
                continue
            if isinstance(v, bool) or not isinstance(v, numbers.Real) or not math.isfinite(v):
                raise DataError(
                    f"fit setting {name} = {v!r}: give a finite number (default "
                    f"{self.__dataclass_fields__[name].default!r})"
                )
        for name in _BOOL_SETTINGS:
            v = getattr(self, name)
            if not isinstance(v, bool):
                raise DataError(f"fit setting {name} = {v!r}: give true or false")
        if self.cv_folds < 2:
            raise DataError(
                f"fit setting cv_folds = {self.cv_folds}: cross-validation needs at least 2 "
                "folds of maneuvers (default 5)"
            )
        if not 0.0 < self.band_level < 1.0:
            raise DataError(
                f"fit setting band_level = {self.band_level}: give a confidence level in (0, 1), "
                "e.g. 0.95"
            )
        if not 0.0 < self.p <= 1.0:
            raise DataError(
                f"fit setting p = {self.p}: the smoothing parameter of Eq. 3.13 lies in (0, 1] "
                "(thesis: 0.4)"
            )
        for name in ("alpha_l_deg", "alpha_u_deg"):
            v = getattr(self, name)
            vals = list(v.values()) if isinstance(v, Mapping) else [v]
            if any(
                isinstance(x, bool) or not isinstance(x, numbers.Real) or not math.isfinite(x)
                for x in vals
            ):
                raise DataError(
                    f"fit setting {name} = {v!r}: give an alpha in deg, or one per flap"
                )
        self._check_ranges()
        self._check_structures()

    def _check_ranges(self) -> None:
        """Refuse values outside their meaning (a bin of zero width, an unknown selection)."""
        for name in ("width_deg", "grid_step_deg", "f_in", "f_out"):
            if getattr(self, name) <= 0:
                raise DataError(f"fit setting {name} = {getattr(self, name)!r}: must be > 0")
        for name in ("past_stall_deg", "min_excitation", "min_excitation_snr"):
            if getattr(self, name) < 0:
                raise DataError(f"fit setting {name} = {getattr(self, name)!r}: must be >= 0")
        if self.max_width_deg is not None and self.max_width_deg < self.width_deg:
            raise DataError(
                f"fit setting max_width_deg = {self.max_width_deg!r}: the widest merged bin "
                f"cannot be narrower than width_deg = {self.width_deg!r}"
            )
        if self.max_vif is not None and self.max_vif <= 1.0:
            raise DataError(
                f"fit setting max_vif={self.max_vif!r}: a variance inflation factor is at least "
                "1; give a limit above 1 (Klein & Morelli: 10) or none"
            )
        if self.min_points_per_param < 1 or self.min_maneuvers < 1:
            name = "min_points_per_param" if self.min_points_per_param < 1 else "min_maneuvers"
            raise DataError(f"fit setting {name} = 0: must be at least 1")
        if self.selection not in (None, "stepwise", "mof"):
            raise DataError(
                f"fit setting selection={self.selection!r}: use 'stepwise', 'mof' or None "
                '("none" in a TOML file)'
            )
        bands = (
            dict(self.band_hz)
            if isinstance(self.band_hz, Mapping)
            else ({} if self.band_hz is None else {"": self.band_hz})
        )
        for c, b in bands.items():
            if c and c not in COEFFICIENTS:
                raise DataError(
                    f"fit setting band_hz: unknown coefficient '{c}'; use {list(COEFFICIENTS)}"
                )
            if isinstance(b, bool) or not isinstance(b, numbers.Real) or not 0 < b < math.inf:
                raise DataError(
                    f"fit setting band_hz{'.' + c if c else ''} = {b!r}: give a positive "
                    "cut-off in Hz (e.g. 2.5) or none"
                )
        if not isinstance(self.stall_alpha_deg, Mapping):
            raise DataError(
                f"fit setting stall_alpha_deg = {self.stall_alpha_deg!r}: give a table of flap = "
                'alpha, both in deg (e.g. [stall_alpha_deg] "10.0" = 17.5)'
            )
        for flap, a in self.stall_alpha_deg.items():
            if not all(
                isinstance(x, numbers.Real) and not isinstance(x, bool) and math.isfinite(x)
                for x in (flap, a)
            ):
                raise DataError(
                    f"fit setting stall_alpha_deg: {flap!r} = {a!r}: give flap = alpha, both in deg"
                )
        lo, hi = self.alpha_l_deg, self.alpha_u_deg
        flaps = {*(lo if isinstance(lo, Mapping) else ()), *(hi if isinstance(hi, Mapping) else ())}
        pairs = []
        for f in sorted(flaps) or [None]:
            a = lo.get(f) if isinstance(lo, Mapping) else lo
            b = hi.get(f) if isinstance(hi, Mapping) else hi
            if a is not None and b is not None:  # a flap one table lacks: refused when fitted
                pairs.append((f, a, b))
        for f, a, b in pairs:
            if a > b:
                at = "" if f is None else f" at flap {f:g}"
                raise DataError(
                    f"fit settings alpha_l_deg = {a:g} and alpha_u_deg = {b:g}{at}: the blend "
                    "starts at alpha_l_deg and ends at alpha_u_deg, so alpha_l_deg <= alpha_u_deg"
                )

    def _check_structures(self) -> None:
        """Refuse structures and candidate pools that are not ``{coefficient: [(name,
        expression), ...]}`` with known coefficients and one name per term."""
        for what, table in (("structures", self.structures), ("candidates", self.candidates)):
            if table is None:
                continue
            if not isinstance(table, Mapping):
                raise DataError(
                    f"fit setting {what} = {table!r}: give a table of coefficient = "
                    '[["name", "expression"], ...]'
                )
            for c, terms in table.items():
                if c not in COEFFICIENTS:
                    raise DataError(f"{what}: unknown coefficient '{c}'; use {list(COEFFICIENTS)}")
                ok = isinstance(terms, Sequence) and not isinstance(terms, str) and all(
                    isinstance(t, Sequence) and not isinstance(t, str) and len(t) == 2
                    and all(isinstance(x, str) and x.strip() for x in t)
                    for t in terms
                )  # fmt: skip
                if not ok:
                    raise DataError(
                        f'{what} {c} = {terms!r}: give a list of ["name", "expression"] '
                        "pairs of strings"
                    )
                names = [t[0] for t in terms]
                twice = sorted({n for n in names if names.count(n) > 1})
                if twice:
                    raise DataError(
                        f"{what} {c}: term name(s) {', '.join(twice)} given twice; name each "
                        "term once"
                    )

    @classmethod
    def from_toml(cls, path: str | Path) -> FitConfig:
        """Read a configuration file.

        The file may hold the scalar settings at top level, ``[structures]`` and
        ``[candidates]`` tables of ``coefficient = [["name", "expression"], ...]``;
        ``[stall_alpha_deg]`` maps flap (as a string key) to alpha; ``alpha_l_deg``,
        ``alpha_u_deg`` and ``band_hz`` take one value or a table (per flap, per coefficient).

        Raises
        ------
        DataError
            Naming the file and the setting (a file that cannot be read, a setting that is
            unknown, of the wrong type or out of range).
        InvalidInputError
            A regressor expression the engine cannot parse (too deep, unknown function),
            naming the file, coefficient and term.
        """
        p = Path(path)
        raw, _ = read_toml(p, "fit configuration")
        kwargs: dict[str, Any] = {}
        known = set(cls.__dataclass_fields__)
        for k, v in raw.items():
            if k not in known:
                raise DataError(f"{p}: unknown setting '{k}'; valid settings are {sorted(known)}")
            if k in ("structures", "candidates") and isinstance(v, dict):
                kwargs[k] = {
                    c: [tuple(t) if isinstance(t, list) else t for t in terms]
                    if isinstance(terms, list)
                    else terms
                    for c, terms in v.items()
                }
            elif k in ("selection", "band_hz", "max_vif") and isinstance(v, str):
                kwargs[k] = None if v.lower() == "none" else v
            elif k in ("stall_alpha_deg", "alpha_l_deg", "alpha_u_deg") and isinstance(v, dict):
                kwargs[k] = {_flap_key(p, k, f): a for f, a in v.items()}
            else:
                kwargs[k] = v
        try:
            cfg = cls(**kwargs)
        except DataError as e:
            raise DataError(f"{p}: {e}") from None
        for what in ("structures", "candidates"):
            table = getattr(cfg, what) if what in raw else None
            if table:
                _parse_regressors(table, f"{p} [{what}]")
        return cfg


def _flap_key(path: Path, setting: str, key: str) -> float:
    """A flap setting written as a TOML key (``"10.0" = 17.5``)."""
    try:
        flap = float(key)
    except ValueError:
        flap = math.nan
    if not math.isfinite(flap):
        raise DataError(
            f"{path}: [{setting}] key '{key}' is not a flap setting in deg; write e.g. "
            '"10.0" = 17.5'
        )
    return flap


def _parse_regressors(table: Mapping[str, Sequence[tuple[str, str]]], source: str) -> None:
    """Parse every regressor of ``table`` with the engine (as a model holding them as terms):
    an expression it cannot read is refused where it was written, before any data is read.

    Raises
    ------
    InvalidInputError
        From the engine, naming ``source``, the coefficient and the term.
    """

    coefs = {
        c: {
            "terms": [
                {"name": n, "regressor": e, "alpha_deg": [0.0, 1.0], "values": [[0.0, 0.0]]}
                for n, e in terms
            ],
            "alpha_l_deg": [0.0],
            "alpha_u_deg": [1.0],
        }
        for c, terms in table.items()
        if terms
    }
    if coefs:
        spec = {"schema": SCHEMA, "flaps_deg": [0.0], "coefficients": coefs}
        _core.DeltaModel.from_json(json.dumps(spec), source)


#: Settings of :class:`FitConfig` by type, for its check.
_INT_SETTINGS = (
    "min_points_per_param", "min_maneuvers", "min_maneuvers_identified", "min_identified_bins",
    "min_selected_bins", "min_maneuvers_selection", "cv_folds", "seed", "bootstrap",
)  # fmt: skip
_FLOAT_SETTINGS = (
    "width_deg", "max_width_deg", "min_excitation", "min_excitation_snr", "p", "grid_step_deg",
    "past_stall_deg", "max_vif", "f_in", "f_out", "band_level",
)  # fmt: skip
_OPTIONAL_SETTINGS = ("max_width_deg", "max_vif")
_BOOL_SETTINGS = (
    "colored", "weighted", "bootstrap_selection", "nested_cv", "chain_calibration",
    "smoother_match", "beta_kink",
)  # fmt: skip


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
            out = out.drop(f"{a}_deg", strict=False).rename({cg: f"{a}_deg"})
    return out


def qualified_coefficients(data: pl.DataFrame, qualified: str | Path = "auto") -> pl.DataFrame:
    """The simulator's coefficients along the records: ``Cl_qual``, ``Cn_qual``, ``CY_qual``.

    Parameters
    ----------
    data
        A :func:`model_frame` of ingested records.
    qualified
        ``"columns"``: the records' ``Cl_sim``, ``Cn_sim``, ``CY_sim`` (a black-box simulator);
        the path of a DAVE-ML file evaluated along the records; ``"adx37"``: the built-in
        virtual aircraft's qualified model; ``"auto"``: the columns when present, else the
        built-in model for data flown on the virtual aircraft, else refused
        (:func:`aerodelta.qualified.resolve`).
    """
    q = resolve(data, qualified).predict(data)
    return pl.DataFrame({f"{c}_qual": q[c] for c in COEFFICIENTS})


def stall_alpha(data: pl.DataFrame, bin_deg: float = 0.5, min_points: int = 50) -> float:
    """Stall angle of attack, deg: the alpha bin of maximum mean aerodynamic lift coefficient.

    ``C_L = -C_Z cos(alpha) + (C_X - C_T) sin(alpha)`` from the measured body coefficients,
    with the thrust coefficient ``C_T = ct_left + ct_right`` (thrust along body x) removed
    where the records carry it: the measured C_X holds the thrust, whose ``C_T sin(alpha)``
    grows with alpha and power and would move the maximum of the total C_L above the
    aerodynamic one (the wing's stall) on powered stalls.
    """
    a = np.radians(data["alpha_deg"].to_numpy())
    cx = data["CX_meas"].to_numpy()
    if all(c in data.columns for c in ("ct_left", "ct_right")):
        ct = (data["ct_left"].cast(pl.Float64) + data["ct_right"].cast(pl.Float64)).to_numpy()
        cx = cx - np.where(np.isfinite(ct), ct, 0.0)
    cl = -data["CZ_meas"].to_numpy() * np.cos(a) + cx * np.sin(a)
    df = pl.DataFrame(
        {"b": np.floor(data["alpha_deg"].cast(pl.Float64).to_numpy() / bin_deg), "cl": cl}
    ).drop_nans()
    if df.height == 0:
        raise DataError("cannot detect the stall alpha: no alpha bin holds enough points")
    # the bins' means summed in row order (_groups: a polars group-by mean splits its sums
    # over the thread pool, and a near tie could go either way with the thread count)
    g = Groups.of(df, ["b"])
    n = np.bincount(g.index, minlength=g.size)
    mean = np.where(n >= min_points, g.reduce(df["cl"], "mean").to_numpy(), np.nan)
    if np.isnan(mean).all():
        raise DataError("cannot detect the stall alpha: no alpha bin holds enough points")
    # the largest mean; equal means: the lowest bin (the groups are sorted, argmax takes
    # the first)
    best = int(np.argmax(np.where(np.isnan(mean), -np.inf, mean)))
    return float((g.keys["b"][best] + 0.5) * bin_deg)


@dataclass(frozen=True)
class FitResult:
    """The outcome of :func:`fit`: the model and every per-bin estimate behind it.

    Attributes
    ----------
    model
        The Δ model (save it with ``result.model.save(path)``); with a bootstrap its terms carry
        confidence bands (``band``: level, lower, upper per flap).
    bins
        One row per coefficient, flap and alpha bin: edges (deg), points, maneuvers, R²,
        condition number, residual std, note.
    params
        One row per coefficient, flap, bin and parameter: estimate, ``std_err`` (clustered
        by maneuver, CR2) with its Bell-McCaffrey ``dof``, ``p_value`` and 95 % interval
        ``ci95_lower``/``ci95_upper``; ``std_err_ols`` (conventional), ``std_err_colored``
        (SIDPAC's all-lag coloured-residual correction) and, with a bootstrap,
        ``std_err_bootstrap`` over maneuvers; with a bootstrap the percentile band
        ``band_lower``/``band_upper`` at ``band_level`` (widened to reach the estimate when
        the replicates lie on one side of it, and to contain the bin's CR2 t interval at
        ``band_level``; NaN when fewer than half the replicates could refit the bin),
        ``significant`` (the estimate differs from zero at ``band_level``: its band excludes
        zero, or without a band ``p_value < 1 - band_level``; with a selecting bootstrap this
        accounts for the selection, ``p_value`` does not), ``bootstrap_ok`` (replicates that
        refitted the bin), ``inclusion`` (share of
        replicates whose own selection kept the term), t, partial F, excitation (against
        the flap, ``excitation``, and against the regressor's noise floor,
        ``excitation_snr``), VIF, ``identifiable`` and a ``note`` saying why not, and
        ``in_table``: whether the bin's estimate enters the smoothed table (identified, or
        not identified only for collinearity, ``max_vif``).
    consistency
        Adjacent-bin consistency per coefficient, flap and parameter (Section 3.3.4).
    smoothed
        The smoothed parameter tables per coefficient, flap and parameter; with a bootstrap
        also ``lower``/``upper`` (the confidence band at ``band_level``: the replicates'
        percentiles widened by the spline's bias, and containing the ``params`` bands of the
        smoothed bins, interpolated between their centres).
    stall_alpha_deg
        Stall alpha used per flap, deg.
    structure
        Structure selection per coefficient, flap and candidate: bins fitted, bins that
        selected it, ``kept``, ``note`` (empty without selection; a flap with fewer than
        ``min_maneuvers_selection`` maneuvers lists its given structure, with the reason).
    selection_bins
        Per coefficient, flap, bin of the candidate-pool fit and candidate: correlation of the
        model error with the regressor, κ-scaled partial F, ``selected``, excitation and
        identifiability in the pool fit, κ (empty without selection).
    cross_validation
        Per coefficient and flap, held-out (cross-validated over maneuvers) RMS and Theil
        inequality of the per-bin Δ fits with the ``selected`` structure, the ``full`` pool
        and the thesis ``default`` structure (empty without selection).
    replicates
        Bootstrap replicates ``{(coefficient, param, flap): (alpha_grid, values[B, grid])}``;
        a replicate that could not smooth the parameter (too few of its bins refitted) is a
        row of NaN (counted in :attr:`notes`).
    notes
        What the fit left out and why: terms dropped because a channel they read has no value
        in the data (a jet without thrust channels), rows left out for a missing value.
    """

    model: DeltaModel
    bins: pl.DataFrame
    params: pl.DataFrame
    consistency: pl.DataFrame
    smoothed: pl.DataFrame
    stall_alpha_deg: dict[float, float]
    structure: pl.DataFrame = field(default_factory=pl.DataFrame)
    selection_bins: pl.DataFrame = field(default_factory=pl.DataFrame)
    cross_validation: pl.DataFrame = field(default_factory=pl.DataFrame)
    replicates: dict[tuple[str, str, float], tuple[np.ndarray, np.ndarray]] = field(
        default_factory=dict, repr=False
    )
    notes: list[str] = field(default_factory=list)

    def summary(self) -> pl.DataFrame:
        """Per-parameter table (statsmodels-like), sorted by coefficient, flap, alpha.

        One row per coefficient, flap, alpha bin and parameter (the ``params`` frame), for
        scripts; the text report an engineer reads is :meth:`summary_text` (also
        ``print(result)``), rendered from :meth:`summary_table`.
        """
        return self.params.sort(["coefficient", "flap_deg", "alpha_lo_deg", "param"])

    def summary_table(self, range_deg: float | None = 5.0) -> pl.DataFrame:
        """The per-bin estimates aggregated over alpha ranges: the frame of :meth:`summary_text`.

        Parameters
        ----------
        range_deg
            Width of the alpha ranges, deg: a bin belongs to the range holding its centre
            (ranges start at multiples of ``range_deg``). ``None``: one range per bin.

        Returns
        -------
        polars.DataFrame
            One row per coefficient, flap, range and parameter: ``alpha_lo_deg``/``alpha_hi_deg``
            (the span of the range's bins), ``bins``, ``bins_fitted`` (finite estimate),
            ``identified`` (bins where the parameter is identified), ``estimate``, ``std_err``
            (CR2 cluster-robust), ``t`` and ``partial_f`` (medians over the fitted bins; one
            bin's own values with ``range_deg=None``), ``pct_error`` (SIDPAC's
            ``100 · std_err / |estimate|`` of those medians), ``reasons`` (why not identified,
            shortened and counted, most frequent first: ``"collinear with 'dCl_r' in 12 of 40
            bins"``), ``r2_min``/``r2_max`` and ``maneuvers_min``/``maneuvers_max`` over the
            range's fitted bins.
        """
        return _summary_table(self.params, self.bins, range_deg)

    def summary_text(
        self,
        range_deg: float | None = 5.0,
        *,
        qualified: str | None = None,
        width: int = 100,
    ) -> str:
        """The results report an engineer reads (SIDPAC / statsmodels style), as text.

        A header (data, qualified model, structure selection, standard errors, stall alpha
        per flap in words), the identified share per coefficient with the reasons for the
        rest, then per coefficient and flap: the structure, the cross-validated score, and a
        table of the parameters per alpha range (estimate, standard error, % error, t,
        partial F, identified bins and why not, R²), and the notes of the fit.

        Parameters
        ----------
        range_deg
            Alpha range per table section, deg (see :meth:`summary_table`); ``None`` for one
            section per bin.
        qualified
            Overrides the qualified model the fit recorded in the model's provenance
            (``"columns"``, ``"adx37"``, ``"daveml:NAME"``); models fitted before it was
            recorded say "not recorded" without it.
        width
            Line length the long lines (lists, notes, reasons) are wrapped to.

        Returns
        -------
        str
            The report; ``print(result)`` prints it with the defaults.
        """
        return _summary_text(self, range_deg=range_deg, qualified=qualified, width=width)

    def __str__(self) -> str:
        return self.summary_text()

    def identified_fraction(self) -> pl.DataFrame:
        """Share of fitted bins in which each parameter is identified, per coefficient/flap."""
        return (
            self.params.group_by(["coefficient", "flap_deg", "param"])
            .agg(pl.col("identifiable").mean().alias("identified_fraction"))
            .sort(["coefficient", "flap_deg", "param"])
        )

    def delta_band(self, data: pl.DataFrame, *, level: float = 0.95) -> pl.DataFrame:
        """Bootstrap confidence band of the blended Δ along records.

        Parameters
        ----------
        data
            Ingested records (as given to :func:`fit`).
        level
            Confidence level.

        Returns
        -------
        polars.DataFrame
            Per coefficient ``C``: ``dC_blended`` (the model's correction), ``dC_lower`` and
            ``dC_upper`` (percentile band of the replicates, NaN on flaps the model was not
            fitted at). The extended coefficient's band is ``C_qualified +`` the band.

        Raises
        ------
        DataError
            If the fit ran without a bootstrap.
        """
        if not self.replicates:
            raise DataError(
                "delta_band: the fit has no bootstrap; fit with FitConfig(bootstrap=200)"
            )
        df = model_frame(data)
        spec = self.model.to_spec()
        for c in spec["coefficients"].values():
            for t in c["terms"]:
                t["values"] = [[1.0] * len(t["alpha_deg"]) for _ in t["values"]]
                t.pop("band", None)
        unit = DeltaModel.from_spec(spec, "unit regressors").evaluate(df, terms=True)
        ev = self.model.evaluate(df)
        alpha = df["alpha_deg"].cast(pl.Float64).to_numpy()
        flap = df["flap_deg"].cast(pl.Float64).to_numpy()
        q = [(1.0 - level) / 2.0, (1.0 + level) / 2.0]
        out: dict[str, np.ndarray] = {}
        for coef in self.model.coefficients:
            lo = np.full(df.height, np.nan)
            hi = np.full(df.height, np.nan)
            w = unit[f"w_{coef}"].to_numpy()
            keys = [k for k in self.replicates if k[0] == coef]
            for f in sorted({k[2] for k in keys}):
                rows = np.flatnonzero(flap == f)
                for start in range(0, rows.size, 20_000):
                    r = rows[start : start + 20_000]
                    acc = None
                    for _, name, _ in (k for k in keys if k[2] == f):
                        grid, reps = self.replicates[(coef, name, f)]
                        x = unit[name].to_numpy()[r]
                        th = np.stack([np.interp(alpha[r], grid, v) for v in reps])
                        acc = th * x if acc is None else acc + th * x
                    # a replicate that could not smooth a parameter (NaN) is left out; under
                    # half of them left, no band
                    ok = None if acc is None else np.isfinite(acc).all(axis=1)
                    if acc is not None and ok is not None and 2 * ok.sum() >= len(ok) >= 2:
                        qs = np.quantile(acc[ok], q, axis=0)
                        lo[r], hi[r] = qs[0] * w[r], qs[1] * w[r]
            out[f"d{coef}_blended"] = ev[f"d{coef}_blended"].to_numpy()
            out[f"d{coef}_lower"] = lo
            out[f"d{coef}_upper"] = hi
        return pl.DataFrame(out)


#: Leading words of an engine note (``aero_core::identify``, ``aero_core::lsq``) and their short
#: form in the summary tables; a note not listed keeps its text before the first colon.
_REASON_PATTERNS: list[tuple[re.Pattern[str], str]] = [
    (re.compile(r"^low excitation:.*noise floor"), "low excitation (near the noise floor)"),
    (re.compile(r"^low excitation:"), "low excitation (against the flap's)"),
    (re.compile(r"^\d+ maneuvers? in the bin \(minimum (\d+)\)"), r"fewer than \1 maneuvers"),
    (re.compile(r"^bin not fitted: too little data"), "bin not fitted (too little data)"),
    (re.compile(r"^cluster-robust error undefined"), "one maneuver alone determines it"),
    (re.compile(r"^not identifiable: (\d+% of its variance)"), r"\1 near-collinear"),
]


def _short_reason(clause: str) -> str:
    """One clause of a ``params`` note, shortened for a table: "collinear with 'dCl_r'
    (estimate correlation 0.93): VIF 45 > 10" -> "collinear with 'dCl_r'"."""
    c = clause.strip()
    for pat, repl in _REASON_PATTERNS:
        m = pat.match(c)
        if m:
            return m.expand(repl)
    c = re.sub(r"^not identifiable: ", "", c)
    c = re.sub(r"\s*\([^)]*\)", "", c)  # "(estimate correlation 0.93)", "(condition index ..)"
    return c.split(":", 1)[0].strip() or "not identified"


def _reason_kind(short: str) -> str:
    """A shortened reason without the term names (the overview counts kinds)."""
    if short.startswith(("collinear with", "near-collinear", "linearly dependent")):
        return "collinear with other terms"
    return short


def _split_reasons(note: str) -> list[str]:
    out: list[str] = []
    for clause in note.split("; "):
        if clause.strip():
            s = _short_reason(clause)
            if s not in out:
                out.append(s)
    return out or ["not identified"]


def _count_reasons(notes: Sequence[str], n_bins: int) -> str:
    """Why a parameter is not identified in the bins of one range, counted: ``notes`` holds
    the note of each such bin. A bin collinear with other terms counts once, under the term its
    estimate correlates with most ("collinear with 'dCl_r' (9), 'dCl_p' (3) in 12 of 40 bins");
    with a single bin the reasons are given whole."""
    if not notes:
        return ""
    if n_bins == 1:
        return "; ".join(_split_reasons(notes[0]))
    counts: dict[str, int] = {}
    partners: dict[str, int] = {}
    n_col = 0
    for note in notes:
        collinear = False
        for r in _split_reasons(note):
            m = re.match(r"collinear with ('[^']*')", r)
            if m:
                if not collinear:
                    partners[m.group(1)] = partners.get(m.group(1), 0) + 1
                    n_col += 1
                collinear = True
            else:
                counts[r] = counts.get(r, 0) + 1
    items: list[tuple[int, str]] = []
    if n_col:
        ranked = sorted(partners.items(), key=lambda kv: (-kv[1], kv[0]))
        if len(ranked) == 1:
            names = ranked[0][0]
        else:
            names = ", ".join(f"{name} ({k})" for name, k in ranked[:3])
            names += ", ..." if len(ranked) > 3 else ""
        items.append((n_col, f"collinear with {names}"))
    items += [(k, r) for r, k in counts.items()]
    items.sort(key=lambda kr: (-kr[0], kr[1]))
    return "; ".join(f"{r} in {k} of {n_bins} bins" for k, r in items)


def _summary_table(
    params: pl.DataFrame, bins: pl.DataFrame, range_deg: float | None
) -> pl.DataFrame:
    """:meth:`FitResult.summary_table`."""
    if range_deg is not None and not (math.isfinite(range_deg) and range_deg > 0):
        raise DataError(f"summary: range_deg={range_deg!r}; give a width in deg > 0, or None")
    keys = ["coefficient", "flap_deg", "alpha_lo_deg", "alpha_hi_deg"]
    schema = {
        "coefficient": pl.Utf8, "flap_deg": pl.Float64, "range": pl.Float64,
        "alpha_lo_deg": pl.Float64, "alpha_hi_deg": pl.Float64, "param": pl.Utf8,
        "regressor": pl.Utf8, "bins": pl.UInt32, "bins_fitted": pl.UInt32,
        "identified": pl.UInt32, "points": pl.Int64, "estimate": pl.Float64,
        "std_err": pl.Float64, "pct_error": pl.Float64, "t": pl.Float64,
        "partial_f": pl.Float64, "reasons": pl.Utf8, "r2_min": pl.Float64, "r2_max": pl.Float64,
        "maneuvers_min": pl.Int64, "maneuvers_max": pl.Int64,
    }  # fmt: skip
    if params.is_empty():
        return pl.DataFrame(schema=schema)
    centre = (pl.col("alpha_lo_deg") + pl.col("alpha_hi_deg")) / 2.0
    rng = pl.col("alpha_lo_deg") if range_deg is None else (centre / range_deg).floor()
    per_bin = bins.select(
        *keys, pl.col("n"), pl.col("n_maneuvers"), pl.col("r2"),
        pl.col("r2").is_finite().alias("bin_fitted"),
    )  # fmt: skip
    p = (
        params.with_row_index("order")
        .join(per_bin, on=keys, how="left")
        .with_columns(rng.alias("range"), pl.col("estimate").is_finite().alias("fitted"))
    )
    group = ["coefficient", "flap_deg", "range", "param"]
    fit_ok = pl.col("fitted")
    ranges = p.group_by(["coefficient", "flap_deg", "range"]).agg(
        pl.col("alpha_lo_deg").min(), pl.col("alpha_hi_deg").max(),
        pl.struct(keys).n_unique().cast(pl.UInt32).alias("bins"),
        pl.col("n").filter(pl.col("param") == pl.col("param").first()).sum().alias("points"),
        pl.col("r2").filter(pl.col("bin_fitted")).min().alias("r2_min"),
        pl.col("r2").filter(pl.col("bin_fitted")).max().alias("r2_max"),
        pl.col("n_maneuvers").filter(pl.col("bin_fitted")).min().alias("maneuvers_min"),
        pl.col("n_maneuvers").filter(pl.col("bin_fitted")).max().alias("maneuvers_max"),
    )  # fmt: skip
    agg = p.group_by(group).agg(
        pl.col("order").min(), pl.col("regressor").first(),
        fit_ok.sum().cast(pl.UInt32).alias("bins_fitted"),
        pl.col("identifiable").sum().cast(pl.UInt32).alias("identified"),
        pl.col("estimate").filter(fit_ok).median().alias("estimate"),
        pl.col("std_err").filter(fit_ok & pl.col("std_err").is_finite()).median().alias("std_err"),
        pl.col("t").filter(fit_ok & pl.col("t").is_finite()).median().alias("t"),
        pl.col("partial_f").filter(fit_ok & pl.col("partial_f").is_finite()).median()
        .alias("partial_f"),
    )  # fmt: skip
    out = agg.join(ranges, on=["coefficient", "flap_deg", "range"], how="left")
    # why not: the shortened clauses of the notes of the bins where the parameter is not
    # identified, counted once per bin, most frequent first
    bad = p.filter(~pl.col("identifiable"))
    per_key: dict[tuple[Any, ...], list[str]] = {}
    for *key, note in bad.select(*group, "note").iter_rows():
        per_key.setdefault(tuple(key), []).append(note)
    keys = list(zip(*(out[c].to_list() for c in group), strict=True))
    reasons = [
        _count_reasons(per_key.get(k, []), n)
        for k, n in zip(keys, out["bins"].to_list(), strict=True)
    ]
    coef_order = {c: i for i, c in enumerate(COEFFICIENTS)}
    out = (
        out.with_columns(
            pl.Series("reasons", reasons, dtype=pl.Utf8),
            (100.0 * pl.col("std_err") / pl.col("estimate").abs()).alias("pct_error"),
            pl.col("coefficient").replace_strict(coef_order, default=99).alias("_c"),
        )
        .sort(["_c", "coefficient", "flap_deg", "range", "order"])
        .drop("_c", "order")
    )
    return out.select(list(schema)).cast(schema)  # type: ignore[arg-type]


def _fmt(v: float | None, spec: str, width: int) -> str:
    """A number right-aligned in ``width``, "-" when missing or not finite."""
    if v is None or not math.isfinite(v):
        return f"{'-':>{width}}"
    return f"{v:>{width}{spec}}"


def _fmt_pct(v: float | None) -> str:
    """A % error in 6 characters: one decimal below 1000, whole above, then powers of ten."""
    if v is None or not math.isfinite(v):
        return f"{'-':>6}"
    return f"{v:6.1f}" if v < 999.95 else f"{v:6.0f}" if v < 99_999.5 else f"{v:6.0e}"


def _fmt_f(v: float | None) -> str:
    """A partial F in 9 characters."""
    if v is None or not math.isfinite(v):
        return f"{'-':>9}"
    return f"{v:9.2f}" if v < 99_999.995 else f"{v:9.2e}"


def _span(lo: float | None, hi: float | None, fmt: str = ".2f") -> str:
    """``0.12-0.95`` (one value when equal, ``-`` when missing); non-negative values."""
    if lo is None or hi is None or not (math.isfinite(lo) and math.isfinite(hi)):
        return "-"
    a, b = format(lo, fmt), format(hi, fmt)
    return a if a == b else f"{a}-{b}"


def _alpha_span(lo: float, hi: float) -> str:
    return f"alpha {lo:.1f} to {hi:.1f} deg"


def _wrap(text: str, width: int, indent: str = "    ", first: str = "") -> list[str]:
    """``text`` wrapped to ``width``: the first line starts with ``first``, the others with
    ``indent``."""
    import textwrap  # noqa: PLC0415

    return textwrap.wrap(
        text, width=width, initial_indent=first, subsequent_indent=indent,
        break_on_hyphens=False, break_long_words=False,
    ) or [first.rstrip()]  # fmt: skip


def _summary_text(
    r: FitResult, *, range_deg: float | None, qualified: str | None, width: int
) -> str:
    """:meth:`FitResult.summary_text`."""
    table = _summary_table(r.params, r.bins, range_deg)
    lines = _header_lines(r, range_deg=range_deg, qualified=qualified, width=width)
    add = lines.append
    if r.params.is_empty():
        add("")
        add("no parameter was fitted")
    notes_left = list(r.notes)
    for (coef, flap), block in table.group_by(["coefficient", "flap_deg"], maintain_order=True):
        prefix = f"{coef} at flap {flap:g} deg: "
        own = [n for n in notes_left if n.startswith(prefix)]
        notes_left = [n for n in notes_left if not n.startswith(prefix)]
        lines += _block_lines(
            r, str(coef), float(flap), block, [n[len(prefix) :] for n in own],
            per_bin=range_deg is None, width=width,
        )  # fmt: skip
    if notes_left:
        add("")
        add("notes:")
        for note in notes_left:
            lines += _wrap(note, width, "    ", "  ")
    return "\n".join(lines)


#: The qualified model in the summary's words (others: :func:`aerodelta.qualified.describe`).
_QUALIFIED = {
    "columns": "the simulator's predictions in the records (Cl_sim, Cn_sim, CY_sim)",
    "adx37": "the built-in ADX-37 lateral model (qualified='adx37')",
}


def _header_lines(
    r: FitResult, *, range_deg: float | None, qualified: str | None, width: int
) -> list[str]:
    """Data, qualified model, structure selection, standard errors, identification rules,
    stall alpha per flap, and the identified share per coefficient."""
    spec = r.model.to_spec()
    prov = spec.get("provenance") or {}
    cfg = prov.get("config") or {}
    flaps = sorted(r.stall_alpha_deg)
    lines = [
        "Δ-model identification: equation-error least squares per alpha bin (thesis 3.3-3.6)",
        "=" * min(width, 88),
    ]
    data = f"{prov['maneuvers']} maneuvers, {prov['rows']:,} rows; " if prov else ""
    lines.append(f"data: {data}flaps {', '.join(f'{f:g}' for f in flaps)} deg")
    recorded = str(qualified or prov.get("qualified") or "")
    source = _QUALIFIED.get(recorded, describe(recorded)) if recorded else "not recorded"
    lines.append(f"qualified model: {source}")
    sel = cfg.get("selection")
    if sel:
        how = "forward stepwise, partial F" if sel == "stepwise" else "orthogonal functions, PSE"
        lines += _wrap(
            f"structure: selected per coefficient and flap from the candidate pool ({how}), "
            f"its size by {cfg.get('cv_folds', 5)}-fold cross-validation over maneuvers; a flap "
            f"with fewer than {cfg.get('min_maneuvers_selection', 15)} maneuvers fits the given "
            "structure",
            width,
        )
    else:
        lines.append("structure: as given (FitConfig.structures), no selection")
    lines += _wrap(
        "standard errors: CR2 cluster-robust by maneuver, Student t on Bell-McCaffrey dof; "
        "% err = 100 * std err / |estimate| (SIDPAC); "
        + (
            f"per {range_deg:g}-deg alpha range the medians over its fitted bins"
            if range_deg is not None
            else "one section per alpha bin"
        ),
        width,
    )
    vif = cfg.get("max_vif")
    lines += _wrap(
        f"identified: at least {cfg.get('min_maneuvers_identified', 5)} maneuvers in the bin, "
        f"excitation at least {100 * float(cfg.get('min_excitation', 0.05)):g}% of the flap's "
        f"and {float(cfg.get('min_excitation_snr', 3.0)):g} times the noise floor, "
        + (f"VIF at most {vif:g}, " if vif is not None else "")
        + "no near dependency, a cluster-robust error",
        width,
    )
    given = {float(k) for k in (cfg.get("stall_alpha_deg") or {})}
    past = float(cfg.get("past_stall_deg", 10.0))
    lines.append("stall alpha:")
    for f in flaps:
        a = r.stall_alpha_deg[f]
        how = "given in the configuration" if f in given else "max C_L, detected"
        lines.append(
            f"  flap {f:g} deg: stall at {a:.1f} deg alpha ({how}); tables end at "
            f"{a + past:.1f} deg"
        )
    if r.params.is_empty():
        return lines
    lines += ["", "identified share of the bin estimates (all flaps and bins):"]
    present = set(r.params["coefficient"].to_list())
    coefs = [c for c in COEFFICIENTS if c in present] + sorted(present - set(COEFFICIENTS))
    for coef in coefs:
        pc = r.params.filter(pl.col("coefficient") == coef)
        share = float(pc["identifiable"].mean() or 0.0)
        lines.append(f"  {coef}: {pc.height:,} bin estimates, {100 * share:.0f}% identified")
        kinds: dict[str, int] = {}
        for note in pc.filter(~pl.col("identifiable"))["note"].to_list():
            for k in {_reason_kind(s) for s in _split_reasons(note)}:
                kinds[k] = kinds.get(k, 0) + 1
        if kinds:
            ranked = sorted(kinds.items(), key=lambda kv: (-kv[1], kv[0]))
            lines += _wrap(
                "not identified: " + "; ".join(f"{n:,} x {k}" for k, n in ranked),
                width, "      ", "    ",
            )  # fmt: skip
    return lines


def _block_lines(
    r: FitResult,
    coef: str,
    flap: float,
    block: pl.DataFrame,
    notes: Sequence[str],
    *,
    per_bin: bool,
    width: int,
) -> list[str]:
    """One coefficient at one flap: bins, structure, cross-validation, notes, then the
    parameter table per alpha range (a range without a fitted bin in one line)."""
    b = r.bins.filter((pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap))
    fitted = b.filter(pl.col("r2").is_finite())
    title = f"{coef}, flap {flap:g} deg"
    lines = ["", f"{title} " + "-" * max(3, min(width, 88) - len(title) - 1)]
    lo, hi = b["alpha_lo_deg"].min(), b["alpha_hi_deg"].max()
    man = _span(fitted["n_maneuvers"].min(), fitted["n_maneuvers"].max(), ".0f")  # type: ignore[arg-type]
    r2 = _span(fitted["r2"].min(), fitted["r2"].max())  # type: ignore[arg-type]
    lines += _wrap(
        f"{b.height} bins over {_alpha_span(lo, hi)} ({fitted.height} fitted), {man} "  # type: ignore[arg-type]
        f"maneuvers per bin, R² {r2}",
        width,
    )
    lines += _structure_lines(r.structure, coef, flap, block, width)
    lines += _cv_lines(r.cross_validation, coef, flap, width)
    for note in notes:
        lines += _wrap(note, width, "        ", "  note: ")
    w = max(9, *(len(p) for p in block["param"].to_list()))
    lines.append(
        f"  {'parameter':<{w}} {'estimate':>10} {'std err':>9} {'% err':>6} {'t':>7} "
        f"{'partial F':>9} {'ident':>6}  why not identified"
    )
    for _, rows in block.group_by("range", maintain_order=True):
        first = rows.row(0, named=True)
        span = _alpha_span(first["alpha_lo_deg"], first["alpha_hi_deg"])
        nb = first["bins"]
        size = f"{first['points']:,} points" if per_bin else (
            f"{nb} bin{'s' if nb != 1 else ''}, {first['points']:,} points"
        )  # fmt: skip
        if int(rows["bins_fitted"].max() or 0) == 0:
            why = rows["reasons"][0] or "not fitted"
            lines += _wrap(f" {span}: {size}; {why}", width, "    ")
            continue
        man = _span(first["maneuvers_min"], first["maneuvers_max"], ".0f")
        per = "" if per_bin else " per bin"
        lines.append(
            f" {span}: {size}, {man} maneuvers{per}, R² {_span(first['r2_min'], first['r2_max'])}"
        )
        for row in rows.iter_rows(named=True):
            left = (
                f"  {row['param']:<{w}} {_fmt(row['estimate'], '.3e', 10)} "
                f"{_fmt(row['std_err'], '.2e', 9)} {_fmt_pct(row['pct_error'])} "
                f"{_fmt(row['t'], '.2f', 7)} {_fmt_f(row['partial_f'])} "
                f"{str(row['identified']) + '/' + str(row['bins']):>6}"
            )
            why = row["reasons"]
            if not why:
                lines.append(left)
            elif len(left) + 2 + len(why) <= width:
                lines.append(f"{left}  {why}")
            else:  # on the lines below, indented under the parameter
                lines += [left, *_wrap(why, width, "        ", "      ")]
    return lines


def _structure_lines(
    st: pl.DataFrame, coef: str, flap: float, block: pl.DataFrame, width: int
) -> list[str]:
    """The structure of one coefficient and flap: selected (how many of how many), or the
    given structure and why it was not selected."""
    names = ", ".join(dict.fromkeys(block["param"].to_list()))
    rows = (
        st.filter((pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap))
        if not st.is_empty()
        else st
    )
    if rows.is_empty():
        return _wrap(f"structure (as given): {names}", width)
    if rows["bins_fitted"].is_null().all():
        why = str(rows["note"][0]).split(";", 1)[0]
        return _wrap(f"structure as given ({why}): {names}", width)
    kept = int(rows["kept"].sum())
    return _wrap(f"structure: {kept} of {rows.height} candidates kept: {names}", width)


def _cv_lines(cv: pl.DataFrame, coef: str, flap: float, width: int) -> list[str]:
    """The cross-validation of one coefficient and flap: held-out Theil inequality of the Δ
    fit against the qualified model's error (1 would be the qualified model alone, Δ = 0)."""
    if cv.is_empty():
        return []
    rows = cv.filter((pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap))
    if rows.is_empty():
        return []
    by = {r["structure"]: r for r in rows.iter_rows(named=True)}
    parts = []
    if "selected_outer" in by:
        o = by["selected_outer"]
        parts.append(
            f"{_fmt(o['cv_tic'], '.3f', 0)} the selection (nested, honest; "
            f"RMS {_fmt(o['cv_rms'], '.2e', 0)})"
        )
    labels = [
        ("selected", "the chosen structure (optimistic)"), ("full", "the full pool"),
        ("default", "the thesis structure"),
    ]  # fmt: skip
    for key, label in labels:
        if key in by:
            n = by[key]["n_params"]
            parts.append(f"{_fmt(by[key]['cv_tic'], '.3f', 0)} {label}, {n} terms")
    return _wrap(
        "held-out TIC of Δ over maneuvers (1: the qualified model alone): " + "; ".join(parts),
        width,
    )


def _maneuver_codes(data: pl.DataFrame) -> np.ndarray:
    return np.ascontiguousarray(
        data["maneuver_id"].cast(pl.Utf8).cast(pl.Categorical).to_physical().to_numpy(),
        dtype=np.uint64,
    )


def _bin_rows(
    coef: str, flap: float, out: Mapping[str, Any], regs: Sequence[tuple[str, str]]
) -> tuple[pl.DataFrame, pl.DataFrame]:
    """The ``bins`` and ``params`` tables of one ``identify`` output (built column-wise)."""
    names: list[str] = out["names"]
    nb, npar = len(out["alpha_lo"]), len(names)
    lo, hi = np.asarray(out["alpha_lo"], dtype=float), np.asarray(out["alpha_hi"], dtype=float)
    bins = pl.DataFrame(
        {
            "coefficient": [coef] * nb, "flap_deg": np.full(nb, flap, dtype=float),
            "alpha_lo_deg": lo, "alpha_hi_deg": hi,
            "n": np.asarray(out["n"], dtype=np.int64),
            "n_maneuvers": np.asarray(out["n_maneuvers"], dtype=np.int64),
            "r2": np.asarray(out["r2"], dtype=float),
            "condition_number": np.asarray(out["condition_number"], dtype=float),
            "residual_std": np.asarray(out["residual_std"], dtype=float),
            "note": [str(v) for v in out["bin_note"]],
        }
    )  # fmt: skip

    def flat(key: str) -> np.ndarray:  # row-major: bin, then parameter
        return np.asarray(out[key], dtype=float).ravel()

    boot = out.get("bootstrap")

    def boot_col(key: str) -> np.ndarray:
        if boot is None:
            return np.full(nb * npar, np.nan)
        return np.asarray(boot[key], dtype=float).ravel()

    est, se = flat("params"), flat("std_err_cluster")
    half = flat("ci95_half_width")
    with np.errstate(divide="ignore", invalid="ignore"):
        t = np.where(se > 0, est / se, np.nan)
    params = pl.DataFrame(
        {
            "coefficient": [coef] * (nb * npar), "flap_deg": np.full(nb * npar, flap, dtype=float),
            "param": names * nb, "regressor": [e for _, e in regs] * nb,
            "alpha_lo_deg": np.repeat(lo, npar), "alpha_hi_deg": np.repeat(hi, npar),
            "estimate": est, "std_err": se, "dof": flat("dof_cluster"),
            "ci95_lower": est - half, "ci95_upper": est + half, "p_value": flat("p_value"),
            "std_err_ols": flat("std_err"), "std_err_colored": flat("std_err_colored"),
            "std_err_bootstrap": boot_col("bin_std"),
            "band_lower": boot_col("bin_lower"), "band_upper": boot_col("bin_upper"),
            "bootstrap_ok": boot_col("bin_replicates_ok"),
            "inclusion": np.tile(np.asarray(boot["inclusion"], dtype=float), nb)
            if boot is not None else np.full(nb * npar, np.nan),
            "t": t, "partial_f": flat("partial_f"), "excitation": flat("excitation"),
            "excitation_snr": flat("excitation_snr"), "vif": flat("vif"),
            "identifiable": np.asarray(out["identifiable"], dtype=bool).ravel(),
            "in_table": np.asarray(out["smoothable"], dtype=bool).ravel(),
            "note": [str(v) for v in out["notes"]],
        }
    )  # fmt: skip
    return bins, params


def _with_significance(params: pl.DataFrame, level: float) -> pl.DataFrame:
    """``params`` with ``significant`` after ``band_upper``: the estimate differs from zero at
    ``level``. With a bootstrap band, the band excludes zero: a selecting bootstrap's band
    carries the selection's uncertainty (a term the replicates drop reaches zero) and contains
    the CR2 interval, so a term kept because it fits the data is not then declared significant
    on the same data by its CR2 t-test alone (post-selection inference; Efron 2014). Without a
    band, ``p_value < 1 - level`` (CR2, Bell-McCaffrey t)."""
    band = pl.col("band_lower").is_finite() & pl.col("band_upper").is_finite()
    excludes = (pl.col("band_lower") > 0.0) | (pl.col("band_upper") < 0.0)
    by_p = pl.col("p_value").is_finite() & (pl.col("p_value") < 1.0 - level)
    sig = params.select(
        pl.when(band).then(excludes).otherwise(by_p).fill_null(False).alias("significant")
    ).to_series()
    return params.insert_column(params.columns.index("band_upper") + 1, sig)


def _selection_rows(
    coef: str,
    *,
    flap: float,
    sel: Mapping[str, Any],
    pool: Sequence[tuple[str, str]],
    chosen: Sequence[int],
    default: Sequence[tuple[str, str]],
) -> tuple[list[dict[str, Any]], pl.DataFrame, list[dict[str, Any]]]:
    """Rows of ``structure``, the ``selection_bins`` frame and ``cross_validation`` rows."""
    pf = sel["pool"]
    nb, npar = len(pf["alpha_lo"]), len(pool)
    shape = (nb, npar)
    selected = np.asarray(sel["selected"], dtype=bool).reshape(shape)
    fpart = np.asarray(sel["partial_f"]).reshape(shape)
    corr = np.asarray(sel["correlation"]).reshape(shape)
    exc = np.asarray(pf["excitation"]).reshape(shape)
    ident = np.asarray(pf["identifiable"], dtype=bool).reshape(shape)
    fitted = np.asarray(sel["fitted"], dtype=bool)
    kappa = np.asarray(sel["kappa"])
    bin_rows = pl.DataFrame(
        {
            "coefficient": [coef] * (nb * npar),
            "flap_deg": np.full(nb * npar, flap),
            "param": [pool[j][0] for _ in range(nb) for j in range(npar)],
            "regressor": [pool[j][1] for _ in range(nb) for j in range(npar)],
            "alpha_lo_deg": np.repeat(np.asarray(pf["alpha_lo"]), npar),
            "alpha_hi_deg": np.repeat(np.asarray(pf["alpha_hi"]), npar),
            "fitted": np.repeat(fitted, npar),
            "kappa": np.repeat(kappa, npar),
            "correlation": corr.ravel(),
            "partial_f": fpart.ravel(),
            "selected": selected.ravel(),
            "excitation": exc.ravel(),
            "identifiable_in_pool": ident.ravel(),
        }
    )
    structure = [
        {
            "coefficient": coef, "flap_deg": flap, "param": pool[j][0], "regressor": pool[j][1],
            "bins_fitted": int(fitted.sum()), "bins_selected": int(sel["count"][j]),
            "kept": j in chosen, "note": "",
        }
        for j in range(npar)
    ]  # fmt: skip
    cv = []
    labelled = [("selected", sel["pruned"]), ("full", sel["full"])]
    if default:
        labelled.append(("default", sel["extra"][0]))
    if sel["outer"] is not None:
        labelled.append(("selected_outer", sel["outer"]))
    per_fold = " | ".join(
        ",".join(pool[c][0] for c in sorted(cols)) for cols in sel["outer_chosen"]
    )
    for label, (cols, rms, tic, mse, mse_se) in labelled:
        cv.append(
            {
                "coefficient": coef, "flap_deg": flap, "structure": label,
                "n_params": len(cols), "params": ",".join(pool[c][0] for c in sorted(cols)),
                "cv_rms": rms, "cv_tic": tic, "cv_mse": mse, "cv_mse_se": mse_se,
                "outer_structures": per_fold if label == "selected_outer" else None,
            }
        )  # fmt: skip
    return structure, bin_rows, cv


def _flap_columns(d: pl.DataFrame, wanted: set[str]) -> tuple[dict[str, np.ndarray], np.ndarray]:
    """The ``wanted`` numeric columns of one flap's rows as float64 (once per flap), and the
    maneuver codes."""
    num = [c for c in d.columns if c in wanted and d[c].dtype.is_numeric() and c != "maneuver_id"]
    conv = d.select(pl.col(num).cast(pl.Float64).fill_null(np.nan))
    return {c: conv[c].to_numpy() for c in num}, _maneuver_codes(d)


#: Function names of the regressor grammar (``aero_core::regressor``): not channels.
_REGRESSOR_FUNCTIONS = frozenset(
    {"pos", "neg", "deadband", "step", "abs", "sqrt", "sin", "cos", "exp", "min", "max"}
)
_IDENT = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def regressor_channels(expr: str) -> list[str]:
    """The data channels a regressor expression reads (identifiers that are not functions)."""
    return sorted({t for t in _IDENT.findall(expr) if t not in _REGRESSOR_FUNCTIONS})


def _screen_regressors(
    regs: Sequence[tuple[str, str]],
    counts: Mapping[str, int],
    *,
    coef: str,
    flap: float,
    user_named: bool,
    what: str,
) -> tuple[list[tuple[str, str]], list[str]]:
    """Drop the regressors whose channels have no value at this flap, with a note each; a
    regressor the user named is refused instead (``DataError``)."""
    kept: list[tuple[str, str]] = []
    notes: list[str] = []
    for name, expr in regs:
        absent = [c for c in regressor_channels(expr) if counts.get(c, 0) == 0]
        if not absent:
            kept.append((name, expr))
            continue
        chans = ", ".join(
            f"'{c}' ({'no value' if c in counts else 'not in the data'})" for c in absent
        )
        if user_named:
            raise DataError(
                f"fit: {coef} term '{name}' = {expr} in the {what} reads {chans} at flap "
                f"{flap:g} deg; map that channel in the records (see docs/data.md) or remove the "
                f"term from the {what}"
            )
        notes.append(f"{coef} at flap {flap:g} deg: term '{name}' = {expr} dropped: {chans}")
    return kept, notes


def _submit(
    ex: ThreadPoolExecutor,
    cfg: FitConfig,
    full: Mapping[str, np.ndarray],
    codes: np.ndarray,
    coef: str,
    *,
    regs: Sequence[tuple[str, str]],
    alpha_max: float,
    selection: str | None,
    forced: Sequence[int],
    extra: Sequence[Sequence[int]],
    bootstrap: int,
    flap: float,
    notes: list[str],
    prune: bool,
    companions: Sequence[tuple[int, int]] = (),
) -> Future:
    """Submit one coefficient's identification at one flap to the engine (which releases the
    GIL), on the rows with a finite qualified-model error, alpha and regressor channels (rows
    left out are counted in ``notes``)."""
    z_all = full[f"{coef}_meas"] - full[f"{coef}_qual"]
    keep = np.isfinite(z_all) & np.isfinite(full["alpha_deg"])
    # only the columns the regressors read; a row without a value of one of them is left out
    # here, counted in a note, never handed to the engine
    read = {c for _, e in regs for c in regressor_channels(e)}
    used = [c for c in full if c == "alpha_deg" or c in read]
    for c in used:
        ok = np.isfinite(full[c])
        if not ok.all():
            gap = int((keep & ~ok).sum())
            if gap:
                notes.append(
                    f"{coef} at flap {flap:g} deg: {gap} of {len(ok)} rows "
                    f"({100 * gap / len(ok):.1f} %) have no value of '{c}' and are left out"
                )
            keep &= ok
    pick = (lambda v: v) if keep.all() else (lambda v: v[keep])
    cols = {c: np.ascontiguousarray(pick(full[c])) for c in used}
    z = np.ascontiguousarray(z_all[keep])
    band = cfg.band_hz.get(coef) if isinstance(cfg.band_hz, Mapping) else cfg.band_hz
    t = np.ascontiguousarray(pick(full["t"])) if band is not None else None
    fut = ex.submit(
        _core.identify_flap, list(regs), cols, z, cols["alpha_deg"],
        np.ascontiguousarray(codes[keep]),
        cfg.width_deg, cfg.min_points_per_param, cfg.min_maneuvers, cfg.max_width_deg,
        cfg.colored, cfg.min_excitation, cfg.p, cfg.weighted, cfg.grid_step_deg,
        alpha_max, cfg.min_identified_bins, selection, cfg.f_in, cfg.f_out, list(forced),
        cfg.min_selected_bins, cfg.cv_folds, cfg.seed, [list(e) for e in extra], bootstrap,
        cfg.band_level, t, band, cfg.min_excitation_snr, cfg.min_maneuvers_identified,
        cfg.bootstrap_selection, math.inf if cfg.max_vif is None else cfg.max_vif, prune,
        cfg.nested_cv, list(companions),
    )  # fmt: skip
    return fut


#: Fewest calibration samples and maneuvers below alpha_l for :func:`calibrate_chain`.
CHAIN_MIN_SAMPLES = 200


@dataclass(frozen=True)
class ChainCalibration:
    """Measurement-chain estimates of :func:`calibrate_chain`, per coefficient.

    Attributes
    ----------
    skew_s
        Time skew τ, s: the measured coefficient reads like the model at ``t + τ``.
    curvature_s2
        Second-order smoothing κ, s² (a central difference of rates sampled every Δt alone
        gives Δt²/4: its response is the trapezoid ¼, ½, ¼ of the derivative).
    t_skew, t_curvature
        Their t statistics, clustered by maneuver.
    samples, maneuvers
        Calibration samples (alpha below ``alpha_l_deg``) and their maneuvers.
    skipped
        Why a coefficient was not calibrated ("" when it was).
    """

    skew_s: dict[str, float] = field(default_factory=dict)
    curvature_s2: dict[str, float] = field(default_factory=dict)
    t_skew: dict[str, float] = field(default_factory=dict)
    t_curvature: dict[str, float] = field(default_factory=dict)
    samples: dict[str, int] = field(default_factory=dict)
    maneuvers: dict[str, int] = field(default_factory=dict)
    skipped: dict[str, str] = field(default_factory=dict)

    def note(self, coef: str) -> str:
        """One line for the fit's notes."""
        if self.skipped.get(coef):
            return f"{coef}: measurement chain not calibrated: {self.skipped[coef]}"
        return (
            f"{coef}: measurement chain calibrated below alpha_l on {self.samples[coef]} samples "
            f"of {self.maneuvers[coef]} maneuvers: C_qual + tau dC_qual/dt + kappa "
            f"d2C_qual/dt2, tau = {1e3 * self.skew_s[coef]:.2f} ms "
            f"(t = {self.t_skew[coef]:.1f}), kappa = {self.curvature_s2[coef]:.3g} s^2 "
            f"(t = {self.t_curvature[coef]:.1f})"
        )


def calibrate_chain(
    df: pl.DataFrame,
    q: Mapping[str, np.ndarray],
    coefs: Sequence[str],
    cfg: FitConfig,
    flaps: Sequence[float],
    *,
    structures: Mapping[str, Sequence[tuple[str, str]]] | None = None,
) -> tuple[dict[str, np.ndarray], ChainCalibration]:
    """The qualified model seen through the measurement chain (``FitConfig.chain_calibration``).

    Per coefficient ``C``, on the rows whose alpha is below the flap's ``alpha_l_deg`` (where
    the extended model is the qualified one), ``z = C_meas - C_qual`` is regressed on
    ``[1, dC_qual/dt, d²C_qual/dt²]`` (derivatives by three-point differences within each
    maneuver) and, when ``structures`` gives the Δ terms postulated for ``C`` (a fit without
    selection), on their regressors too: a Δ the fit is told exists below alpha_l and that
    correlates with the model's derivatives would otherwise be read as the chain (an omitted
    regressor). With a selection the structure is not known yet and the premise of the blend,
    no Δ below alpha_l, is used. The slopes of the two derivatives are the chain's time skew
    τ (s) and second-order smoothing κ (s²),
    and ``C_qual + τ dC_qual/dt + κ d²C_qual/dt²`` is returned for every row (unchanged where
    a derivative is not defined: a maneuver's ends, gaps). The chain is a property of the
    instrumentation and of the preprocessing, the same at every alpha, so the estimate from
    the trusted range carries over; the Δ the fit identifies is then what the qualified model
    lacks, not the chain's response to the whole aircraft's coefficient. Skipped, with the
    reason, without the time column ``t``, with fewer than :data:`CHAIN_MIN_SAMPLES`
    calibration samples or ``min_maneuvers_identified`` maneuvers (at least 2, for the
    clustered errors), or when the derivatives are (near) combinations of the intercept and
    the structure's regressors below alpha_l. The numerics are ``aero_core::chain``.

    Parameters
    ----------
    df
        Model frame: ``t`` (s), ``alpha_deg``, ``flap_deg``, ``maneuver_id``, ``C_meas``.
    q
        Qualified coefficients per coefficient name, one value per row of ``df``.
    coefs
        Coefficients to calibrate.
    cfg
        Fit settings (``alpha_l_deg``, ``min_maneuvers_identified``).
    flaps
        The flap settings of the data, deg.
    structures
        Per coefficient, the Δ terms ``(name, regressor expression)`` fitted without selection
        (``None``: none; a regressor whose channels the data lack, or that is constant below
        alpha_l, is left out of the calibration).

    Returns
    -------
    tuple
        The calibrated qualified coefficients (a new dict; coefficients not calibrated are
        the input arrays) and the :class:`ChainCalibration`.
    """
    out = {c: np.asarray(v, dtype=float) for c, v in q.items()}
    cal = ChainCalibration()
    if "t" not in df.columns:
        for c in coefs:
            cal.skipped[c] = "the data have no time column 't'"
        return out, cal
    t = np.ascontiguousarray(df["t"].cast(pl.Float64).to_numpy())
    man = maneuver_keys(df)
    alpha = df["alpha_deg"].cast(pl.Float64).to_numpy()
    flap = df["flap_deg"].cast(pl.Float64).to_numpy()
    alpha_l = np.full(df.height, -np.inf)
    for f in flaps:
        alpha_l[flap == f] = _per_flap(cfg.alpha_l_deg, f, "alpha_l_deg")
    trusted = np.isfinite(alpha) & (alpha < alpha_l)
    terms = {c: [(str(n), str(e)) for n, e in (structures or {}).get(c, [])] for c in coefs}
    # the channels the structures read that the data have (a term on another is left out)
    channels = {ch for ts in terms.values() for _, e in ts for ch in regressor_channels(e)}
    columns = {
        ch: np.ascontiguousarray(df[ch].cast(pl.Float64).to_numpy())
        for ch in sorted(channels)
        if ch in df.columns
    }
    # the engine: three-point time derivatives within maneuvers, the clustered least squares
    # of each coefficient (in parallel), the calibrated values
    results = _core.calibrate_chain(
        t,
        man,
        trusted,
        [
            (
                np.ascontiguousarray(out[c]),
                np.ascontiguousarray(df[f"{c}_meas"].cast(pl.Float64).to_numpy()),
                terms[c],
            )
            for c in coefs
        ],
        columns,
        CHAIN_MIN_SAMPLES,
        cfg.min_maneuvers_identified,
    )
    for c, (why, est, corrected) in zip(coefs, results, strict=True):
        if est is None or corrected is None:
            cal.skipped[c] = why
            continue
        out[c] = corrected
        (
            cal.skew_s[c], cal.curvature_s2[c], cal.t_skew[c], cal.t_curvature[c],
            cal.samples[c], cal.maneuvers[c],
        ) = est  # fmt: skip
    return out, cal


def _stall_alphas(
    df: pl.DataFrame, flaps: Sequence[float], given: Mapping[float, float]
) -> dict[float, float]:
    """Per flap (in ``flaps`` order), the stall alpha the user gave (``given``, deg) or
    :func:`stall_alpha` of its rows."""
    out = {f: float(given[f]) for f in flaps if f in given}
    if len(out) < len(flaps):
        cols = ["flap_deg", "alpha_deg", "CX_meas", "CZ_meas", "ct_left", "ct_right"]
        parts = {
            float(k[0]): v
            for k, v in df.select([c for c in cols if c in df.columns])
            .partition_by("flap_deg", as_dict=True)
            .items()
            if k[0] is not None
        }
        out.update({f: stall_alpha(parts[f]) for f in flaps if f not in out})
    return {f: out[f] for f in flaps}


def _in_background(fn: Callable[[pl.DataFrame], T], data: pl.DataFrame) -> Future[T]:
    """``fn(data)`` on a thread of its own, which ends when it is done."""
    ex = ThreadPoolExecutor(max_workers=1, thread_name_prefix="aerodelta")
    try:
        return ex.submit(fn, data)
    finally:
        ex.shutdown(wait=False)


def fit(
    data: pl.DataFrame,
    *,
    qualified: str | Path = "auto",
    config: FitConfig | None = None,
    progress: bool = False,
) -> FitResult:
    """Identify the Δ model from ingested flight records.

    Per flap and coefficient: select the structure from the candidate pool (unless
    ``config.selection`` is ``None``), fit the kept regressors bin by bin, smooth them and,
    with ``config.bootstrap > 0``, bootstrap them over maneuvers for confidence bands.

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
    coefs = list(cfg.structures)
    for c in coefs:
        if c not in COEFFICIENTS:
            raise DataError(f"structures: unknown coefficient '{c}'; use {list(COEFFICIENTS)}")
    if cfg.selection not in (None, "stepwise", "mof"):
        raise DataError(f"selection='{cfg.selection}': use 'stepwise', 'mof' or None")
    if cfg.max_vif is not None and not (isinstance(cfg.max_vif, int | float) and cfg.max_vif > 1.0):
        raise DataError(
            f"max_vif={cfg.max_vif!r}: a variance inflation factor is at least 1; give a limit "
            "above 1 (Klein & Morelli: 10) or None for the condition-index rule only"
        )
    pools = cfg.candidates if cfg.candidates is not None else DEFAULT_CANDIDATES
    if cfg.selection is not None:
        missing = [c for c in coefs if c not in pools]
        if missing:
            raise DataError(
                f"candidates: no candidate pool for {missing}; give one per coefficient"
            )
    df = model_frame(data)
    needed = ["alpha_deg", "flap_deg", "maneuver_id"] + [f"{c}_meas" for c in coefs]
    if cfg.band_hz is not None and "t" not in df.columns:
        raise DataError(
            f"fit: band_hz={cfg.band_hz} needs the time column 't' (s) of the records; keep it "
            "from the ingestion or fit without the band limit, FitConfig(band_hz=None)"
        )
    missing = [c for c in needed if c not in df.columns]
    if missing:
        raise DataError(f"fit: the data lack {missing}; run aerodelta.ingest first")
    # the provenance hash (hashlib releases the GIL) beside the qualified model, the chain
    # calibration and the engine's fits
    data_hash = _in_background(data_sha256, data)
    qual = resolve(df, qualified)
    q = qual.predict(df)
    flaps = sorted(float(f) for f in df["flap_deg"].unique().drop_nulls())
    if not flaps:
        raise DataError("fit: no row has a flap setting (flap_deg); check the manifest")
    notes: list[str] = []
    # the stall alpha per flap (measured lift only) on this thread while the engine passes the
    # qualified model through the smoother (it releases the GIL)
    matching = _in_background(partial(through_smoother, q=q), df) if cfg.smoother_match else None
    stall = _stall_alphas(df, flaps, cfg.stall_alpha_deg)
    if matching is not None:
        q, matched = matching.result()
        if (line := matched.note()) is not None:
            notes.append(line)
    if cfg.chain_calibration:
        given = cfg.structures if cfg.selection is None else None
        q, chain = calibrate_chain(df, q, coefs, cfg, flaps, structures=given)
        notes.extend(chain.note(c) for c in coefs)
    df = pl.concat([df, pl.DataFrame({f"{c}_qual": q[c] for c in COEFFICIENTS})], how="horizontal")
    # maneuvers per flap setting (the null flap, refused above when alone, counts nowhere)
    n_maneuvers = {
        float(f): int(n)
        for f, n in df.group_by("flap_deg").agg(pl.col("maneuver_id").n_unique()).iter_rows()
        if f is not None
    }
    most = max(n_maneuvers.values(), default=0)
    if most < cfg.min_maneuvers_identified:
        raise DataError(
            f"fit: too little data: at most {most} maneuvers at one flap "
            f"setting, and a parameter needs {cfg.min_maneuvers_identified} maneuvers in an "
            "alpha bin to be identified (min_maneuvers_identified); fly more maneuvers"
        )
    # structures the user gave (not the thesis defaults): a term of theirs is never dropped
    custom_structures = {
        c: [tuple(t) for t in v] != [tuple(t) for t in DEFAULT_STRUCTURES.get(c, [])]
        for c, v in cfg.structures.items()
    }
    bins_rows: list[pl.DataFrame] = []
    param_rows: list[pl.DataFrame] = []
    cons_rows: list[dict[str, Any]] = []
    smooth_rows: list[dict[str, Any]] = []
    struct_rows: list[dict[str, Any]] = []
    selbin_rows: list[pl.DataFrame] = []
    cv_rows: list[dict[str, Any]] = []
    tables: dict[str, dict[str, dict[float, tuple[np.ndarray, ...]]]] = {}
    regressors: dict[str, dict[str, str]] = {c: {} for c in coefs}
    replicates: dict[tuple[str, str, float], tuple[np.ndarray, np.ndarray]] = {}

    tasks = [(f, c) for f in flaps for c in coefs]
    bar = None
    if progress:
        bar = tqdm(total=len(tasks), desc="fit", unit="fit", file=sys.stderr)

    def collect(
        job: tuple[float, str, list[tuple[str, str]], list[tuple[str, str]], list, Future],
    ) -> None:
        flap, coef, regs, default, extra, fut = job
        out = fut.result()
        chosen: list[int] = list(out["chosen"])
        # terms left out as collinear with others at this flap (aero_core::select::collinear)
        pruned = {int(c): str(why) for c, why in out["pruned"]}
        notes.extend(
            f"{coef} at flap {flap:g} deg: '{regs[c][0]}' {why}" for c, why in pruned.items()
        )
        final = [regs[i] for i in chosen]
        regressors[coef].update(dict(final))
        b_rows, p_rows = _bin_rows(coef, flap, out, final)
        bins_rows.append(b_rows)
        param_rows.append(p_rows)
        if cfg.selection is not None and out["selection"] is None:
            n_man = n_maneuvers[flap]
            struct_rows.extend(
                {
                    "coefficient": coef, "flap_deg": flap, "param": name, "regressor": expr,
                    "bins_fitted": None, "bins_selected": None, "kept": i not in pruned,
                    "note": f"not selected: {n_man} maneuvers at this flap, "
                    f"{cfg.min_maneuvers_selection} needed; the given structure is fitted"
                    + (f"; {pruned[i]}" if i in pruned else ""),
                }
                for i, (name, expr) in enumerate(regs)
            )  # fmt: skip
        if out["selection"] is not None:
            st, sb, cv = _selection_rows(
                coef,
                flap=flap,
                sel=out["selection"],
                pool=regs,
                chosen=chosen,
                default=default if extra else [],
            )
            for c, why in pruned.items():
                st[c]["note"] = why
            struct_rows.extend(st)
            selbin_rows.append(sb)
            cv_rows.extend(cv)
        names: list[str] = out["names"]
        for j, name in enumerate(names):
            cons_rows.append(
                {
                    "coefficient": coef, "flap_deg": flap, "param": name,
                    "scatter": out["consistency_scatter"][j],
                    "step_z": out["consistency_step_z"][j],
                    "pairs": out["consistency_pairs"][j],
                }
            )  # fmt: skip
        boot = out["bootstrap"]
        if boot is not None:
            ng = len(boot["alpha_deg"])
            nrep = int(boot["n_replicates"])
            lower = np.asarray(boot["lower"]).reshape(len(names), ng)
            upper = np.asarray(boot["upper"]).reshape(len(names), ng)
            reps = np.asarray(boot["replicates"]).reshape(len(names), nrep, ng)
            # failed replicates are counted, never read as zeros: one note per count
            failed: dict[int, list[str]] = {}
            for name, ok in zip(names, boot["replicates_ok"], strict=True):
                if int(ok) < nrep:
                    failed.setdefault(int(ok), []).append(name)
            for ok, which in sorted(failed.items()):
                band = (
                    "no smoothed band (fewer than half of them left)"
                    if 2 * ok < nrep or ok < 2
                    else f"the smoothed band from the other {ok}"
                )
                notes.append(
                    f"{coef} at flap {flap:g} deg: {nrep - ok} of {nrep} bootstrap replicates "
                    f"could not smooth {', '.join(which)} (too few of the bins refitted: too few "
                    f"distinct maneuvers drawn of the {n_maneuvers[flap]} at this flap); {band}"
                )
        for j, (name, grid, values, nused, note) in enumerate(out["smoothed"]):
            g, v = np.asarray(grid), np.asarray(values)
            lo = lower[j] if boot is not None else np.full(len(g), np.nan)
            hi = upper[j] if boot is not None else np.full(len(g), np.nan)
            tables.setdefault(coef, {}).setdefault(name, {})[flap] = (g, v, lo, hi)
            if boot is not None:
                replicates[(coef, name, flap)] = (g, reps[j])
            for a, val, lv, hv in zip(g, v, lo, hi, strict=True):
                smooth_rows.append(
                    {
                        "coefficient": coef, "flap_deg": flap, "param": name,
                        "alpha_deg": a, "value": val, "lower": lv, "upper": hv,
                        "bins_used": nused, "note": note,
                    }
                )  # fmt: skip
        if bar is not None:
            bar.update(1)

    # the engine releases the GIL: the (flap, coefficient) fits run side by side, and their
    # results are assembled in a fixed order (the same output for any number of threads)
    jobs: list[tuple[float, str, list[tuple[str, str]], list[tuple[str, str]], list, Future]] = []
    # the columns any regressor can read (names appearing in its expression), and the fit's own
    exprs = [e for c in coefs for _, e in [*cfg.structures[c], *pools.get(c, [])]]
    wanted = {"alpha_deg", "t", *(f"{c}_{k}" for c in coefs for k in ("meas", "qual"))}
    wanted |= {c for c in df.columns if any(c in e for e in exprs)}
    # per flap, those (the other columns are not copied)
    keep = wanted | {"flap_deg", "maneuver_id"}
    parts = {
        float(k[0]): v
        for k, v in df.select([c for c in df.columns if c in keep])
        .partition_by("flap_deg", as_dict=True)
        .items()
    }
    with ThreadPoolExecutor(max_workers=engine_threads(cap=4)) as ex:
        for flap in flaps:
            full, codes = _flap_columns(parts[flap], wanted)
            # values per channel a regressor can read (a channel absent from the data is not
            # counted: the engine names it as unknown)
            counts = {c: int(np.isfinite(v).sum()) for c, v in full.items()}
            counts.update({c: 0 for c in wanted if c in df.columns and c not in full})
            selection = cfg.selection if n_maneuvers[flap] >= cfg.min_maneuvers_selection else None
            for coef in coefs:
                default, dn = _screen_regressors(
                    [(str(n), str(e)) for n, e in cfg.structures[coef]], counts,
                    coef=coef, flap=flap, user_named=custom_structures[coef], what="structure",
                )  # fmt: skip
                if selection is None:
                    regs = default
                    notes.extend(dn)
                else:
                    regs, pn = _screen_regressors(
                        [(str(n), str(e)) for n, e in pools[coef]], counts, coef=coef, flap=flap,
                        user_named=cfg.candidates is not None, what="candidate pool",
                    )  # fmt: skip
                    notes.extend(pn)
                forced = [i for i, (_, e) in enumerate(regs) if e.strip() == "1"]
                by_expr = {e.replace(" ", ""): i for i, (_, e) in enumerate(regs)}
                extra_cols = [by_expr.get(e.replace(" ", "")) for _, e in default]
                extra = [sorted(c for c in extra_cols if c is not None)] if selection else []
                pairs = [
                    (by_expr[a], by_expr[b])
                    for a, b in BETA_KINK
                    if cfg.beta_kink and selection and a in by_expr and b in by_expr
                ]
                fut = _submit(
                    ex, cfg, full, codes, coef, regs=regs,
                    alpha_max=stall[flap] + cfg.past_stall_deg, selection=selection,
                    forced=forced, extra=extra, bootstrap=cfg.bootstrap, flap=flap, notes=notes,
                    prune=selection is not None or not custom_structures[coef], companions=pairs,
                )  # fmt: skip
                jobs.append((flap, coef, regs, default, extra, fut))
            while len(jobs) > 2 * len(coefs):  # bounded memory: about three flaps in flight
                collect(jobs.pop(0))
        for job in jobs:
            collect(job)
    if bar is not None:
        bar.close()

    spec = _model_spec(
        cfg, flaps=flaps, tables=tables, regressors=regressors, stall=stall, data=data,
        data_hash=data_hash.result(), qualified=qual.source,
    )  # fmt: skip
    return FitResult(
        model=DeltaModel.from_spec(spec, "fitted model"),
        bins=pl.concat(bins_rows) if bins_rows else pl.DataFrame(),
        params=_with_significance(pl.concat(param_rows), cfg.band_level)
        if param_rows
        else pl.DataFrame(),
        consistency=pl.DataFrame(cons_rows),
        smoothed=pl.DataFrame(smooth_rows),
        stall_alpha_deg=stall,
        structure=pl.DataFrame(struct_rows),
        selection_bins=pl.concat(selbin_rows) if selbin_rows else pl.DataFrame(),
        cross_validation=pl.DataFrame(cv_rows),
        replicates=replicates,
        notes=notes,
    )


def _model_spec(
    cfg: FitConfig,
    *,
    flaps: list[float],
    tables: dict[str, dict[str, dict[float, tuple[np.ndarray, ...]]]],
    regressors: Mapping[str, Mapping[str, str]],
    stall: dict[float, float],
    data: pl.DataFrame,
    data_hash: str,
    qualified: str,
) -> dict[str, Any]:
    coefficients: dict[str, Any] = {}
    for coef, params in tables.items():
        terms = []
        regs = regressors[coef]
        for name, per_flap in params.items():
            grid = np.unique(np.concatenate([t[0] for t in per_flap.values()]))

            def resample(
                k: int,
                per_flap: Mapping[float, tuple[np.ndarray, ...]] = per_flap,
                grid: np.ndarray = grid,
            ) -> list[list[float]]:
                # np.interp holds the end values: each flap's table is reproduced at its nodes;
                # a flap where the parameter is not in the structure gets zeros
                return [
                    np.interp(grid, per_flap[f][0], per_flap[f][k]).tolist()
                    if f in per_flap
                    else [0.0] * len(grid)
                    for f in flaps
                ]

            term: dict[str, Any] = {
                "name": name, "regressor": regs[name], "alpha_deg": grid.tolist(),
                "values": resample(1),
            }  # fmt: skip
            if cfg.bootstrap > 0 and all(np.isfinite(t[2]).all() for t in per_flap.values()):
                term["band"] = {"level": cfg.band_level, "lower": resample(2), "upper": resample(3)}
            terms.append(term)
        coefficients[coef] = {
            "terms": terms,
            "alpha_l_deg": [_per_flap(cfg.alpha_l_deg, f, "alpha_l_deg") for f in flaps],
            "alpha_u_deg": [_per_flap(cfg.alpha_u_deg, f, "alpha_u_deg") for f in flaps],
        }
    spec: dict[str, Any] = {
        "schema": SCHEMA,
        "flaps_deg": flaps,
        "alpha_channel": "alpha_deg",
        "flap_channel": "flap_deg",
        "coefficients": coefficients,
        "provenance": {
            "library": f"aerodelta {__version__}",
            "data_sha256": data_hash,
            "qualified": qualified,
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
    envelope = data_envelope(data, flaps, cfg.min_maneuvers_identified)
    if envelope is not None:
        spec["envelope"] = envelope
    return spec


#: Width of the alpha bands of the validated envelope, deg.
ENVELOPE_BAND_DEG = 1.0


def data_envelope(
    data: pl.DataFrame,
    flaps: Sequence[float],
    min_maneuvers: int,
    band_deg: float = ENVELOPE_BAND_DEG,
) -> dict[str, Any] | None:
    """The flight data's alpha/beta coverage per flap, as stored with a fitted model
    (``envelope`` in the model JSON; ``aero_core::envelope``): per flap setting and alpha band
    of ``band_deg`` (deg), the smallest and largest sideslip measured (deg) where at least
    ``min_maneuvers`` maneuvers have samples. ``None`` when ``flap_deg``, ``alpha_deg``,
    ``beta_deg`` or ``maneuver_id`` is missing. The simulator's "outside the validated
    envelope" indication (14 CFR Part 60, FSTD Directive 2) is read from it
    (:meth:`aerodelta.model.DeltaModel.in_envelope`)."""
    need = ("flap_deg", "alpha_deg", "beta_deg", "maneuver_id")
    if any(c not in data.columns for c in need):
        return None
    cells = (
        data.select(
            pl.col("flap_deg").cast(pl.Float64),
            (pl.col("alpha_deg").cast(pl.Float64) / band_deg).floor().alias("band"),
            pl.col("beta_deg").cast(pl.Float64),
            "maneuver_id",
        )
        .drop_nulls()
        .filter(pl.col("band").is_finite() & pl.col("beta_deg").is_finite())
        .group_by("flap_deg", "band")
        .agg(
            pl.col("beta_deg").min().alias("beta_min_deg"),
            pl.col("beta_deg").max().alias("beta_max_deg"),
            pl.col("maneuver_id").n_unique().alias("maneuvers"),
        )
        .filter(pl.col("maneuvers") >= min_maneuvers)
        .with_columns(pl.col("band").cast(pl.Int64), pl.col("maneuvers").cast(pl.UInt32))
        .sort("flap_deg", "band")
    )
    bands = [cells.filter(pl.col("flap_deg") == f).drop("flap_deg").to_dicts() for f in flaps]
    return {
        "band_deg": band_deg,
        "flaps_deg": [float(f) for f in flaps],
        "bands": bands,
        "min_maneuvers": int(min_maneuvers),
    }


def theil_inequality(measured: np.ndarray, predicted: np.ndarray) -> float:
    """Theil inequality coefficient ``rms(y - ŷ) / (rms(y) + rms(ŷ))`` (0 perfect, 1 useless)."""
    ok = np.isfinite(measured) & np.isfinite(predicted)
    y, yh = measured[ok], predicted[ok]
    den = np.sqrt(np.mean(y**2)) + np.sqrt(np.mean(yh**2))
    return float(np.sqrt(np.mean((y - yh) ** 2)) / den) if den > 0 else math.nan


def validate_model(
    model: DeltaModel, data: pl.DataFrame, *, qualified: str | Path = "auto"
) -> pl.DataFrame:
    """Qualified vs extended model against measured coefficients, per coefficient.

    Returns a frame with RMS error and Theil inequality coefficient (TIC) of the qualified and of
    the extended model (``C_qual + w dC``), and their ratio, on the given records (use maneuvers
    held out of the fit). ``qualified="auto"`` takes the qualified model the fit recorded
    (a DAVE-ML one must be named again: the model records its file name, not its path).
    """
    df = model_frame(data)
    qualified = for_model(model.to_spec(), qualified, "pass its path as qualified=")
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
