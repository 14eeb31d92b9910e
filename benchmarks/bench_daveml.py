"""DAVE-ML evaluation speed: aerodelta's compiled model against a hand-written numpy peer.

Peer: the example lateral-directional model written out as vectorised numpy (one
``np.interp`` per table, then the sums of products), i.e. the fastest a Python user gets
without a model compiler. Also times loading the 1.3 MB HL-20 model and a batch over the
F-16 model. Run: ``python benchmarks/bench_daveml.py``.
"""

from __future__ import annotations

import math
import os
import tempfile
import time
from pathlib import Path

import numpy as np

from aerodelta.daveml import example_model, load_daveml, write_example_model


def _shared() -> Path | None:
    env = os.environ.get("AERODELTA_SHARED_DAVEML")
    if env:
        return Path(env)
    for base in Path(__file__).resolve().parents:
        d = base / "shared" / "data" / "daveml"
        if d.is_dir():
            return d
    return None


def best(f, repeat: int = 5) -> float:
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        f()
        times.append(time.perf_counter() - t0)
    return min(times)


def main() -> None:
    n = 1_000_000
    rng = np.random.default_rng(0)
    x = {
        "alpha_deg": rng.uniform(-5.0, 25.0, n),
        "beta_deg": rng.uniform(-10.0, 10.0, n),
        "p_hat": rng.uniform(-0.1, 0.1, n),
        "r_hat": rng.uniform(-0.1, 0.1, n),
        "da_deg": rng.uniform(-20.0, 20.0, n),
        "dr_deg": rng.uniform(-20.0, 20.0, n),
    }
    spec = example_model()
    with tempfile.TemporaryDirectory() as d:
        model = write_example_model(Path(d) / "example.dml")
    d2r = math.pi / 180.0

    def peer() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        a = x["alpha_deg"]
        t = {s["id"]: np.interp(a, s["breakpoints"][0], s["values"]) for s in spec["tables"]}
        cl = d2r * (t["Cl_beta"] * x["beta_deg"] + t["Cl_da"] * x["da_deg"])
        cl += t["Cl_p"] * x["p_hat"] + t["Cl_r"] * x["r_hat"]
        cn = d2r * (t["Cn_beta"] * x["beta_deg"] + t["Cn_dr"] * x["dr_deg"])
        cn += t["Cn_p"] * x["p_hat"] + t["Cn_r"] * x["r_hat"]
        cy = d2r * (t["CY_beta"] * x["beta_deg"] + t["CY_dr"] * x["dr_deg"])
        return cl, cn, cy

    ours = best(lambda: model.evaluate(x))
    theirs = best(peer)
    got = model.evaluate(x)
    want = peer()
    err = max(
        float(np.abs(got[c].to_numpy() - w).max())
        for c, w in zip(["Cl", "Cn", "CY"], want, strict=True)
    )
    print(
        f"example model, {n} points: aerodelta {ours * 1e3:.1f} ms, "
        f"numpy peer {theirs * 1e3:.1f} ms, "
        f"ratio peer/aerodelta {theirs / ours:.2f} (max |diff| {err:.1e})"
    )

    shared = _shared()
    if shared is None:
        print(
            "public DAVE-ML models not found; "
            "set AERODELTA_SHARED_DAVEML for the F-16/HL-20 timings"
        )
        return
    t_load = best(lambda: load_daveml(shared / "HL20_aero.dml"), repeat=3)
    print(f"load HL20_aero.dml (1.3 MB, 361 variables, 241 functions): {t_load * 1e3:.1f} ms")
    f16 = load_daveml(shared / "F16_aero.dml")
    m = 200_000
    inp = {
        "vt": rng.uniform(300.0, 900.0, m),
        "alpha": rng.uniform(-10.0, 45.0, m),
        "beta": rng.uniform(-30.0, 30.0, m),
        "p": rng.uniform(-1.0, 1.0, m),
        "q": rng.uniform(-1.0, 1.0, m),
        "r": rng.uniform(-1.0, 1.0, m),
        "el": rng.uniform(-25.0, 25.0, m),
        "ail": rng.uniform(-21.5, 21.5, m),
        "rdr": rng.uniform(-30.0, 30.0, m),
    }
    t_f16 = best(lambda: f16.evaluate(inp), repeat=3)
    print(
        f"F16_aero.dml, {m} points (50 variables, 18 tables): {t_f16 * 1e3:.1f} ms "
        f"({t_f16 / m * 1e9:.0f} ns per point)"
    )


if __name__ == "__main__":
    main()
