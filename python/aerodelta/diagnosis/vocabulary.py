"""Candidate effects of the sim-to-real gap diagnosis (DESIGN.md, "Effect vocabulary").

Each candidate is a group of regressors per coefficient. An **aerodynamic** candidate's
coefficients are functions of alpha (per flap, on a piecewise-linear "hat" basis in alpha, the
continuous analogue of the thesis's alpha bins, Section 3.3.1); a **measurement** candidate is one
global parameter (a vane bias in deg, a lag in s, an accelerometer displacement in m) shared by
every alpha and flap, its regressor the first-order effect of that error on the gap
``C_meas - C_sim``:

- ``alpha_vane_bias``, ``beta_vane_bias`` (b, deg): the simulator is evaluated at the biased
  angle, so ``gap = -b dC_sim/d(angle)``;
- ``control_lag`` (tau, s): the recorded controls lead the acting ones,
  ``gap = -tau sum_d dC_sim/d(delta) d(delta)/dt``;
- ``time_skew`` (tau, s): air data recorded late, ``gap = tau (dC_sim/dalpha alphadot +
  dC_sim/dbeta betadot)``; with a black-box simulator (``*_sim`` columns, which cannot be
  evaluated at other states) every input late, ``gap = tau dC_sim/dt`` along the record;
- ``accelerometer_offset`` (dx, dz, m; C_Y only): the measured side force picks up
  ``m/(qbar S) (rdot dx - pdot dz)`` (omega-dot cross r).

Regressor angles are in degrees (as the Δ model's), rates non-dimensional (``phat``, ``rhat``).
User-defined candidates are polars expressions (or SQL expression strings) over the data.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Literal

import polars as pl

from aerodelta.exceptions import InvalidInputError

COEFFICIENTS = ("Cl", "Cn", "CY")

Kind = Literal["aerodynamic", "measurement", "user"]


@dataclass(frozen=True)
class Candidate:
    """One candidate effect for one coefficient.

    Attributes
    ----------
    name
        Vocabulary name (or the user's).
    kind
        ``"aerodynamic"`` and ``"user"`` act through alpha-dependent coefficients;
        ``"measurement"`` through global parameters.
    regressors
        Names of the regressor columns of the design (see :data:`AERO_REGRESSORS` and
        :data:`MEASUREMENT_REGRESSORS`).
    """

    name: str
    kind: Kind
    regressors: tuple[str, ...]

    @property
    def global_(self) -> bool:
        """True when the effect is one parameter per regressor for all alpha and flaps."""
        return self.kind == "measurement"


#: Aerodynamic regressors as polars expressions over a model frame (angles in deg).
AERO_REGRESSORS: dict[str, pl.Expr] = {
    "one": pl.lit(1.0),
    "beta": pl.col("beta_deg"),
    "phat": pl.col("phat"),
    "rhat": pl.col("rhat"),
    "da_db": (pl.col("da_deg") - 2.0).clip(lower_bound=0.0)
    + (pl.col("da_deg") + 2.0).clip(upper_bound=0.0),
    "dr": pl.col("dr_deg"),
    "ds": pl.col("ds_deg"),
    "alphadot_ds": pl.col("alphadot_dps") * pl.col("ds_deg"),
    "ct_sum": pl.col("ct_left") + pl.col("ct_right"),
    "ct_diff": pl.col("ct_left") - pl.col("ct_right"),
    "betadot": pl.col("betadot_dps"),
    "alphadot_beta": pl.col("alphadot_dps") * pl.col("beta_deg"),
    "alphadot_betadot": pl.col("alphadot_dps") * pl.col("betadot_dps"),
}

#: Measurement regressors (computed from the simulator's sensitivities; see module doc).
MEASUREMENT_REGRESSORS = (
    "m_alpha_bias",
    "m_beta_bias",
    "m_control_lag",
    "m_time_skew",
    "m_acc_dx",
    "m_acc_dz",
)

_SIDESLIP_RATE = ("betadot", "alphadot_beta", "alphadot_betadot")

#: Control, thrust and sideslip-rate candidates shared by both moments.
_MOMENT_CONTROLS: list[tuple[str, tuple[str, ...]]] = [
    ("aileron_effectiveness", ("da_db",)),
    ("rudder_effectiveness", ("dr",)),
    ("spoiler_effect", ("ds", "alphadot_ds")),
    ("thrust_effect", ("ct_sum",)),
    ("thrust_asymmetry", ("ct_diff",)),
    ("sideslip_rate", _SIDESLIP_RATE),
]

#: Aerodynamic candidates per coefficient: the vocabulary's regressor groups (DESIGN.md).
AERODYNAMIC: dict[str, list[tuple[str, tuple[str, ...]]]] = {
    "Cl": [
        ("lateral_asymmetry", ("one",)),
        ("dihedral", ("beta",)),
        ("roll_damping", ("phat",)),
        ("roll_due_to_yaw_rate", ("rhat",)),
        *_MOMENT_CONTROLS,
    ],
    "Cn": [
        ("lateral_asymmetry", ("one",)),
        ("directional_stability", ("beta",)),
        ("yaw_damping", ("rhat",)),
        ("yaw_due_to_roll_rate", ("phat",)),
        *_MOMENT_CONTROLS,
    ],
    "CY": [
        ("lateral_asymmetry", ("one",)),
        ("sideforce_beta", ("beta",)),
        ("rudder_effectiveness", ("dr",)),
        ("spoiler_effect", ("ds", "alphadot_ds")),
        ("thrust_effect", ("ct_sum",)),
        ("sideslip_rate", _SIDESLIP_RATE),
    ],
}

#: Measurement candidates per coefficient.
MEASUREMENT: dict[str, list[tuple[str, tuple[str, ...]]]] = {
    c: [
        ("alpha_vane_bias", ("m_alpha_bias",)),
        ("beta_vane_bias", ("m_beta_bias",)),
        ("control_lag", ("m_control_lag",)),
        ("time_skew", ("m_time_skew",)),
    ]
    for c in COEFFICIENTS
}
MEASUREMENT["CY"] = [*MEASUREMENT["CY"], ("accelerometer_offset", ("m_acc_dx", "m_acc_dz"))]

#: Measurement candidates that need the simulator's sensitivities (a loadable model).
NEEDS_MODEL = frozenset({"alpha_vane_bias", "beta_vane_bias", "control_lag"})


@dataclass(frozen=True)
class Vocabulary:
    """The candidate list per coefficient, and the expressions of user-defined regressors.

    Build one with :func:`default_vocabulary` and, for effects of your own,
    :meth:`with_user_effects`.
    """

    candidates: Mapping[str, Sequence[Candidate]]
    user_regressors: Mapping[str, pl.Expr] = field(default_factory=dict)

    def for_coefficient(self, coefficient: str) -> list[Candidate]:
        """Candidates of ``coefficient`` (``"Cl"``, ``"Cn"`` or ``"CY"``)."""
        return list(self.candidates.get(coefficient, ()))

    def with_user_effects(
        self, effects: Mapping[str, Mapping[str, Sequence[str | pl.Expr]]]
    ) -> Vocabulary:
        """Add user-defined aerodynamic effects.

        Parameters
        ----------
        effects
            ``{name: {coefficient: [regressor, ...]}}``; a regressor is a polars expression
            or a SQL expression string over the data's columns (``"beta_deg * rhat"``).
            Each regressor's coefficient is a function of alpha, per flap.
        """
        cands = {c: list(v) for c, v in self.candidates.items()}
        regs = dict(self.user_regressors)
        for name, per_coef in effects.items():
            if not isinstance(per_coef, Mapping):
                raise InvalidInputError(
                    f"user effect '{name}': give {{coefficient: [regressor, ...]}}, not "
                    f"{type(per_coef).__name__}"
                )
            for coef, given in per_coef.items():
                if coef not in COEFFICIENTS:
                    raise InvalidInputError(
                        f"user effect '{name}': unknown coefficient '{coef}'; use one of "
                        f"{', '.join(COEFFICIENTS)}"
                    )
                # one regressor given alone, not a list of characters
                exprs = [given] if isinstance(given, str | pl.Expr) else given
                names = []
                for i, e in enumerate(exprs):
                    key = f"user:{name}:{coef}:{i}"
                    if isinstance(e, str):
                        try:
                            regs[key] = pl.sql_expr(e)
                        except Exception as err:  # polars raises several SQL error classes
                            first = str(err).strip().splitlines()[0] if str(err).strip() else ""
                            raise InvalidInputError(
                                f"user effect '{name}', {coef}: regressor {e!r} is not a SQL "
                                f"expression over the data's columns ({first})"
                            ) from err
                    elif isinstance(e, pl.Expr):
                        regs[key] = e
                    else:
                        raise InvalidInputError(
                            f"user effect '{name}', {coef}: regressor {e!r} is neither a SQL "
                            "expression string nor a polars expression"
                        )
                    names.append(key)
                cands.setdefault(coef, []).append(Candidate(name, "user", tuple(names)))
        return Vocabulary(cands, regs)


def default_vocabulary(measurement: bool = True) -> Vocabulary:
    """The vocabulary of DESIGN.md as candidates per coefficient.

    Parameters
    ----------
    measurement
        Include the measurement effects (vane biases, control lag, time skew, accelerometer
        offset).
    """
    out: dict[str, list[Candidate]] = {}
    for c in COEFFICIENTS:
        lst = [Candidate(n, "aerodynamic", r) for n, r in AERODYNAMIC[c]]
        if measurement:
            lst += [Candidate(n, "measurement", r) for n, r in MEASUREMENT[c]]
        out[c] = lst
    return Vocabulary(out)
