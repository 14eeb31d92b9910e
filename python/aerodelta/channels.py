"""The canonical flight test schema (see ``docs/data.md``): names, units, roles and ranges.

Angles in deg, rates in deg/s, everything else SI. ``RANGES`` holds plausible physical ranges;
a value outside betrays a unit error or a broken sensor and is refused by validation.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class ChannelSpec:
    """One canonical channel.

    Attributes
    ----------
    name : str
        Canonical name (unit in the suffix).
    unit : str
        Canonical unit (a :mod:`aerodelta.units` name).
    role : str
        ``sensor`` (continuous measurement), ``control`` (surface or setting), ``time``,
        ``discrete`` (an on/off event signal, 1 = on), ``derived`` or ``sim``.
    lo, hi : float
        Plausible physical range in the canonical unit.
    doc : str
        Meaning.
    """

    name: str
    unit: str
    role: str
    lo: float
    hi: float
    doc: str


_SPECS = [
    ChannelSpec("t", "s", "time", 0.0, 1e7, "time, strictly increasing, uniform"),
    ChannelSpec("alpha_deg", "deg", "sensor", -45.0, 60.0, "angle of attack at the vane"),
    ChannelSpec("beta_deg", "deg", "sensor", -45.0, 45.0, "sideslip at the vane"),
    ChannelSpec("p_dps", "deg/s", "sensor", -300.0, 300.0, "roll rate"),
    ChannelSpec("q_dps", "deg/s", "sensor", -300.0, 300.0, "pitch rate"),
    ChannelSpec("r_dps", "deg/s", "sensor", -300.0, 300.0, "yaw rate"),
    ChannelSpec("phi_deg", "deg", "sensor", -180.0, 180.0, "bank angle"),
    ChannelSpec("theta_deg", "deg", "sensor", -90.0, 90.0, "pitch attitude"),
    # heading may be unwrapped (continuous through turns), so its range is wide
    ChannelSpec("psi_deg", "deg", "sensor", -36000.0, 36000.0, "heading (wrapped or unwrapped)"),
    ChannelSpec("ax_mps2", "m/s2", "sensor", -60.0, 60.0, "specific force x at the sensor"),
    ChannelSpec("ay_mps2", "m/s2", "sensor", -60.0, 60.0, "specific force y at the sensor"),
    ChannelSpec("az_mps2", "m/s2", "sensor", -80.0, 40.0, "specific force z at the sensor"),
    ChannelSpec("tas_mps", "m/s", "sensor", 10.0, 250.0, "true airspeed"),
    ChannelSpec("rho_kgm3", "kg/m3", "sensor", 0.2, 1.6, "air density"),
    ChannelSpec("ps_pa", "Pa", "sensor", 1e4, 1.1e5, "static pressure"),
    ChannelSpec("pt_pa", "Pa", "sensor", 1e4, 1.5e5, "total pressure"),
    ChannelSpec("sat_k", "K", "sensor", 180.0, 330.0, "static air temperature"),
    ChannelSpec("h_m", "m", "sensor", -500.0, 15000.0, "altitude"),
    ChannelSpec("da_deg", "deg", "control", -40.0, 40.0, "aileron (positive rolls left)"),
    ChannelSpec("de_deg", "deg", "control", -40.0, 40.0, "elevator"),
    ChannelSpec("dr_deg", "deg", "control", -40.0, 40.0, "rudder (positive yaws left)"),
    ChannelSpec("dsl_deg", "deg", "control", -5.0, 90.0, "left roll spoiler"),
    ChannelSpec("dsr_deg", "deg", "control", -5.0, 90.0, "right roll spoiler"),
    ChannelSpec("flap_deg", "deg", "control", -5.0, 60.0, "flap setting"),
    ChannelSpec("ct_left", "-", "sensor", -1.0, 5.0, "thrust coefficient, left engine"),
    ChannelSpec("ct_right", "-", "sensor", -1.0, 5.0, "thrust coefficient, right engine"),
    ChannelSpec("torque_left_nm", "N*m", "sensor", -1e5, 1e6, "left engine shaft torque"),
    ChannelSpec("torque_right_nm", "N*m", "sensor", -1e5, 1e6, "right engine shaft torque"),
    ChannelSpec("rpm_left", "rpm", "sensor", 0.0, 1e5, "left propeller speed"),
    ChannelSpec("rpm_right", "rpm", "sensor", 0.0, 1e5, "right propeller speed"),
    ChannelSpec("prop_rpm", "rpm", "sensor", 0.0, 1e5, "propeller speed (gyroscopic term)"),
    # optional discretes of the stall-protection system (docs/stall.md): 1 while on, 0 off
    ChannelSpec("pusher_active", "-", "discrete", 0.0, 1.0, "stick pusher pushing (1) or not (0)"),
    ChannelSpec("stall_warning", "-", "discrete", 0.0, 1.0, "stall warning on (1) or off (0)"),
    ChannelSpec("Cl_sim", "-", "sim", -5.0, 5.0, "simulator rolling moment coefficient"),
    ChannelSpec("Cn_sim", "-", "sim", -5.0, 5.0, "simulator yawing moment coefficient"),
    ChannelSpec("CY_sim", "-", "sim", -5.0, 5.0, "simulator side force coefficient"),
]

#: Every canonical channel by name.
CHANNELS: dict[str, ChannelSpec] = {s.name: s for s in _SPECS}

#: Channels every record must have (airspeed and density may come from ps/pt/sat instead).
REQUIRED: tuple[str, ...] = (
    "t",
    "alpha_deg",
    "beta_deg",
    "p_dps",
    "q_dps",
    "r_dps",
    "phi_deg",
    "theta_deg",
    "psi_deg",
    "ax_mps2",
    "ay_mps2",
    "az_mps2",
    "da_deg",
    "de_deg",
    "dr_deg",
)

#: Optional on/off channels (0 or 1; a value above 0.5 reads as on): the stall-protection
#: system's pusher activation and stall warning (read by :mod:`aerodelta.stall`).
DISCRETE: tuple[str, ...] = tuple(s.name for s in _SPECS if s.role == "discrete")

#: Alternatives: a channel or the set of channels that replaces it.
ALTERNATIVES: dict[str, tuple[str, ...]] = {
    "tas_mps": ("ps_pa", "pt_pa", "sat_k"),
    "rho_kgm3": ("ps_pa", "sat_k"),
}

#: Derived columns added by preprocessing, with units.
DERIVED: dict[str, str] = {
    "alpha_cg_deg": "deg",
    "beta_cg_deg": "deg",
    "pdot_dps2": "deg/s2",
    "qdot_dps2": "deg/s2",
    "rdot_dps2": "deg/s2",
    "alphadot_dps": "deg/s",
    "betadot_dps": "deg/s",
    "ax_cg_mps2": "m/s2",
    "ay_cg_mps2": "m/s2",
    "az_cg_mps2": "m/s2",
    "qbar_pa": "Pa",
    "phat": "-",
    "qhat": "-",
    "rhat": "-",
    "ct_diff": "-",
    "ds_deg": "deg",
    "Cl_meas": "-",
    "Cn_meas": "-",
    "CY_meas": "-",
    "CX_meas": "-",
    "CZ_meas": "-",
    "Cm_meas": "-",
}
