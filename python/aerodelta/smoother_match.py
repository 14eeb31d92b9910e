"""The qualified model seen through the smoother the measured coefficients came through.

``aerodelta ingest`` smooths each channel per maneuver before it builds the measured
coefficients (zero-phase optimal Fourier smoothing, SIDPAC ``smoo``, each channel with the
Wiener weights its own spectrum chose): C_Y carries the band of the lateral accelerometer,
C_l that of the roll rate (through ṗ), C_n that of the yaw rate. The qualified model evaluated
along the records keeps its full band, so ``C_meas - C_qual`` holds the part of every fast
transient that the smoothing took from the measurement only. With sensor noise the lateral
accelerometer's cut-off falls to about 2 Hz and the recoveries' side-force transient then read
as a ΔC_Y_0 (JSBSim DHC-6: about a third of a bin's standard error, docs/identification.md).

Once chosen, the weights make the smoother linear, so the model's force, ``C_qual q̄``, passed
maneuver by maneuver through the weights the ingestion applied to the measurement's channel and
divided by ``q̄`` again, carries exactly the measurement's band (Klein & Morelli, *Aircraft
System Identification*, 2006, Section 5.5: equation error needs both sides filtered alike). The
weights are redesigned from the raw channel by the same deterministic smoother; a maneuver whose
rows are no longer the record the ingestion smoothed (cut, resampled or edited since: smoothing
its raw roll rate again does not give the stored ``p_s_dps``) is left at full band and counted.
The numerics are ``aero_core::preprocess::matched``.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta._groups import maneuver_keys

#: The raw channel whose smoothing sets each measured coefficient's band.
MEASURED_CHANNEL = {"Cl": "p_dps", "Cn": "r_dps", "CY": "ay_mps2"}

#: The columns the match reads besides the references: time (s), maneuver, the roll rate
#: raw and as the ingestion stored it smoothed (deg/s), the dynamic pressure (Pa).
NEEDED = ("t", "maneuver_id", "p_dps", "p_s_dps", "qbar_pa")


@dataclass(frozen=True)
class SmootherMatch:
    """What :func:`through_smoother` did, in maneuvers.

    Attributes
    ----------
    matched
        Maneuvers whose coefficients were passed through the ingestion's smoother.
    unsmoothed
        Maneuvers ingested without smoothing (left as they are: nothing to match).
    changed
        Maneuvers whose rows are not the record the ingestion smoothed (left at full band).
    nonfinite
        Coefficient-maneuvers left at full band for a non-finite value.
    skipped
        Why nothing was matched (the data lack a column), or ``""``.
    full_band
        Coefficients left at full band because the data lack their channel.
    """

    matched: int = 0
    unsmoothed: int = 0
    changed: int = 0
    nonfinite: int = 0
    skipped: str = ""
    full_band: tuple[str, ...] = ()

    def note(self) -> str | None:
        """One line for the fit's notes when a maneuver was left at full band, else ``None``."""
        if self.skipped:
            return (
                "the qualified model is compared with the measured coefficients at full band: "
                f"{self.skipped}"
            )
        parts = [
            f"{c} (no '{MEASURED_CHANNEL[c]}' channel) in every maneuver" for c in self.full_band
        ]
        if self.changed:
            parts.append(
                f"{self.changed} maneuver(s) whose rows changed since the ingestion smoothed "
                "them (cut, resampled or edited)"
            )
        if self.nonfinite:
            parts.append(f"{self.nonfinite} coefficient-maneuver(s) holding a non-finite value")
        if not parts:
            return None
        return (
            f"the qualified model seen through the ingestion's smoother in {self.matched} "
            f"maneuver(s), left at full band for {'; '.join(parts)}: the Δ there holds the "
            "part of fast transients the smoothing took from the measurement only"
        )


def through_smoother(
    frame: pl.DataFrame, q: Mapping[str, np.ndarray]
) -> tuple[dict[str, np.ndarray], SmootherMatch]:
    """Each qualified coefficient in ``q`` seen through the smoother its measurement came
    through (see the module doc).

    Parameters
    ----------
    frame
        The ingested records (a model frame): ``t`` (s), ``maneuver_id``, ``p_dps`` and
        ``p_s_dps`` (deg/s), ``qbar_pa`` (Pa) and each coefficient's raw channel
        (:data:`MEASURED_CHANNEL`).
    q
        Qualified coefficients by name (``Cl``, ``Cn``, ``CY``), one value per row.

    Returns
    -------
    tuple
        The coefficients (a new dict; one whose channel the data lack is the input array) and
        the :class:`SmootherMatch`.
    """
    out = {c: np.asarray(v, dtype=float) for c, v in q.items()}
    missing = [c for c in NEEDED if c not in frame.columns]
    if missing:
        return out, SmootherMatch(
            skipped=f"the data lack {missing} (records not from aerodelta.ingest)"
        )
    coefs = [c for c in out if MEASURED_CHANNEL.get(c) in frame.columns]
    absent = tuple(c for c in out if c not in coefs)
    if not coefs:
        return out, SmootherMatch(
            skipped=f"the data lack the channels {sorted(set(MEASURED_CHANNEL.values()))}"
        )

    def col(name: str) -> np.ndarray:
        return np.ascontiguousarray(frame[name].cast(pl.Float64).to_numpy(), dtype=np.float64)

    values, (matched, unsmoothed, changed, nonfinite) = _core.through_smoother(
        col("t"),
        maneuver_keys(frame),
        col("p_dps"),
        col("p_s_dps"),
        col("qbar_pa"),
        [(col(MEASURED_CHANNEL[c]), np.ascontiguousarray(out[c])) for c in coefs],
    )
    for c, v in zip(coefs, values, strict=True):
        out[c] = np.asarray(v)
    return out, SmootherMatch(matched, unsmoothed, changed, nonfinite, full_band=absent)
