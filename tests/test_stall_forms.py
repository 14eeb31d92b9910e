"""The tabulated (Goman-Khrabrov) stall stored in the model file and flown by the exports and
the replays, as the tanh form is.

References: scipy's ``BSpline`` for the separation curve (the engine's ``X0Table`` is a
uniform cubic B-spline with its end coefficients repeated, constant beyond the end knots),
the engine's own point evaluation (``_core.kirchhoff_point`` with the table, itself checked
against scipy here), JSBSim running the exported aerodynamics, and the engine's replay of the
same stall given explicitly.
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.interpolate import BSpline

import aerodelta as ad
from aerodelta import _core
from aerodelta.cli import main
from aerodelta.export import extended_daveml_text
from aerodelta.fit import DEFAULT_STRUCTURES, model_frame
from aerodelta.goman_khrabrov import fit_goman_khrabrov
from aerodelta.model import DeltaModel

jsbsim = pytest.importorskip("jsbsim")

from _jsbsim_fixture import TEST_PROPS, driven  # noqa: E402
from aerodelta.jsbsim import jsbsim_stall_system_xml, jsbsim_xml  # noqa: E402

_D2R = math.pi / 180.0
#: Core parameters at flaps 0 and 10 (the virtual aircraft's lags and lines).
CORE = {
    0.0: {"tau1": 0.2, "tau2": 0.06, "CL_alpha": 5.2, "alpha0": -2.78 * _D2R, "Cm0": 0.06,
          "Cm_alpha": -0.75, "Cm_x": -0.12},
    10.0: {"tau1": 0.22, "tau2": 0.066, "CL_alpha": 5.2, "alpha0": -7.09 * _D2R, "Cm0": 0.03,
           "Cm_alpha": -0.75, "Cm_x": -0.12},
}  # fmt: skip
DRAG = {0.0: {"CD0": 0.027, "CD_k": 0.0322, "CD_x": 0.30}}


def _table(f: float) -> tuple[list[float], list[float]]:
    """A separation curve no tanh follows: attached to 14 deg, a plateau at 0.55 from 17 to
    21 deg, separated past 26 deg (knots every 1 deg from 10 to 30 deg, flap 10's shifted
    1 deg down). The end coefficients (0.93, 0.04) differ from their neighbours, so that the
    ends' handling (the end coefficients repeated beyond the knots) shows in the curve."""
    knots = np.radians(np.arange(10.0, 31.0) - f / 10.0)
    deg = np.arange(10.0, 31.0)
    values = np.interp(deg, [10, 14, 17, 21, 26, 30], [1.0, 1.0, 0.55, 0.55, 0.0, 0.0])
    values[0], values[1], values[-1] = 0.93, 0.99, 0.04
    return knots.tolist(), values.tolist()


def _x0_scipy(knots: list[float], values: list[float], u: np.ndarray) -> np.ndarray:
    """The engine's curve by scipy: the cubic B-spline on the knots extended by three on each
    side, coefficients ``[c0, c0, c1, ..., c_{K-1}, c_{K-1}]``, evaluated at ``u`` held in
    ``[t_0, t_{K-1}]``."""
    t = np.asarray(knots)
    h = t[1] - t[0]
    full = np.concatenate([t[0] - h * np.arange(3, 0, -1), t, t[-1] + h * np.arange(1, 4)])
    c = np.concatenate([[values[0]], values, [values[-1]]])
    return BSpline(full, c, 3, extrapolate=False)(np.clip(u, t[0], t[-1]))


def gk_model(known: str = "adx37") -> DeltaModel:
    """A Δ model (zero lateral terms) storing the tabulated stall at flaps 0 and 10, with its
    drag at flap 0."""
    coefs: dict[str, Any] = {}
    for c, terms in DEFAULT_STRUCTURES.items():
        coefs[c] = {
            "terms": [{"name": n, "regressor": r, "alpha_deg": [-4.0, 30.0],
                       "values": [[0.0, 0.0]] * 3} for n, r in terms],
            "alpha_l_deg": [12.0] * 3, "alpha_u_deg": [14.0] * 3,
        }  # fmt: skip
    flaps = []
    for f, p in CORE.items():
        knots, values = _table(f)
        flaps.append({"flap_deg": f, "params": p, "x0_knots": knots, "x0_values": values,
                      **({"drag": DRAG[f]} if f in DRAG else {})})  # fmt: skip
    return DeltaModel.from_spec(
        {"schema": "aerodelta.model/1", "flaps_deg": [0.0, 10.0, 20.0], "coefficients": coefs,
         "longitudinal": {"model": "goman-khrabrov", "known": known, "flaps": flaps}}
    )  # fmt: skip


def _point(f: float, a: np.ndarray, ad_: np.ndarray, x: np.ndarray) -> tuple[np.ndarray, ...]:
    knots, values = _table(f)
    return _core.kirchhoff_point(
        CORE[f], np.ascontiguousarray(a), np.ascontiguousarray(ad_), np.ascontiguousarray(x),
        knots=knots, values=values,
    )  # fmt: skip


def test_the_model_file_stores_the_table_and_the_engine_reads_it(tmp_path: Path) -> None:
    m = gk_model()
    m.save(tmp_path / "m.json")
    back = DeltaModel.load(tmp_path / "m.json")
    assert back.stall_form == "goman-khrabrov" and back.kirchhoff_known == "adx37"
    assert back.kirchhoff == CORE
    for f in CORE:
        knots, values = back.separation_tables[f]
        np.testing.assert_array_equal(knots, _table(f)[0])
        np.testing.assert_array_equal(values, _table(f)[1])
    assert back.adx37_stall_flaps == [0.0, 10.0]
    # the engine's point evaluation is scipy's spline (the curve the exports must carry)
    u = np.radians(np.linspace(5.0, 35.0, 301))
    x0 = _point(0.0, u, np.zeros_like(u), np.ones_like(u))[0]
    np.testing.assert_allclose(x0, _x0_scipy(*_table(0.0), u), rtol=0, atol=1e-14)
    # a bad table is refused naming the flap and the knot
    spec = m.to_spec()
    spec["longitudinal"]["flaps"][1]["x0_values"][4] = 1.5
    with pytest.raises(ad.AerodeltaError, match=r"flap 10.*knot 4"):
        DeltaModel.from_spec(spec)
    spec = m.to_spec()
    spec["longitudinal"]["model"] = "kirchhoff"
    with pytest.raises(ad.AerodeltaError, match="goman-khrabrov"):
        DeltaModel.from_spec(spec)
    # only a stall fit is stored
    with pytest.raises(ad.InvalidInputError, match="give the result of"):
        m.with_longitudinal(CORE)


@pytest.mark.parametrize("known", ["adx37", "none"])
def test_daveml_carries_the_table(known: str) -> None:
    """The DAVE-ML export's static separation point ``x_sep_0`` is scipy's spline of
    ``alpha - tau2 alphadot`` to 1e-12 inside, between and beyond the knots; ``x_sep_dot``,
    ``CL_ext``, ``Cm_ext`` and ``CD_ext`` match the engine in the export's own check cases
    (1e-9) and at random states (1e-12 for the lift and moment increments)."""
    m = gk_model(known)
    out = extended_daveml_text(m)
    assert out.max_rel_error <= 1e-9 and out.model.run_checks()["pass"].all()
    assert {"x_sep_dot", "x_sep_0", "CL_ext", "Cm_ext", "CD_ext"} <= set(out.model.outputs)
    rng = np.random.default_rng(11)
    n = 400
    alpha = rng.uniform(0.0, 40.0, n)
    rate = rng.uniform(-20.0, 20.0, n)
    x = rng.uniform(0.0, 1.0, n)
    for f in CORE:
        got = out.model.evaluate(
            {"alpha_deg": alpha, "alphadot_dps": rate, "x_sep": x, "flap_deg": np.full(n, f)},
            outputs=["x_sep_0", "x_sep_dot", "CL_ext", "Cm_ext", "CL", "Cm"],
        )
        a, r = np.radians(alpha), np.radians(rate)
        u = a - CORE[f]["tau2"] * r
        x0 = got["x_sep_0"].to_numpy()
        np.testing.assert_allclose(x0, _x0_scipy(*_table(f), u), rtol=0, atol=1e-12)
        want_x0, want_xd, cl, cm = _point(f, a, r, x)
        np.testing.assert_allclose(x0, want_x0, rtol=0, atol=1e-12)
        np.testing.assert_allclose(got["x_sep_dot"].to_numpy(), want_xd, rtol=0, atol=1e-11)
        dcl = got["CL_ext"].to_numpy() - got["CL"].to_numpy()
        dcm = got["Cm_ext"].to_numpy() - got["Cm"].to_numpy()
        if known == "none":  # the dynamics alone: less the same curves at x0(alpha)
            xs = _point(f, a, np.zeros(n), x)[0]
            _, _, cls, cms = _point(f, a, np.zeros(n), xs)
            np.testing.assert_allclose(dcl, cl - cls, rtol=0, atol=1e-12)
            np.testing.assert_allclose(dcm, cm - cms, rtol=0, atol=1e-12)
        else:  # the curves replace the qualified static ones: the check cases cover them
            assert np.abs(dcl).max() > 0.1


@pytest.mark.parametrize("known", ["adx37", "none"])
def test_jsbsim_flies_the_table(known: str, tmp_path: Path) -> None:
    """A pull from 5 to 32 deg and back (5 s) at flap 0, then 10, the channels set on the
    property tree each JSBSim frame: each flap's ``separated-static`` is ``1 - x0`` of scipy's
    spline at ``alpha - tau2 alphadot`` (1e-12), the separated fraction follows the engine's
    exact step from the previous frame (1e-12), and ``CL-delta``, ``Cm-delta`` (``known
    none``: the dynamics alone, the curves at ``x`` less at ``x0(alpha)``) are the engine's at
    JSBSim's ``x`` (1e-9)."""
    m = gk_model(known)
    aero = jsbsim_xml(m, TEST_PROPS)
    assert "knot-lagged" in aero
    fdm, dt, pull = driven(tmp_path, aero, jsbsim_stall_system_xml(m), peak_deg=32.0)
    alpha = np.concatenate([pull, pull])
    rate = np.concatenate([np.gradient(pull, dt)] * 2)
    flap = np.repeat([0.0, 10.0], pull.size)
    names = ["aero/aerodelta/stall/x", "aero/aerodelta/stall/CL-delta",
             "aero/aerodelta/stall/Cm-delta"]  # fmt: skip
    names += [
        f"aero/aerodelta/stall/flap-{i}/separated{k}" for i in (0, 1) for k in ("-static", "")
    ]
    rows: dict[str, list[float]] = {k: [] for k in names}
    for a, r, f in zip(alpha, rate, flap, strict=True):
        fdm["test/alpha_deg"], fdm["test/alphadot_dps"], fdm["test/flap_deg"] = a, r, f
        assert fdm.run()
        for k in names:
            rows[k].append(fdm[k])
    g = {k: np.asarray(v) for k, v in rows.items()}
    a_rad, r_rad = np.radians(alpha), np.radians(rate)
    x = g["aero/aerodelta/stall/x"]
    qual = ad.export_qualified_daveml(tmp_path / "q.dml").evaluate(
        {"alpha_deg": alpha, "flap_deg": flap}, outputs=["CL_basic", "Cm_basic"]
    )
    for i, f in enumerate(CORE):
        v = g[f"aero/aerodelta/stall/flap-{i}/separated-static"]
        s = g[f"aero/aerodelta/stall/flap-{i}/separated"]
        u = a_rad - CORE[f]["tau2"] * r_rad
        np.testing.assert_allclose(v, 1.0 - _x0_scipy(*_table(f), u), rtol=0, atol=1e-12)
        e = math.exp(-dt / CORE[f]["tau1"])
        gh = 1.0 - (1.0 - e) / (dt / CORE[f]["tau1"])
        step = e * s[:-1] + (1.0 - e - gh) * v[:-1] + gh * v[1:]
        np.testing.assert_allclose(s[1:], step, rtol=0, atol=1e-12)
        on = flap == f
        assert x[on].min() < 0.1 and 0.3 < np.median(1.0 - v[on]) < 1.0  # the plateau flown
        _, _, cl, cm = _point(f, a_rad[on], r_rad[on], x[on])
        if known == "none":
            xs = _point(f, a_rad[on], np.zeros(on.sum()), x[on])[0]
            _, _, cls, cms = _point(f, a_rad[on], np.zeros(on.sum()), xs)
        else:
            cls, cms = qual["CL_basic"].to_numpy()[on], qual["Cm_basic"].to_numpy()[on]
        np.testing.assert_allclose(
            g["aero/aerodelta/stall/CL-delta"][on], cl - cls, rtol=0, atol=1e-9
        )
        np.testing.assert_allclose(
            g["aero/aerodelta/stall/Cm-delta"][on], cm - cms, rtol=0, atol=1e-9
        )


def test_a_fitted_table_is_stored_by_the_command_line_and_replayed(
    stall_campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``aerodelta longitudinal --form goman-khrabrov --model M --out-model OUT`` stores the
    table of :func:`fit_goman_khrabrov` on the same records bit for bit; the closed-loop replay
    of a stored-stall flap flies it: another flight than the model without it, and the same
    flight, bit for bit, as the model without it given the fit's table explicitly
    (``kirchhoff={15: GkFlapFit}``); a table without its core parameters, or with a
    coefficient outside [0, 1], is refused."""
    data = ad.ingest(stall_campaign, compat=False, progress=False).data
    src = tmp_path / "model.json"
    ad.fit(data).model.save(src)
    out = tmp_path / "out.json"
    argv = ["longitudinal", str(stall_campaign), "--form", "goman-khrabrov", "--flaps", "15",
            "--no-progress", "--model", str(src), "--out-model", str(out)]  # fmt: skip
    assert main(argv) == 0
    assert f"wrote {out}" in capsys.readouterr().out
    res = fit_goman_khrabrov(model_frame(data), flaps=[15.0])
    stored = DeltaModel.load(out)
    assert stored.stall_form == "goman-khrabrov"
    knots, values = stored.separation_tables[15.0]
    np.testing.assert_array_equal(knots, np.radians(res[15.0].knots_deg))
    np.testing.assert_array_equal(values, res[15.0].x0)
    assert stored.kirchhoff == {15.0: res[15.0].params}
    spec = json.loads(out.read_text())["longitudinal"]
    assert spec["model"] == "goman-khrabrov" and "drag" in spec["flaps"][0]
    # the replays fly it: an ADX-37 stall at flap 15 (known adx37)
    assert stored.adx37_stall_flaps == [15.0]
    from aerodelta.closed_loop import closed_loop_replay  # noqa: PLC0415

    ids = (
        data.filter(data["flap_deg"] == 15.0)["maneuver_id"].unique(maintain_order=True)[:2]
    ).to_list()
    flown = closed_loop_replay(data, model=stored, maneuvers=ids)
    plain = closed_loop_replay(data, model=DeltaModel.load(src), maneuvers=ids)
    assert flown.setup["model_kirchhoff_flaps"] == [15.0]
    assert plain.setup["model_kirchhoff_flaps"] == []
    assert set(flown.runs) == set(ids)
    for mid in ids:
        assert not flown.runs[mid].equals(plain.runs[mid])
    # the same table given explicitly (the fit of one flap) flies the same flights, bit for bit
    explicit = closed_loop_replay(
        data, model=DeltaModel.load(src), kirchhoff={15.0: res[15.0]}, maneuvers=ids
    )
    assert explicit.setup["kirchhoff_flaps"] == [15.0]
    for mid in ids:
        assert explicit.runs[mid].equals(flown.runs[mid])
    # a table without its core parameters: one line naming what is missing
    core = dict(res[15.0].params)
    del core["tau1"]
    table = {"x0_knots": knots.tolist(), "x0_values": values.tolist()}
    with pytest.raises(ad.InvalidInputError, match=r"tabulated form's parameters lack tau1"):
        closed_loop_replay(data, kirchhoff={15.0: {**core, **table}}, maneuvers=ids)
    bad = {**res[15.0].params, **table, "x0_values": [*values.tolist()[:-1], 1.5]}
    with pytest.raises(ad.AerodeltaError, match="knot"):
        closed_loop_replay(data, kirchhoff={15.0: bad}, maneuvers=ids)
