"""Benchmark: one 60 s stall maneuver at 100 Hz (6-DOF, truth model, roll-off) in the
Rust engine via the bindings, against real time and against a straightforward
numpy implementation of the same equations (thesis Eq. 3.1) with a simplified
aero model of the same structure: fixed-step RK4 in numpy (same step, same
number of model evaluations) and scipy ``solve_ivp`` (RK45).

Run: ``python benchmarks/bench_sim.py``
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from aerodelta.campaign import replay, trim

G = 9.80665
S, B, C = 54.35, 25.91, 2.10
M, IXX, IYY, IZZ, IXZ = 15000.0, 1.57e5, 2.68e5, 3.31e5, 1.2e4
HP = 2 * 60.0 * 1020.0 * np.pi / 30
INERTIA = np.array([[IXX, 0, -IXZ], [0, IYY, 0], [-IXZ, 0, IZZ]])
INV_I = np.linalg.inv(INERTIA)
DT, SECONDS = 0.01, 60.0


def inputs(tr: dict, n: int) -> tuple[np.ndarray, np.ndarray]:
    """Elevator pulled slowly into the stall: 0.25 deg/s for 40 s, then pushed."""
    c = np.tile(tr["controls_deg"], (n, 1))
    t = np.arange(n) * DT
    c[:, 1] += np.where(t < 40, -0.25 * t, -10 + 1.0 * (t - 40))
    k = np.full((n, 2), tr["ct"])
    return c, k


def isa_rho(h: float) -> float:
    t = 288.15 - 0.0065 * h
    return 101325 * (t / 288.15) ** 5.25588 / (287.05287 * t)


def aero(x: np.ndarray, c: np.ndarray, ct: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Same-structure aero: lift curve with a break, derivative lateral model, roll-off bump."""
    u, v, w, p, q, r = x[:6]
    vt = np.sqrt(u * u + v * v + w * w)
    a, b = np.arctan2(w, u), np.arcsin(v / vt)
    ad = np.degrees(a)
    da, de, dr = np.radians(c[:3])
    ph, qh, rh = p * B / (2 * vt), q * C / (2 * vt), r * B / (2 * vt)
    cl0 = 0.25 + 5.2 * a
    clift = np.where(ad < 19.5, cl0, 1.75 - 0.44 * (1 - np.exp(-(((ad - 19.5) / 2.5) ** 2))))
    clift = clift + 0.35 * de + 6 * qh
    cd = 0.027 + 0.032 * clift**2
    cts = ct[0] + ct[1]
    cx = -cd * np.cos(a) + clift * np.sin(a) + cts
    cz = -cd * np.sin(a) - clift * np.cos(a)
    g = np.clip((ad - 14) / 5.5, 0, 1)
    rolloff = 0.0103 * np.exp(-0.5 * ((ad - 17.09) / 0.5) ** 2)
    cy = -0.78 * b + 0.27 * dr
    cl = -0.095 * b + (-0.5 + 0.6 * g) * ph + 0.3 * rh - 0.16 * da + rolloff
    cm = 0.06 - 0.75 * a - 2.0 * de - 25 * qh - 0.19 * cts
    cn = 0.115 * b - 0.16 * rh - 0.105 * dr + 0.012 * da
    qs = 0.5 * isa_rho(x[11]) * vt * vt * S
    return qs * np.array([cx, cy, cz]), qs * np.array([B * cl, C * cm, B * cn])


def f(x: np.ndarray, c: np.ndarray, ct: np.ndarray) -> np.ndarray:
    """Thesis Eq. 3.1 in matrix form."""
    force, moment = aero(x, c, ct)
    u, v, w, p, q, r, ph, th, ps = x[:9]
    sf, cf, st, ctt, sp, cp = np.sin(ph), np.cos(ph), np.sin(th), np.cos(th), np.sin(ps), np.cos(ps)
    om = np.array([p, q, r])
    h = INERTIA @ om + np.array([-HP, 0, 0])
    wd = INV_I @ (moment - np.cross(om, h))
    return np.array(
        [
            r * v - q * w + force[0] / M - G * st,
            p * w - r * u + force[1] / M + G * ctt * sf,
            q * u - p * v + force[2] / M + G * ctt * cf,
            wd[0],
            wd[1],
            wd[2],
            p + st / ctt * (q * sf + r * cf),
            q * cf - r * sf,
            (q * sf + r * cf) / ctt,
            u * cp * ctt + v * (cp * st * sf - sp * cf) + w * (cp * st * cf + sp * sf),
            u * sp * ctt + v * (sp * st * sf + cp * cf) + w * (sp * st * cf - cp * sf),
            u * st - v * ctt * sf - w * ctt * cf,
        ]
    )


def numpy_rk4(x0: np.ndarray, c: np.ndarray, k: np.ndarray) -> np.ndarray:
    x = x0.copy()
    for i in range(len(c)):
        k1 = f(x, c[i], k[i])
        k2 = f(x + 0.5 * DT * k1, c[i], k[i])
        k3 = f(x + 0.5 * DT * k2, c[i], k[i])
        k4 = f(x + DT * k3, c[i], k[i])
        x = x + DT / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
    return x


def scipy_rk45(x0: np.ndarray, c: np.ndarray, k: np.ndarray) -> np.ndarray:
    def rhs(t: float, x: np.ndarray) -> np.ndarray:
        i = min(int(t / DT), len(c) - 1)
        return f(x, c[i], k[i])

    sol = solve_ivp(rhs, (0, SECONDS), x0, method="RK45", rtol=1e-6, atol=1e-8, max_step=DT)
    return sol.y[:, -1]


def best(fn, repeat: int) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    tr = trim(0.0, 75.0, 3000.0)
    n = int(SECONDS / DT)
    c, k = inputs(tr, n)
    x0 = np.array(tr["state"])
    states = replay(0.0, x0, DT, c, k, effects="default", rolloff_seed=1)
    amax = np.degrees(np.arctan2(states[:, 2], states[:, 0])).max()
    t_rust = best(lambda: replay(0.0, x0, DT, c, k, effects="default", rolloff_seed=1), 20)
    t_np = best(lambda: numpy_rk4(x0, c, k), 1)
    t_sp = best(lambda: scipy_rk45(x0, c, k), 1)
    print(f"maneuver: {SECONDS:.0f} s at {1 / DT:.0f} Hz, max alpha {amax:.1f} deg")
    print(f"aerodelta (Rust RK4, truth model + roll-off): {t_rust * 1e3:8.2f} ms")
    print(f"numpy fixed-step RK4 (simplified aero):       {t_np * 1e3:8.2f} ms")
    print(f"scipy solve_ivp RK45 (simplified aero):       {t_sp * 1e3:8.2f} ms")
    print(f"real-time ratio:          {SECONDS / t_rust:10.0f}x  (floor 10000x)")
    print(f"speed-up vs numpy RK4:    {t_np / t_rust:10.0f}x  (floor 50x)")
    print(f"speed-up vs solve_ivp:    {t_sp / t_rust:10.0f}x")


if __name__ == "__main__":
    main()
