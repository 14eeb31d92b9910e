"""Closed-form rigid-body motion for the ingestion tests (independent of aero_core).

Body rates and air-relative body velocities are sums of sinusoids, so ṗ, q̇, ṙ, u̇, v̇, ẇ are
exact; attitude comes from integrating the Euler kinematics (thesis Eq. 3.1g-i) with scipy at
tight tolerance. Specific force at the CG from Eq. 3.1a-c (a = V̇ + ω×V − g_body), at the sensor
by the rigid-body transfer, vane angles from the local velocity V + ω×r at each vane, and the
true coefficients from Euler's equations with the propeller rotor (thesis Eq. 3.2-3.4).
"""

from __future__ import annotations

import numpy as np
import polars as pl
from scipy.integrate import solve_ivp

G0 = 9.80665
AIRCRAFT_TOML = """
name = "test twin"
[geometry]
S_m2 = 61.0
b_m = 27.05
cbar_m = 2.3
[mass]
mass_kg = 20000.0
Ixx_kgm2 = 3.0e5
Iyy_kgm2 = 4.5e5
Izz_kgm2 = 7.1e5
Ixz_kgm2 = 1.5e4
[propulsion]
n_engines = 2
prop_inertia_kgm2 = 25.0
prop_rotation = "ccw"
prop_rpm_channel = "prop_rpm"
[sensors]
accel_m = [0.5, 0.15, 0.3]
alpha_vane_m = [8.0, -1.4, 0.5]
beta_vane_m = [8.0, 0.0, -1.2]
"""
AC = {
    "S": 61.0,
    "b": 27.05,
    "c": 2.3,
    "m": 20000.0,
    "Ixx": 3.0e5,
    "Iyy": 4.5e5,
    "Izz": 7.1e5,
    "Ixz": 1.5e4,
    "Ip": 25.0,
}
R_ACC = np.array([0.5, 0.15, 0.3])
R_ALPHA = np.array([8.0, -1.4, 0.5])
R_BETA = np.array([8.0, 0.0, -1.2])

# user-unit channel map: radians, knots, feet, g
CHANNEL_MAP_TOML = """
[channels]
t = { source = "Time", unit = "s" }
alpha_deg = { source = "AOA", unit = "rad" }
beta_deg = { source = "AOS", unit = "rad" }
p_dps = { source = "P", unit = "rad/s" }
q_dps = { source = "Q", unit = "rad/s" }
r_dps = { source = "R", unit = "rad/s" }
phi_deg = { source = "PHI", unit = "rad" }
theta_deg = { source = "THETA", unit = "rad" }
psi_deg = { source = "PSI", unit = "rad" }
ax_mps2 = { source = "NX", unit = "g" }
ay_mps2 = { source = "NY", unit = "ft/s2" }
az_mps2 = { source = "NZ", unit = "g" }
tas_mps = { source = "KTAS", unit = "kt" }
rho_kgm3 = { source = "RHO", unit = "slug/ft3" }
h_m = { source = "ALT", unit = "ft" }
da_deg = { source = "DA", unit = "deg" }
de_deg = { source = "DE", unit = "deg" }
dr_deg = { source = "DR", unit = "deg" }
ct_left = { source = "CTL", unit = "-" }
ct_right = { source = "CTR", unit = "-" }
prop_rpm = { source = "NP", unit = "rpm" }
"""


def motion(
    t: np.ndarray,
    seed: int = 0,
    loading: dict[str, object] | None = None,
) -> dict[str, np.ndarray]:
    """Closed-form motion; returns canonical channels (SI, deg) and the truth.

    ``loading`` flies it with another mass (``m``, kg), inertia tensor (``I``: Ixx, Iyy, Izz,
    Ixz, Ixy, Iyz about the CG, Etkin sign), CG (``cg``, m from the datum the sensor positions
    are measured from) and reports the moments about ``ref`` (m from the datum): the full
    Euler equations M = I ω̇ + ω × (I ω + h) about the CG, plus (cg − ref) × m a_cg."""
    rng = np.random.default_rng(seed)
    a = rng.uniform(0.7, 1.3, 12)
    w = rng.uniform(0.25, 0.9, 6)
    p = 0.15 * a[0] * np.sin(w[0] * t)
    pd = 0.15 * a[0] * w[0] * np.cos(w[0] * t)
    q = 0.02 * a[1] + 0.08 * a[2] * np.sin(w[1] * t)
    qd = 0.08 * a[2] * w[1] * np.cos(w[1] * t)
    r = 0.1 * a[3] * np.cos(w[2] * t)
    rd = -0.1 * a[3] * w[2] * np.sin(w[2] * t)
    u = 60.0 * a[4] + 5.0 * np.sin(w[3] * t)
    ud = 5.0 * w[3] * np.cos(w[3] * t)
    v = 3.0 * a[5] * np.sin(w[4] * t)
    vd = 3.0 * a[5] * w[4] * np.cos(w[4] * t)
    ww = 8.0 * a[6] + 4.0 * np.cos(w[5] * t)
    wd = -4.0 * w[5] * np.sin(w[5] * t)

    def rates(s: float) -> tuple[float, float, float]:
        return (
            0.15 * a[0] * np.sin(w[0] * s),
            0.02 * a[1] + 0.08 * a[2] * np.sin(w[1] * s),
            0.1 * a[3] * np.cos(w[2] * s),
        )

    def euler_rhs(s: float, y: np.ndarray) -> list[float]:
        ps, qs, rs = rates(s)
        ph, th, _ = y
        return [
            ps + np.tan(th) * (qs * np.sin(ph) + rs * np.cos(ph)),
            qs * np.cos(ph) - rs * np.sin(ph),
            (qs * np.sin(ph) + rs * np.cos(ph)) / np.cos(th),
        ]

    sol = solve_ivp(
        euler_rhs,
        (t[0], t[-1]),
        [0.05, 0.1, 0.3],
        t_eval=t,
        rtol=1e-11,
        atol=1e-12,
        method="DOP853",
    )
    phi, th, psi = sol.y
    ax = ud - r * v + q * ww + G0 * np.sin(th)
    ay = vd - p * ww + r * u - G0 * np.cos(th) * np.sin(phi)
    az = wd - q * u + p * v - G0 * np.cos(th) * np.cos(phi)
    om = np.stack([p, q, r], axis=1)
    omd = np.stack([pd, qd, rd], axis=1)
    cg = np.zeros(3) if loading is None else np.asarray(loading["cg"], dtype=float)
    r_acc, r_alpha, r_beta = R_ACC - cg, R_ALPHA - cg, R_BETA - cg
    acc_s = (
        np.stack([ax, ay, az], axis=1) + np.cross(omd, r_acc) + np.cross(om, np.cross(om, r_acc))
    )
    vel = np.stack([u, v, ww], axis=1)
    va = vel + np.cross(om, r_alpha)
    vb = vel + np.cross(om, r_beta)
    alpha_v = np.arctan2(va[:, 2], va[:, 0])
    beta_v = np.arcsin(vb[:, 1] / np.linalg.norm(vb, axis=1))
    tas = np.linalg.norm(vel, axis=1)
    rho = np.full_like(t, 1.0)
    rpm = np.full_like(t, 1000.0)
    hp = 2 * AC["Ip"] * rpm * 2 * np.pi / 60
    qbar = 0.5 * rho * tas**2
    qs = qbar * AC["S"]
    ixx, iyy, izz, ixz = AC["Ixx"], AC["Iyy"], AC["Izz"], AC["Ixz"]
    cl = (ixx * pd - ixz * (rd + p * q) + (izz - iyy) * q * r) / (qs * AC["b"])
    cn = (izz * rd - ixz * (pd - q * r) + (iyy - ixx) * p * q + hp * q) / (qs * AC["b"])
    cy = AC["m"] * ay / qs
    cm = (iyy * qd + (ixx - izz) * p * r + ixz * (p**2 - r**2) - hp * r) / (qs * AC["c"])
    if loading is not None:
        ixx, iyy, izz, ixz, ixy, iyz = np.asarray(loading["I"], dtype=float)
        tensor = np.array([[ixx, -ixy, -ixz], [-ixy, iyy, -iyz], [-ixz, -iyz, izz]])
        h = np.zeros_like(om)
        h[:, 0] = -hp
        force = float(loading["m"]) * np.stack([ax, ay, az], axis=1)  # type: ignore[arg-type]
        arm = cg - np.asarray(loading["ref"], dtype=float)
        mom = omd @ tensor.T + np.cross(om, om @ tensor.T + h) + np.cross(arm, force)
        cl = mom[:, 0] / (qs * AC["b"])
        cm = mom[:, 1] / (qs * AC["c"])
        cn = mom[:, 2] / (qs * AC["b"])
        cy = force[:, 1] / qs
    d = np.degrees
    return {
        "t": t,
        "alpha_deg": d(alpha_v),
        "beta_deg": d(beta_v),
        "p_dps": d(p),
        "q_dps": d(q),
        "r_dps": d(r),
        "phi_deg": d(phi),
        "theta_deg": d(th),
        "psi_deg": d(psi),
        "ax_mps2": acc_s[:, 0],
        "ay_mps2": acc_s[:, 1],
        "az_mps2": acc_s[:, 2],
        "tas_mps": tas,
        "rho_kgm3": rho,
        "h_m": np.full_like(t, 1500.0),
        "da_deg": 2.0 * np.sin(0.4 * t),
        "de_deg": -1.0 + 0.5 * np.sin(0.3 * t),
        "dr_deg": 1.5 * np.cos(0.2 * t),
        "ct_left": np.full_like(t, 0.1),
        "ct_right": np.full_like(t, 0.08),
        "prop_rpm": rpm,
        # truth
        "alpha_cg_true": d(np.arctan2(ww, u)),
        "beta_cg_true": d(np.arcsin(v / tas)),
        "Cl_true": cl,
        "Cn_true": cn,
        "CY_true": cy,
        "Cm_true": cm,
        "pdot_true": d(pd),
    }


CANONICAL = [
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
    "tas_mps",
    "rho_kgm3",
    "h_m",
    "da_deg",
    "de_deg",
    "dr_deg",
    "ct_left",
    "ct_right",
    "prop_rpm",
]


def canonical_frame(m: dict[str, np.ndarray]) -> pl.DataFrame:
    """The record in canonical units."""
    return pl.DataFrame({k: m[k] for k in CANONICAL})


def user_frame(m: dict[str, np.ndarray]) -> pl.DataFrame:
    """The record in user units (radians, knots, feet, g) under user names."""
    ft, kt, slug = 0.3048, 1852.0 / 3600.0, 515.3788183931961
    return pl.DataFrame(
        {
            "Time": m["t"],
            "AOA": np.radians(m["alpha_deg"]),
            "AOS": np.radians(m["beta_deg"]),
            "P": np.radians(m["p_dps"]),
            "Q": np.radians(m["q_dps"]),
            "R": np.radians(m["r_dps"]),
            "PHI": np.radians(m["phi_deg"]),
            "THETA": np.radians(m["theta_deg"]),
            "PSI": np.radians(m["psi_deg"]),
            "NX": m["ax_mps2"] / G0,
            "NY": m["ay_mps2"] / ft,
            "NZ": m["az_mps2"] / G0,
            "KTAS": m["tas_mps"] / kt,
            "RHO": m["rho_kgm3"] / slug,
            "ALT": m["h_m"] / ft,
            "DA": m["da_deg"],
            "DE": m["de_deg"],
            "DR": m["dr_deg"],
            "CTL": m["ct_left"],
            "CTR": m["ct_right"],
            "NP": m["prop_rpm"],
        }
    )
