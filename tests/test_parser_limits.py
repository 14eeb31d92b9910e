"""Pathological input to the parsers (issue 18): deep regressor expressions in a model or fit
configuration, deep MathML and entity expansion in DAVE-ML, unsafe JSBSim property names.

Each must give one clear line naming what to fix, as an aerodelta exception, never a crash.
The inputs that used to overflow the engine's stack run in a fresh interpreter, so a
regression fails the test with the child's exit status instead of killing pytest.
"""

from __future__ import annotations

import json
import subprocess
import sys
import textwrap
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta._exportutil import MAX_DEPTH, parse_regressor
from aerodelta.jsbsim import jsbsim_xml

N = 20_000

#: Regressors 20,000 levels deep in each way the grammar nests, and a flat 20,000-term chain.
DEEP_REGRESSORS = {
    "parentheses": ("(" * N + "beta_deg" + ")" * N, f"nests {N} levels deep"),
    "unary minus": ("-" * N + "beta_deg", f"nests {N} levels deep"),
    "power chain": (" ^ ".join(["beta_deg"] * (N + 1)), f"nests {N} levels deep"),
    "function calls": ("abs(" * N + "beta_deg" + ")" * N, f"nests {N} levels deep"),
    "flat sum": (" + ".join(["beta_deg"] * N), f"is {N} operations deep"),
}

_RUNNER = """
import json, traceback
out = {}
for key, thunk in CASES.items():
    try:
        thunk()
        out[key] = {"ok": True}
    except Exception as e:
        out[key] = {"ok": False, "mro": [c.__name__ for c in type(e).__mro__], "msg": str(e)}
print(json.dumps(out))
"""


def _in_child(code: str, tmp_path: Path) -> dict[str, dict]:
    """Run ``code`` (which defines ``CASES``: name -> thunk) in a fresh interpreter; the outcome
    of each thunk: ``ok``, or the exception's class names (``mro``) and message."""
    script = tmp_path / "probe.py"
    script.write_text(textwrap.dedent(code) + _RUNNER)
    r = subprocess.run(
        [sys.executable, str(script)], capture_output=True, text=True, timeout=600, check=False
    )
    assert r.returncode == 0, f"the interpreter died (status {r.returncode}): {r.stderr[-2000:]}"
    return json.loads(r.stdout.strip().splitlines()[-1])


def _one_clear_line(outcome: dict, cls: str, *needles: str) -> str:
    assert not outcome["ok"], "must be refused"
    assert cls in outcome["mro"] and "AerodeltaError" in outcome["mro"], outcome["mro"]
    msg = outcome["msg"]
    assert "\n" not in msg and len(msg) < 600, msg
    for n in needles:
        assert n in msg, f"{n!r} not in: {msg}"
    return msg


def _model_spec(regressor: str) -> dict:
    return {
        "schema": "aerodelta.model/1",
        "flaps_deg": [0.0, 10.0],
        "coefficients": {
            "Cl": {
                "terms": [
                    {"name": "dCl_0", "regressor": "1", "alpha_deg": [10.0, 20.0],
                     "values": [[0.0, 0.01], [0.0, 0.03]]},
                    {"name": "dCl_deep", "regressor": regressor, "alpha_deg": [10.0, 20.0],
                     "values": [[0.0, 0.001], [0.0, 0.002]]},
                ],
                "alpha_l_deg": [8.0, 10.0],
                "alpha_u_deg": [12.0, 14.0],
            }
        },
    }  # fmt: skip


def test_deep_regressors_in_a_model_are_refused(tmp_path: Path) -> None:
    files = {}
    for key, (expr, _) in DEEP_REGRESSORS.items():
        p = tmp_path / f"{key.replace(' ', '_')}.json"
        p.write_text(json.dumps(_model_spec(expr)))
        files[key] = str(p)
    out = _in_child(
        f"""
        import json
        import aerodelta as ad
        FILES = {files!r}
        CASES = {{}}
        for key, path in FILES.items():
            spec = json.loads(open(path).read())
            CASES[key] = lambda spec=spec: ad.DeltaModel.from_spec(spec)
            CASES[key + " (file)"] = lambda path=path: ad.DeltaModel.load(path)
        """,
        tmp_path,
    )
    for key, (_, needle) in DEEP_REGRESSORS.items():
        limit = "at most 256 are supported" if "operations" in needle else "at most 64"
        for k in (key, f"{key} (file)"):
            msg = _one_clear_line(out[k], "InvalidInputError", "dCl_deep", needle, limit)
            assert f"({len(DEEP_REGRESSORS[key][0])} characters)" in msg, msg
        assert out[f"{key} (file)"]["msg"].startswith(f"{files[key]}: coefficient Cl, term")


def test_regressors_at_the_limits_are_accepted() -> None:
    # MAX_DEPTH - 1 terms and one more subtraction: exactly MAX_DEPTH deep
    flat = " + ".join(["beta_deg"] * (MAX_DEPTH - 1))
    nested = "(" * 64 + "beta_deg" + ")" * 64
    m = ad.DeltaModel.from_spec(_model_spec(f"{flat} - {nested}"))
    got = m.evaluate(pl.DataFrame({"alpha_deg": [20.0], "flap_deg": [0.0], "beta_deg": [1.0]}))
    assert got["dCl"][0] == pytest.approx(0.01 + 0.001 * (MAX_DEPTH - 2))


def _fit_data(n_man: int = 8, rows: int = 400) -> pl.DataFrame:
    rng = np.random.default_rng(3)
    n = n_man * rows
    alpha = np.tile(np.linspace(0.0, 20.0, rows), n_man)
    beta = rng.normal(0.0, 5.0, n)
    return pl.DataFrame(
        {
            "t": np.tile(np.arange(rows) * 0.05, n_man),
            "maneuver_id": np.repeat(np.arange(n_man), rows),
            "flap_deg": np.zeros(n),
            "alpha_deg": alpha,
            "beta_deg": beta,
            "Cl_meas": 0.001 * beta + rng.normal(0.0, 1e-4, n),
            "CZ_meas": -0.1 * alpha + 0.004 * alpha**2,
            "CX_meas": np.zeros(n),
            "Cl_sim": np.zeros(n),
            "Cn_sim": np.zeros(n),
            "CY_sim": np.zeros(n),
        }
    )


def test_deep_regressors_in_a_fit_config_are_refused(tmp_path: Path) -> None:
    data = tmp_path / "data.parquet"
    _fit_data().write_parquet(data)
    toml = tmp_path / "fit.toml"
    deep = DEEP_REGRESSORS["parentheses"][0]
    toml.write_text(
        f'selection = "none"\n[structures]\nCl = [["dCl_0", "1"], ["dCl_deep", "{deep}"]]\n'
    )
    out = _in_child(
        f"""
        import polars as pl
        import aerodelta as ad
        data = pl.read_parquet({str(data)!r})
        EXPRS = {{k: v[0] for k, v in {DEEP_REGRESSORS!r}.items()}}
        def fit(expr):
            structures = {{"Cl": [("dCl_0", "1"), ("dCl_deep", expr)]}}
            ad.fit(data, config=ad.FitConfig(selection=None, structures=structures))
        CASES = {{k: (lambda e=e: fit(e)) for k, e in EXPRS.items()}}
        CASES["toml"] = lambda: ad.fit(data, config=ad.FitConfig.from_toml({str(toml)!r}))
        """,
        tmp_path,
    )
    for key, (_, needle) in DEEP_REGRESSORS.items():
        _one_clear_line(out[key], "InvalidInputError", "dCl_deep", needle)
    _one_clear_line(out["toml"], "InvalidInputError", "dCl_deep", f"nests {N} levels deep")


def test_export_parser_refuses_deep_expressions_as_data_errors() -> None:
    for expr, _ in DEEP_REGRESSORS.values():
        with pytest.raises(ad.DataError) as e:
            parse_regressor(expr)
        msg = str(e.value)
        assert "\n" not in msg and len(msg) < 600 and "characters)" in msg, msg
    assert parse_regressor(" + ".join(["x"] * MAX_DEPTH)).op == "+"
    assert parse_regressor("-" * 64 + "x").op == "minus"


# -- DAVE-ML --------------------------------------------------------------------------------

_HEAD = '<?xml version="1.0"?>\n'
_ROOT = '<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">\n'


def _deep_mathml(k: int) -> str:
    return (
        f'{_HEAD}{_ROOT}<variableDef name="a" varID="a" units="nd"><isInput/></variableDef>\n'
        '<variableDef name="CL_total" varID="CL_total" units="nd"><calculation><math>\n'
        + "<apply><plus/><cn>1</cn>" * k
        + "<ci>a</ci>"
        + "</apply>" * k
        + "\n</math></calculation><isOutput/></variableDef>\n</DAVEfunc>\n"
    )


def _with_entities(decl: str, body: str) -> str:
    return (
        f"{_HEAD}<!DOCTYPE DAVEfunc [\n{decl}\n]>\n{_ROOT}"
        f'<variableDef name="a" varID="a" units="nd"><description>{body}</description>'
        "<isInput/></variableDef>\n</DAVEfunc>\n"
    )


def test_hostile_daveml_files_are_refused(tmp_path: Path) -> None:
    lols = ['<!ENTITY lol "lol">'] + [
        f'<!ENTITY lol{k} "{("&lol" + (str(k - 1) if k > 1 else "") + ";") * 10}">'
        for k in range(1, 10)
    ]
    files = {
        "deep": _deep_mathml(6200),
        "quadratic": _with_entities(f'<!ENTITY big "{"x" * 80_000}">', "&big;" * 16_000),
        "laughs": _with_entities("\n".join(lols), "&lol9;"),
    }
    assert len(files["quadratic"]) > 160_000
    paths = {}
    for k, text in files.items():
        p = tmp_path / f"{k}.dml"
        p.write_text(text)
        paths[k] = str(p)
    out = _in_child(
        f"""
        import aerodelta as ad
        from aerodelta.daveml import DaveModel
        PATHS = {paths!r}
        CASES = {{}}
        for k, p in PATHS.items():
            CASES[k] = lambda p=p: ad.load_daveml(p)
            CASES[k + " (string)"] = lambda p=p: DaveModel.from_string(open(p).read(), "x.dml")
        """,
        tmp_path,
    )
    _one_clear_line(
        out["deep"], "ParseError", paths["deep"], 'varID="CL_total"',
        "nests 6201 MathML elements deep", "at most 512", "intermediate variables",
    )  # fmt: skip
    _one_clear_line(out["deep (string)"], "ParseError", "x.dml:4:", "CL_total")
    for k in ("quadratic", "laughs"):
        _one_clear_line(
            out[k], "ParseError", f"{paths[k]}:3: <!ENTITY", "declares an XML entity", "remove"
        )
        _one_clear_line(out[f"{k} (string)"], "ParseError", "x.dml:3: <!ENTITY")


def test_daveml_with_an_external_doctype_still_loads(daveml_dir: Path) -> None:
    m = ad.load_daveml(daveml_dir / "F16_aero.dml")
    assert m.n_shots > 0
    assert all(m.run_checks()["pass"])


# -- JSBSim export ----------------------------------------------------------------------------


def test_jsbsim_properties_are_checked_and_comments_stay_xml(tmp_path: Path) -> None:
    m = ad.DeltaModel.from_spec(_model_spec("deadband(da_deg, 2) * beta_deg--2"))
    props = {"da_deg": "-fcs/left-aileron-pos-deg", "beta_deg": "aero/beta-deg * 1.5"}
    text = jsbsim_xml(m, props)
    root = ET.fromstring(text)  # the regressor's '--' does not break the comment
    assert "<property>-fcs/left-aileron-pos-deg</property>" in text
    assert root.tag == "aerodynamics"
    for bad in ['fcs/x"/><evil a="', "fcs/x<y", "fcs/a b", "fcs/é", "a&b", "1 * nan"]:
        with pytest.raises(ad.DataError) as e:
            jsbsim_xml(m, {**props, "da_deg": bad})
        msg = str(e.value)
        assert "\n" not in msg and "da_deg" in msg, msg
        assert "property name" in msg or "finite number" in msg, msg
