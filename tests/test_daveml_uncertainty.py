"""The extended model's DAVE-ML carries the fitted bands as S-119 ``uncertainty`` and the fit's
``provenance`` (issue 19 item 4): read back equal to the model's band tables, cited by every Δ
table, valid against the public DAVE-ML 2.0 DTD (``../shared/data/daveml/DAVEfunc.dtd``, read
with lxml), and reported by ``aerodelta check-daveml``."""

from __future__ import annotations

import io
import re
from pathlib import Path

import numpy as np
import pytest

import aerodelta as ad
from aerodelta.cli import main
from aerodelta.daveml import DaveModel
from aerodelta.export import export_extended_daveml, extended_daveml_text
from aerodelta.model import DeltaModel


def banded_model(seed: int = 3) -> DeltaModel:
    """Two coefficients, three flaps, seeded tables with asymmetric bands around them (one
    term without a band)."""
    rng = np.random.default_rng(seed)
    flaps = [0.0, 10.0, 20.0]
    coefs = {}
    for c, terms in (("Cl", ["beta_deg", "phat", "1"]), ("Cn", ["rhat", "deadband(da_deg, 2)"])):
        out = []
        for k, reg in enumerate(terms):
            alpha = np.sort(rng.uniform(6.0, 24.0, 7))
            v = 0.01 * rng.normal(size=(3, 7))
            t = {"name": f"d{c}_{k}", "regressor": reg, "alpha_deg": alpha.tolist(),
                 "values": v.tolist()}  # fmt: skip
            if not (c == "Cn" and k == 1):
                lo, hi = v - rng.uniform(0, 0.004, v.shape), v + rng.uniform(0, 0.006, v.shape)
                t["band"] = {"level": 0.9, "lower": lo.tolist(), "upper": hi.tolist()}
            out.append(t)
        coefs[c] = {"terms": out, "alpha_l_deg": [8.0, 9.0, 10.0], "alpha_u_deg": [12, 13, 14]}
    return DeltaModel.from_spec(
        {"schema": "aerodelta.model/1", "flaps_deg": flaps, "coefficients": coefs,
         "provenance": {"library": "aerodelta test", "qualified": "adx37", "maneuvers": 12,
                        "rows": 3456, "data_sha256": "ab" * 32,
                        "config": {"bootstrap": 50, "band_level": 0.9, "seed": 11}}}
    )  # fmt: skip


def test_bands_read_back_as_absolute_uniform_bounds() -> None:
    model = banded_model()
    out = extended_daveml_text(model)
    unc = out.model.uncertainty()
    spec = model.to_spec()
    terms = [t for c in spec["coefficients"].values() for t in c["terms"]]
    banded = {t["name"]: t["band"] for t in terms if "band" in t}
    assert sorted(unc["variable"].to_list()) == sorted(banded)
    for row in unc.iter_rows(named=True):
        band = banded[row["variable"]]
        assert (row["effect"], row["distribution"], row["num_sigmas"]) == (
            "absolute", "uniform", None,
        )  # fmt: skip
        lower, upper = row["bounds"]
        # flap rows, alpha fastest, the exact doubles
        assert lower == [v for r in band["lower"] for v in r]
        assert upper == [v for r in band["upper"] for v in r]


def test_provenance_in_the_header_cited_by_every_delta_table() -> None:
    text = extended_daveml_text(banded_model()).text
    header = text[: text.index("</fileHeader>")]
    prov = re.search(r'<provenance provID="(\w+)">(.*?)</provenance>', header, re.S)
    assert prov is not None
    body = prov.group(2)
    for want in (
        "equation-error least squares", "aerodelta test", "built-in ADX-37",
        "12 maneuvers, 3456 samples", "ab" * 32, "90 % percentile bands of a 50-replicate "
        "bootstrap over maneuvers (seed 11)",
    ):  # fmt: skip
        assert want in body, want
    tables = re.findall(r'<griddedTableDef name="(d\w+)_table".*?</griddedTableDef>', text, re.S)
    refs = re.findall(
        r'<griddedTableDef name="(d\w+)_table"[^>]*>\s*<provenanceRef provID="(\w+)"/>', text
    )
    assert len(tables) == 5 and sorted(t for t, _ in refs) == sorted(tables)
    assert {p for _, p in refs} == {prov.group(1)}


def _dtd_with_mathml_stub(dtd: Path, text: str) -> str:
    """The public DTD with its external MathML 2 module replaced by declarations of the MathML
    elements the file uses (any content): everything outside ``<math>`` is checked against the
    DTD as published."""
    tags = set(re.findall(r"<([a-z]\w*)\b", "".join(re.findall(r"<math.*?</math>", text, re.S))))
    tags.discard("math")
    stub = ["<!ELEMENT math ANY>", "<!ATTLIST math xmlns CDATA #IMPLIED>"]
    stub += [f"<!ELEMENT {t} ANY>" for t in sorted(tags)]
    src = dtd.read_text(encoding="utf-8")
    src = re.sub(r"<!ENTITY % mathml2 PUBLIC[^>]*>\s*%mathml2;", "\n".join(stub), src)
    assert "%mathml2;" not in src
    return src


def test_exported_file_is_valid_against_the_daveml_dtd(daveml_dir: Path, tmp_path: Path) -> None:
    etree = pytest.importorskip("lxml.etree")
    path = tmp_path / "ext.dml"
    export_extended_daveml(path, banded_model())
    text = path.read_text(encoding="utf-8")
    dtd = etree.DTD(io.StringIO(_dtd_with_mathml_stub(daveml_dir / "DAVEfunc.dtd", text)))
    doc = etree.fromstring(text.encode(), etree.XMLParser(load_dtd=False, no_network=True))
    ok = dtd.validate(doc)
    assert ok, dtd.error_log.filter_from_errors()[:5]
    # the check: a band that misses its value breaks the DTD's rule for absolute bounds, and
    # is refused by the reader naming the line
    bad = text
    k = bad.index("<!-- upper -->")
    start = bad.index("<dataTable>", k) + len("<dataTable>")
    end = bad.index("</dataTable>", start)
    first = bad[start:end].split(",")[0]
    bad = bad[:start] + bad[start:end].replace(first, " -9.0", 1) + bad[end:]
    with pytest.raises(ad.ParseError, match=r"ext\.dml:\d+: <uniformPDF>: absolute bounds"):
        DaveModel.from_string(bad, "ext.dml")


def test_check_daveml_reports_the_uncertainty(tmp_path: Path, capsys) -> None:
    path = tmp_path / "ext.dml"
    export_extended_daveml(path, banded_model())
    assert main(["check-daveml", str(path)]) == 0
    out = capsys.readouterr().out
    assert "uncertainty: 4 variables or tables (4 absolute uniform)" in out


def test_a_fit_with_a_bootstrap_exports_its_bands(quick_campaign: Path, tmp_path: Path) -> None:
    data = ad.ingest(quick_campaign, compat=False).data
    res = ad.fit(data, config=ad.FitConfig(bootstrap=10, seed=2))
    out = export_extended_daveml(tmp_path / "ext.dml", res.model)
    spec = res.model.to_spec()
    terms = [t for c in spec["coefficients"].values() for t in c["terms"]]
    with_band = [t["name"] for t in terms if "band" in t]
    assert with_band, "the bootstrap gave bands"
    assert sorted(out.model.uncertainty()["variable"].to_list()) == sorted(with_band)
    # without a bootstrap: no uncertainty, and the provenance says why
    plain = extended_daveml_text(ad.fit(data).model)
    assert plain.model.uncertainty().height == 0
    assert "no bands: fitted without a bootstrap" in plain.text


@pytest.mark.parametrize("which", ["qualified", "example"])
def test_other_written_files_are_valid_against_the_dtd(
    which: str, daveml_dir: Path, tmp_path: Path
) -> None:
    etree = pytest.importorskip("lxml.etree")
    from aerodelta.daveml import write_example_model  # noqa: PLC0415
    from aerodelta.export import export_qualified_daveml  # noqa: PLC0415

    path = tmp_path / "m.dml"
    (export_qualified_daveml if which == "qualified" else write_example_model)(path)
    text = path.read_text(encoding="utf-8")
    dtd = etree.DTD(io.StringIO(_dtd_with_mathml_stub(daveml_dir / "DAVEfunc.dtd", text)))
    doc = etree.fromstring(text.encode(), etree.XMLParser(load_dtd=False, no_network=True))
    assert dtd.validate(doc), dtd.error_log.filter_from_errors()[:5]
