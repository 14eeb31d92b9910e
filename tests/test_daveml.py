"""DAVE-ML models: the public NASA check cases, scipy for table lookups, the CLI, malformed
files and the project's own example model (round trip)."""

from __future__ import annotations

import doctest
import json
import math
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import polars as pl
import pytest
from scipy.interpolate import RegularGridInterpolator

import aerodelta
import aerodelta.daveml
from aerodelta import cli
from aerodelta.daveml import (
    check_daveml,
    daveml_text,
    example_model,
    load_daveml,
    write_daveml,
    write_example_model,
)

# file -> (static shots, checked outputs, internal values), counted from the files.
PUBLIC = {
    "F16_aero.dml": (16, 144, 800),
    "HL20_aero.dml": (25, 250, 8616),
    "tables.dml": (6, 12, 0),
    "fiveD_table.dml": (9, 9, 0),
    "atmos_76.dml": (42, 126, 0),
    "F16_prop.dml": (9, 54, 39),
}


@pytest.mark.parametrize("name", sorted(PUBLIC))
def test_public_model_passes_every_check_at_its_own_tolerance(daveml_dir: Path, name: str) -> None:
    path = daveml_dir / name
    checks = check_daveml(path)
    shots, n_out, n_int = PUBLIC[name]
    assert load_daveml(path).n_shots == shots
    assert checks.filter(pl.col("kind") == "output").height == n_out
    assert checks.filter(pl.col("kind") == "internal").height == n_int
    failed = checks.filter(~pl.col("pass"))
    assert failed.height == 0, failed
    # The NASA values themselves, not only the pass flags.
    err = (checks["actual"] - checks["expected"]).abs()
    assert (err <= checks["tolerance"]).all()


def test_f16_internal_values_match_to_round_off(daveml_dir: Path) -> None:
    checks = check_daveml(daveml_dir / "F16_aero.dml").filter(pl.col("kind") == "internal")
    err = (checks["actual"] - checks["expected"]).abs()
    assert err.max() < 1e-12


@pytest.mark.parametrize("name", ["simple_aero.dml", "simplest_aero.dml"])
def test_simple_function_form_matches_numpy_interp(daveml_dir: Path, name: str) -> None:
    m = load_daveml(daveml_dir / name)
    assert m.n_shots == 0
    alpha = np.linspace(-10.0, 20.0, 61)
    got = m.evaluate({"alpdeg": alpha}, ["cl"])["cl"].to_numpy()
    want = np.interp(alpha, [-4.0, 0.0, 4.0, 8.0, 12.0, 16.0], [0.0, 0.2, 0.4, 0.8, 1.0, 1.2])
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-15)


def _text(node: ET.Element) -> list[float]:
    return [float(t) for t in "".join(node.itertext()).replace(",", " ").split()]


def test_twod_gridded_function_against_scipy(daveml_dir: Path) -> None:
    """twoD_table.dml: deprecated <griddedTable>, input limits inside the breakpoint range."""
    path = daveml_dir / "twoD_table.dml"
    ns = {"d": "http://daveml.org/2010/DAVEML"}
    root = ET.parse(path).getroot()
    bps = {
        b.get("bpID"): _text(b.find("d:bpVals", ns))
        for b in root.iter(f"{{{ns['d']}}}breakpointDef")
    }
    data = np.array(_text(root.find(".//d:dataTable", ns))).reshape(
        len(bps["MACH1"]), len(bps["ALPHA1"])
    )
    ref = RegularGridInterpolator((bps["MACH1"], bps["ALPHA1"]), data, method="linear")
    rng = np.random.default_rng(7)
    mach = rng.uniform(-0.2, 1.5, 2000)
    alpha = rng.uniform(-8.0, 20.0, 2000)
    want = ref(np.column_stack([np.clip(mach, 0.3, 0.95), np.clip(alpha, -0.4, 16.0)]))
    got = load_daveml(path).evaluate({"MACH": mach, "ALPHA": alpha}, ["CL"])["CL"].to_numpy()
    np.testing.assert_allclose(got, want, rtol=0, atol=1e-14)


def _spec_3d(extrapolate: str) -> dict:
    rng = np.random.default_rng(3)
    bps = [[-2.0, 0.0, 1.0, 4.0], [0.0, 0.5, 3.0], [1.0, 2.0, 2.5, 3.0, 5.0]]
    values = rng.normal(size=(4, 3, 5))
    return {
        "name": "three-D",
        "inputs": [{"id": f"x{k}", "units": "nd"} for k in range(3)],
        "tables": [
            {
                "id": "T",
                "args": ["x0", "x1", "x2"],
                "breakpoints": bps,
                "values": values,
                "extrapolate": extrapolate,
                "is_output": True,
            }
        ],
        "outputs": [{"id": "y", "terms": [{"coef": 2.0, "factors": ["T"]}, {"coef": 0.5}]}],
        "checks": [{"name": "c", "inputs": {"x0": 0.3, "x1": 1.1, "x2": 4.4}}],
        "bps": bps,
        "values": values,
    }


@pytest.mark.parametrize("extrapolate", ["both", "neither"])
def test_written_3d_table_against_scipy(tmp_path: Path, extrapolate: str) -> None:
    spec = _spec_3d(extrapolate)
    bps, values = spec.pop("bps"), spec.pop("values")
    m = write_daveml(tmp_path / "t3.dml", spec)
    assert check_daveml(tmp_path / "t3.dml")["pass"].all()
    rng = np.random.default_rng(11)
    pts = np.column_stack(
        [rng.uniform(-4.0, 6.0, 3000), rng.uniform(-1.0, 4.0, 3000), rng.uniform(0.0, 6.0, 3000)]
    )
    if extrapolate == "neither":
        pts_ref = np.column_stack([np.clip(pts[:, k], bps[k][0], bps[k][-1]) for k in range(3)])
    else:
        pts_ref = pts
    ref = RegularGridInterpolator(
        tuple(bps), values, method="linear", bounds_error=False, fill_value=None
    )
    out = m.evaluate({f"x{k}": pts[:, k] for k in range(3)}, ["T", "y"])
    np.testing.assert_allclose(out["T"].to_numpy(), ref(pts_ref), rtol=0, atol=1e-12)
    np.testing.assert_allclose(out["y"].to_numpy(), 2.0 * ref(pts_ref) + 0.5, rtol=0, atol=1e-12)


# -- CLI ------------------------------------------------------------------------------------


def test_cli_check_passes_on_public_model(
    daveml_dir: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    rc = cli.main(["check-daveml", str(daveml_dir / "F16_aero.dml")])
    out = capsys.readouterr().out
    assert rc == 0
    assert "944 checks, 944 passed, 0 failed (144 outputs, 800 internal values)" in out
    assert sum(ln.endswith("  pass") for ln in out.splitlines()) == 144
    assert "Skewed inputs" in out


def test_cli_json_format(daveml_dir: Path, capsys: pytest.CaptureFixture[str]) -> None:
    rc = cli.main(["check-daveml", str(daveml_dir / "atmos_76.dml"), "--format", "json"])
    doc = json.loads(capsys.readouterr().out)
    assert rc == 0
    assert doc["summary"] == {
        "checks": 126,
        "passed": 126,
        "failed": 0,
        "outputs": 126,
        "internal": 0,
        "shots": 42,
    }
    first = doc["checks"][0]
    assert first["shot"] == "sea level" and first["variable"] == "t_amb_F"
    assert first["expected"] == 59.0 and first["tolerance"] == 0.4


def test_cli_failure_exit_status(
    daveml_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = (daveml_dir / "tables.dml").read_text()
    # First check output of the file is output 1 = -20 at input 1 = -10: make it wrong.
    bad = text.replace("<signalValue>-20.0</signalValue>", "<signalValue>-20.5</signalValue>", 1)
    assert bad != text
    path = tmp_path / "tables_bad.dml"
    path.write_text(bad)
    rc = cli.main(["check-daveml", str(path)])
    out = capsys.readouterr().out
    assert rc == 1
    assert "12 checks, 11 passed, 1 failed" in out
    line = next(ln for ln in out.splitlines() if "FAIL" in ln)
    assert line.startswith("first point") and "out1t" in line and "-20.5" in line


def test_cli_malformed_file_one_error_line(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "bad.dml"
    path.write_text(_malformed("unknown_varid"))
    rc = cli.main(["check-daveml", str(path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 1
    assert len(err) == 1
    assert "bad.dml:8: <independentVarRef varID=\"nope\">: unknown varID 'nope'" in err[0]


def test_cli_write_example_then_check(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "sub" / "example.dml"
    out.parent.mkdir()
    assert cli.main(["write-example-model", str(out)]) == 0
    assert "9 check cases" in capsys.readouterr().out
    assert cli.main(["check-daveml", str(out)]) == 0
    text = capsys.readouterr().out
    assert "27 checks, 27 passed, 0 failed" not in text  # internal values are counted too
    assert ", 0 failed (27 outputs, " in text
    assert [p.name for p in out.parent.iterdir()] == ["example.dml"]


# -- Malformed files ------------------------------------------------------------------------

_GOOD = """<?xml version="1.0"?>
<DAVEfunc xmlns="http://daveml.org/2010/DAVEML">
  <fileHeader><author name="t"/><creationDate date="2026-01-01"/></fileHeader>
  <variableDef name="alpha" varID="alpha" units="deg"><isInput/></variableDef>
  <variableDef name="CL" varID="CL" units="nd"><isOutput/></variableDef>
  <breakpointDef bpID="A"><bpVals>0, 5, 10</bpVals></breakpointDef>
  <function name="CL">
    <independentVarRef varID="alpha" extrapolate="neither"/>
    <dependentVarRef varID="CL"/>
    <functionDefn><griddedTableDef gtID="CLT"><breakpointRefs><bpRef bpID="A"/></breakpointRefs>
      <dataTable>0.1 0.6 1.1</dataTable></griddedTableDef></functionDefn>
  </function>
  <checkData><staticShot name="s">
    <checkInputs><signal><signalName>alpha</signalName><signalUnits>deg</signalUnits>
      <signalValue>2.5</signalValue></signal></checkInputs>
    <checkOutputs><signal><signalName>CL</signalName><signalUnits>nd</signalUnits>
      <signalValue>0.35</signalValue><tol>1e-12</tol></signal></checkOutputs>
  </staticShot></checkData>
</DAVEfunc>
"""


def _malformed(kind: str) -> str:
    edits = {
        "good": ("", ""),
        "unknown_varid": ('<independentVarRef varID="alpha"', '<independentVarRef varID="nope"'),
        "table_size": ("0.1 0.6 1.1", "0.1 0.6 1.1 1.6"),
        "breakpoints": ("0, 5, 10", "0, 5, 5"),
        "units": ("<signalUnits>deg</signalUnits>", "<signalUnits>rad</signalUnits>"),
    }
    old, new = edits[kind]
    return _GOOD.replace(old, new)


@pytest.mark.parametrize(
    ("kind", "where"),
    [
        ("unknown_varid", "bad.dml:8: <independentVarRef varID=\"nope\">: unknown varID 'nope'"),
        (
            "table_size",
            'bad.dml:10: <griddedTableDef gtID="CLT">: table: has 4 values but its breakpoints '
            "(alpha:3) need 3",
        ),
        (
            "breakpoints",
            "bad.dml:6: <breakpointDef bpID=\"A\">: axis 'A', breakpoint 2: "
            "5 does not exceed breakpoint 1",
        ),
        (
            "units",
            "bad.dml:14: <signalUnits>: unit mismatch in shot 's', signal 'alpha': the check "
            "gives 'rad' but <variableDef varID=\"alpha\"> (line 4) is in 'deg'",
        ),
    ],
)
def test_malformed_file_error_names_element_and_line(tmp_path: Path, kind: str, where: str) -> None:
    path = tmp_path / "bad.dml"
    path.write_text(_malformed(kind))
    with pytest.raises(aerodelta.ParseError) as info:
        load_daveml(path)
    assert where in str(info.value)


def test_good_reference_file_passes(tmp_path: Path) -> None:
    path = tmp_path / "good.dml"
    path.write_text(_malformed("good"))
    checks = check_daveml(path)
    assert checks.height == 1 and checks["pass"].all()
    assert checks["actual"][0] == pytest.approx(0.35, abs=1e-15)


def test_evaluate_errors_are_invalid_input(daveml_dir: Path) -> None:
    m = load_daveml(daveml_dir / "tables.dml")
    assert m.name == "tables.dml"  # no fileHeader name: the file name
    with pytest.raises(aerodelta.InvalidInputError, match="input 'in3'"):
        m.evaluate({"in1": [0.0], "in2": [0.0]})
    with pytest.raises(aerodelta.InvalidInputError, match="'bogus'"):
        m.evaluate({"in1": 0.0, "in2": 0.0, "in3": 0.0, "bogus": 1.0})
    df = m.evaluate(
        pl.DataFrame({"in1": [0.0], "in2": [0.0], "in3": [0.0], "bogus": [1.0]}), ignore_extra=True
    )
    assert df.columns == ["out1t", "out2t"]
    assert df.row(0) == (0.0, 23.0)  # the file's "multidimensional" shot


# -- The project's example model ------------------------------------------------------------


def test_example_model_round_trip(tmp_path: Path) -> None:
    spec = example_model()
    path = tmp_path / "example.dml"
    m = write_example_model(path)
    assert m.inputs == ["alpha_deg", "beta_deg", "p_hat", "r_hat", "da_deg", "dr_deg"]
    assert m.outputs == ["Cl", "Cn", "CY"]
    checks = check_daveml(path)
    assert checks["pass"].all() and checks.height == 9 * (3 + 6 + 10 + 3)
    # Closed form from the spec's tables (numpy interp holds the ends, as extrapolate="neither").
    rng = np.random.default_rng(5)
    n = 500
    x = {
        "alpha_deg": rng.uniform(-10.0, 30.0, n),
        "beta_deg": rng.uniform(-10.0, 10.0, n),
        "p_hat": rng.uniform(-0.1, 0.1, n),
        "r_hat": rng.uniform(-0.1, 0.1, n),
        "da_deg": rng.uniform(-20.0, 20.0, n),
        "dr_deg": rng.uniform(-20.0, 20.0, n),
    }
    tab = {
        t["id"]: np.interp(x["alpha_deg"], t["breakpoints"][0], t["values"]) for t in spec["tables"]
    }
    d2r = math.pi / 180.0
    cl = (
        d2r * (tab["Cl_beta"] * x["beta_deg"] + tab["Cl_da"] * x["da_deg"])
        + tab["Cl_p"] * x["p_hat"]
        + tab["Cl_r"] * x["r_hat"]
    )
    cn = (
        d2r * (tab["Cn_beta"] * x["beta_deg"] + tab["Cn_dr"] * x["dr_deg"])
        + tab["Cn_p"] * x["p_hat"]
        + tab["Cn_r"] * x["r_hat"]
    )
    cy = d2r * (tab["CY_beta"] * x["beta_deg"] + tab["CY_dr"] * x["dr_deg"])
    got = load_daveml(path).evaluate(pl.DataFrame(x))
    np.testing.assert_allclose(got["Cl"].to_numpy(), cl, rtol=0, atol=1e-14)
    np.testing.assert_allclose(got["Cn"].to_numpy(), cn, rtol=0, atol=1e-14)
    np.testing.assert_allclose(got["CY"].to_numpy(), cy, rtol=0, atol=1e-14)
    # Same text from the in-memory writer, apart from nothing: deterministic given a date.
    spec["date"] = "2026-01-01"
    assert daveml_text(spec) == daveml_text(spec)


def test_example_model_signs_follow_etkin(tmp_path: Path) -> None:
    m = write_example_model(tmp_path / "e.dml")
    lin = m.evaluate({"alpha_deg": 4.0, "beta_deg": 1.0}).row(0, named=True)
    assert lin["Cl"] < 0 and lin["Cn"] > 0 and lin["CY"] < 0  # dihedral, weathercock, side force
    da = m.evaluate({"alpha_deg": 4.0, "da_deg": 10.0}).row(0, named=True)
    assert da["Cl"] < 0  # positive aileron rolls left
    dr = m.evaluate({"alpha_deg": 4.0, "dr_deg": 10.0}).row(0, named=True)
    assert dr["Cn"] < 0  # positive rudder yaws left
    # Roll damping is lost through the stall.
    clp = m.evaluate({"alpha_deg": [4.0, 16.0]}, ["Cl_p"])["Cl_p"].to_list()
    assert clp[0] == pytest.approx(-0.5) and clp[1] > -0.15


def test_write_rejects_bad_spec_naming_the_table(tmp_path: Path) -> None:
    spec = example_model()
    spec["tables"][2]["breakpoints"] = [[0.0, 1.0]]
    with pytest.raises(aerodelta.InvalidInputError, match="table 'Cl_r'"):
        write_daveml(tmp_path / "x.dml", spec)
    assert not list(tmp_path.iterdir())


def test_core_binding_takes_and_returns_dicts(daveml_dir: Path) -> None:
    core = load_daveml(daveml_dir / "fiveD_table.dml")._m
    x = {f"in{k}": np.array([1.0, 2.0, 1.5]) for k in range(1, 6)}
    out = core.evaluate(x)
    assert list(out) == ["out1t"]
    assert isinstance(out["out1t"], np.ndarray)
    assert out["out1t"][:2].tolist() == [11111.0, 22222.0]
    assert core.evaluate(x, ["in3"])["in3"].tolist() == [1.0, 2.0, 1.5]


def test_docstring_examples_run() -> None:
    result = doctest.testmod(aerodelta.daveml, raise_on_error=False)
    assert result.attempted > 0 and result.failed == 0


def test_cli_internal_flag_lists_internal_values(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "e.dml"
    write_example_model(out)
    assert cli.main(["check-daveml", str(out), "--internal"]) == 0
    lines = capsys.readouterr().out.splitlines()
    internal = [ln for ln in lines if " internal " in ln and ln.endswith("pass")]
    assert len(internal) == 9 * 19  # 6 inputs + 10 tables + 3 outputs per shot
