"""Extended-model export and evaluation: the engine against the exported DAVE-ML and JSBSim.

Builds a Δ model of the default structures (three coefficients, five flaps, seeded tables),
times the DAVE-ML export (merge into the built-in ADX-37 qualified model, check cases, the
verification against the engine) and the JSBSim export, then evaluates the extended Cl, Cn,
CY at 10^5 states with the engine (ADX-37 qualified model + ``DeltaModel.evaluate``, the peer)
and with the exported DAVE-ML file (``DaveModel.evaluate``), and at 10^3 states with JSBSim
(properties set and read one state at a time from Python). Run:
``python benchmarks/bench_export.py``.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import polars as pl

from aerodelta import _core
from aerodelta.daveml import DaveModel
from aerodelta.export import extended_daveml_text
from aerodelta.jsbsim import jsbsim_xml

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))
from test_export_extended import (
    _TEST_PROPS,
    DEFAULT_PROPERTIES,
    _load_jsbsim,
    engine_delta,
    random_states,
    synthetic_model,
)


def timed(f, repeat: int = 3) -> tuple[float, object]:
    best, out = float("inf"), None
    for _ in range(repeat):
        t0 = time.perf_counter()
        out = f()
        best = min(best, time.perf_counter() - t0)
    return best, out


def main() -> None:
    flaps = [0.0, 5.0, 10.0, 15.0, 35.0]
    model = synthetic_model(flaps)
    t, out = timed(lambda: extended_daveml_text(model), repeat=1)
    print(
        f"DAVE-ML export (merge, {out.n_checks} check cases, verify): {t * 1e3:8.1f} ms, "
        f"{len(out.text) / 1e6:.2f} MB, max rel. diff to engine {out.max_rel_error:.1e}"
    )
    t, xml = timed(lambda: jsbsim_xml(model, qualified=True), repeat=1)
    print(
        f"JSBSim export (with the qualified model):            {t * 1e3:8.1f} ms, "
        f"{len(xml) / 1e6:.2f} MB"
    )

    n = 100_000
    s = random_states(n, seed=1, flaps=flaps)
    cols = {k: np.ascontiguousarray(v) for k, v in s.items()}

    def engine() -> np.ndarray:
        cl, _, _ = _core.qualified_lateral_adx37({**cols, "alphadot_dps": np.zeros(n)})
        return cl + engine_delta(model, s)["dCl_blended"].to_numpy()

    dave = DaveModel.from_string(out.text, "ext")
    inputs = {
        "alpha_deg": s["alpha_deg"], "beta_rad": np.radians(s["beta_deg"]), "phat": s["phat"],
        "qhat": s["qhat"], "rhat": s["rhat"], "da_deg": s["da_deg"], "dr_deg": s["dr_deg"],
        "dsl_deg": s["dsl_deg"], "dsr_deg": s["dsr_deg"], "flap_deg": s["flap_deg"],
        "ct_left": s["ct_left"], "ct_right": s["ct_right"], "alphadot_dps": s["alphadot_dps"],
        "betadot_dps": s["betadot_dps"],
    }  # fmt: skip
    t_eng, ref = timed(engine)
    t_dave, got = timed(
        lambda: dave.evaluate(pl.DataFrame(inputs), outputs=["Cl_ext", "Cn_ext", "CY_ext"])
    )
    err = np.max(np.abs(got["Cl_ext"].to_numpy() - ref))
    print(f"engine (qualified + Δ), {n} states:       {t_eng * 1e3:8.1f} ms (peer)")
    print(
        f"exported DAVE-ML, {n} states:             {t_dave * 1e3:8.1f} ms "
        f"({t_dave / t_eng:.1f}x the engine), max |ΔCl_ext| {err:.1e}"
    )

    m = 1000
    tmp = Path(tempfile.mkdtemp())
    try:
        fdm = _load_jsbsim(tmp, jsbsim_xml(model, _TEST_PROPS, qualified=True))
        s["beta_rad"] = np.radians(s["beta_deg"])

        def jsb() -> np.ndarray:
            vals = np.empty(m)
            for i in range(m):
                for ch in DEFAULT_PROPERTIES:
                    if ch in s:
                        fdm[f"test/{ch}"] = float(s[ch][i])
                vals[i] = fdm["aero/aerodelta/Cl/extended"]
            return vals

        t_jsb, vals = timed(jsb, repeat=1)
        err = np.max(np.abs(vals - ref[:m]))
        print(
            f"JSBSim via the property tree, {m} states:  {t_jsb * 1e3:8.1f} ms "
            f"({t_jsb / m / (t_eng / n):.0f}x the engine per state, Python-bound), "
            f"max |ΔCl_ext| {err:.1e}"
        )
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


if __name__ == "__main__":
    main()
