"""`FitResult.summary_text` and `aerodelta fit`: the results report an engineer reads."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
from aerodelta.cli import main

Row = tuple[str, float, str, str]


@pytest.fixture(scope="module")
def campaign(quick_campaign: Path) -> Path:
    return quick_campaign


@pytest.fixture(scope="module")
def data(campaign: Path) -> pl.DataFrame:
    return ad.ingest(campaign, compat=False, progress=False).data


@pytest.fixture(scope="module")
def result(data: pl.DataFrame) -> ad.FitResult:
    # 8 maneuvers per flap: select the structure anyway, so the report has its CV lines
    return ad.fit(data, config=ad.FitConfig(min_maneuvers_selection=5))


@pytest.fixture(scope="module")
def text(result: ad.FitResult) -> str:
    return result.summary_text(qualified="adx37")  # the campaign has no *_sim columns


def _num(tok: str) -> float:
    return float("nan") if tok == "-" else float(tok)


def parse(text: str) -> dict[Row, list[str]]:
    """Rows of the parameter tables: (coefficient, flap, "lo to hi" range, param) -> the
    fields estimate, std err, % err, t, partial F, identified, bins, and the reasons."""
    rows: dict[Row, list[str]] = {}
    block = rng = None
    last: Row | None = None
    for line in text.splitlines():
        m = re.match(r"^(C[lnY]), flap (\S+) deg -+$", line)
        if m:
            block = (m.group(1), float(m.group(2)))
            continue
        m = re.match(r"^ alpha (\S+ to \S+) deg: ", line)
        if m:
            rng = m.group(1)
            continue
        pat = r"^  (d\S+) +(\S+) +(\S+) +(\S+) +(\S+) +(\S+) +(\d+)/(\d+)(?:  (.*))?$"
        m = re.match(pat, line)
        if m and block is not None and rng is not None:
            last = (*block, rng, m.group(1))
            rows[last] = [*m.groups()[1:8], m.group(9) or ""]
        elif last is not None and line.startswith("      ") and not line.startswith("        "):
            rows[last][7] = line.strip()  # the reasons, on the line below
        elif last is not None and line.startswith("        "):
            rows[last][7] += " " + line.strip()
        else:
            last = None
    return rows


def test_report_names_every_coefficient_flap_and_parameter(result: ad.FitResult, text: str) -> None:
    rows = parse(text)
    for coef, flap, param in (
        result.params.select("coefficient", "flap_deg", "param").unique().rows()
    ):
        assert f"{coef}, flap {flap:g} deg" in text
        assert any(k[:2] == (coef, flap) and k[3] == param for k in rows), (coef, flap, param)
    assert "qualified model: the built-in ADX-37 lateral model" in text
    assert "CR2 cluster-robust by maneuver" in text and "Bell-McCaffrey" in text
    # the honest (nested) cross-validated score beside the optimistic one
    outer = result.cross_validation.filter(pl.col("structure") == "selected_outer")
    assert outer.height > 0
    flat = " ".join(text.split())  # wrapped lines joined
    assert f"{outer['cv_tic'][0]:.3f} the selection (nested, honest" in flat
    # one printed row per row of the summary table whose range has a fitted bin
    table = result.summary_table()
    ranges = table.group_by("coefficient", "flap_deg", "range").agg(pl.col("bins_fitted").max())
    fitted = table.join(
        ranges.filter(pl.col("bins_fitted") > 0), on=["coefficient", "flap_deg", "range"]
    )
    assert len(rows) == fitted.height


def test_stall_alpha_in_words(result: ad.FitResult, text: str) -> None:
    for flap, a in result.stall_alpha_deg.items():
        assert f"flap {flap:g} deg: stall at {a:.1f} deg alpha (max C_L, detected)" in text
    # a stall alpha given in the configuration says so: test_fit_cli_prints_the_report


def _range_rows(p: pl.DataFrame, key: Row) -> pl.DataFrame:
    coef, flap, span, param = key
    lo, hi = (float(v) for v in span.split(" to "))
    return p.filter(
        (pl.col("coefficient") == coef) & (pl.col("flap_deg") == flap)
        & (pl.col("param") == param)
        & (pl.col("alpha_lo_deg") >= lo - 0.051) & (pl.col("alpha_hi_deg") <= hi + 0.051)
    )  # fmt: skip


def test_numbers_match_the_params_frame(result: ad.FitResult, text: str) -> None:
    rows = parse(text)
    p = result.params
    # each row of a range: medians over the range's fitted bins, % error = 100 se / |estimate|
    checked = 0
    for key, (est, se, pct, _t, _f, ident, nbins, _why) in rows.items():
        if key[0] != "Cl":
            continue
        sel = _range_rows(p, key)
        assert int(nbins) == sel.height, key
        assert int(ident) == int(sel["identifiable"].sum()), key
        ok = sel.filter(pl.col("estimate").is_finite())
        m_est = float(np.median(ok["estimate"].to_numpy()))
        m_se = float(np.median(ok["std_err"].to_numpy()))
        assert _num(est) == pytest.approx(m_est, rel=1e-3, abs=1e-12), key
        assert _num(se) == pytest.approx(m_se, rel=1e-2), key
        assert _num(pct) == pytest.approx(100 * m_se / abs(m_est), rel=1e-3, abs=0.051), key
        checked += 1
    assert checked >= 20
    # one section per bin: each bin's own values
    per_bin = parse(result.summary_text(None))
    row = p.filter(pl.col("identifiable") & (pl.col("param") == "dCl_p")).row(0, named=True)
    span = f"{row['alpha_lo_deg']:.1f} to {row['alpha_hi_deg']:.1f}"
    est, se, pct, t, f, ident, nbins, why = per_bin[("Cl", row["flap_deg"], span, "dCl_p")]
    assert _num(est) == pytest.approx(row["estimate"], rel=1e-3)
    assert _num(pct) == pytest.approx(
        100 * row["std_err"] / abs(row["estimate"]), rel=1e-3, abs=0.051
    )
    assert _num(t) == pytest.approx(row["t"], abs=0.0051)
    assert _num(f) == pytest.approx(row["partial_f"], rel=1e-3, abs=0.0051)
    assert (ident, nbins, why) == ("1", "1", "")


def test_reasons_for_not_identified_parameters(result: ad.FitResult, text: str) -> None:
    rows = parse(text)
    silent = [k for k, v in rows.items() if int(v[5]) < int(v[6]) and not v[7]]
    assert not silent, f"not identified without a reason: {silent[:3]}"
    # a collinear parameter names the term its estimate trades against, counted over the bins
    col = result.params.filter(pl.col("note").str.starts_with("collinear with '"))
    assert col.height > 0, "the quick campaign has collinear bins"
    assert re.search(r"collinear with '[^']+'[^;]* in \d+ of \d+ bins", text)
    assert "(estimate correlation" not in text and "VIF 1" not in text, "reasons are shortened"
    few = result.params.filter(pl.col("note").str.contains("maneuvers in the bin"))
    if few.height:
        assert "fewer than 5 maneuvers in" in text
    for coef in ("Cl", "Cn", "CY"):
        assert re.search(rf"\n  {coef}: [\d,]+ bin estimates, \d+% identified\n", text)
    assert "    not identified: " in text and "x collinear with other terms" in text


def test_no_python_reprs_and_short_lines(result: ad.FitResult, text: str) -> None:
    for t in (text, result.summary_text(None), result.summary_text(2.0), str(result)):
        for line in t.splitlines():
            assert not re.search(r"[\[{]['\"]|\{\}|\[\]|np\.|\bnan\b|\bNone\b|\binf\b", line), line
            assert len(line) <= 100, line
    assert str(result).startswith("Δ-model identification")
    # the fit records the qualified model it resolved (provenance.qualified): the virtual
    # campaign's records were marked as flown on the built-in aircraft
    assert "qualified model: the built-in ADX-37 lateral model" in str(result)
    assert result.model.to_spec()["provenance"]["qualified"] == "adx37"
    assert "the fit's notes" not in text
    for note in result.notes:  # every note is printed, under its coefficient and flap
        tail = note.split(": ", 1)[1]
        assert tail.split()[0] in text


def test_summary_keeps_its_frame(result: ad.FitResult) -> None:
    s = result.summary()
    assert isinstance(s, pl.DataFrame) and s.height == result.params.height
    t = result.summary_table(2.0)
    cols = {"estimate", "std_err", "pct_error", "t", "partial_f", "reasons", "identified"}
    assert cols | {"bins", "r2_min", "r2_max"} <= set(t.columns)
    assert t.height > result.summary_table(5.0).height
    assert result.summary_table(None).height == result.params.height
    with pytest.raises(ad.AerodeltaError, match="range_deg"):
        result.summary_table(0.0)


def test_fit_cli_prints_the_report(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cfg = tmp_path / "fit.toml"
    cfg.write_text('[stall_alpha_deg]\n"10" = 16.0\n')
    out = tmp_path / "model.json"
    argv = ["fit", str(campaign), "--out", str(out), "--no-progress"]
    assert main([*argv, "--config", str(cfg), "--range", "10"]) == 0
    o = capsys.readouterr().out
    assert "flap 10 deg: stall at 16.0 deg alpha (given in the configuration)" in o
    assert "flap 0 deg: stall at" in o and "(max C_L, detected)" in o
    assert "qualified model: the built-in ADX-37 lateral model" in o
    assert "per 10-deg alpha range" in o and re.search(r"\n  Cl: [\d,]+ bin estimates", o)
    assert "structure as given (not selected: 8 maneuvers at this flap, 15 needed)" in o
    assert main([*argv, "--verbose"]) == 0  # one section per bin
    o = capsys.readouterr().out
    assert "one section per alpha bin" in o
    assert re.search(r"\n alpha \S+ to \S+ deg: [\d,]+ points, \d+ maneuvers, R² ", o)
    assert main([*argv, "--range", "0"]) == 1
    assert "--range 0" in capsys.readouterr().err
