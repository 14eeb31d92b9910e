"""``aerodelta rolloff`` in-process on a small virtual campaign, and the roll-off figures:
events traceable to the injected truth (maneuver and time), statistics consistent with the
events, a usable runtime configuration, the Monte Carlo comparison, PNG files; figure data
against Eq. 3.20 in closed form."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import polars as pl
import pytest

import aerodelta as ad
import aerodelta.rolloff as ro
from aerodelta import rolloff_plots as rp
from aerodelta.cli import main

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


@pytest.fixture(scope="module")
def campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    out = tmp_path_factory.mktemp("cli_rolloff") / "camp"
    ad.generate_campaign(out, effects="none", seed=21, size=1, excitation=0.0)
    return out


def test_cli_rolloff_writes_traceable_events_statistics_and_monte_carlo(
    campaign: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "ro"
    argv = ["rolloff", "--data", str(campaign), "--out", str(out), "--no-progress"]
    rc = main([*argv, "--monte-carlo", "4", "--seed", "3", "--threads", "2"])
    assert rc == 0
    stdout = capsys.readouterr().out
    assert "roll-off events accepted" in stdout
    ev = pl.read_csv(out / "events.csv")
    acc = ev.filter(pl.col("accepted"))
    assert acc.height >= 3
    # traceable: each accepted event is a straight stall of the manifest, and its peak time is
    # within 3 s of the injected roll-off's largest contribution (truth files)
    manifest = pl.read_csv(campaign / "manifest.csv")
    for r in acc.iter_rows(named=True):
        row = manifest.filter(pl.col("maneuver_id") == r["maneuver_id"])
        assert row.height == 1 and row["kind"][0] == "straight"
        tr = pl.read_parquet(campaign / "truth" / f"{r['maneuver_id']}.parquet")
        d = tr["dCl_stochastic_rolloff"].to_numpy()
        assert abs(r["t_peak"] - tr["t"][int(np.argmax(np.abs(d)))]) < 3.0
        assert np.sign(r["peak"]) == np.sign(d[np.argmax(np.abs(d))])
    # statistics are those of the accepted events
    stats = json.loads((out / "statistics.json").read_text())
    assert sum(s["n"] for s in stats) == acc.height
    for s in stats:
        a = acc.filter(pl.col("flap_deg") == s["flap_deg"])["alpha_onset_deg"].to_numpy()
        assert s["alpha_mean_deg"] == pytest.approx(a.mean())
    # the derived configuration is accepted by the runtime model
    cfg = json.loads((out / "rolloff_config.json").read_text())
    assert ro.sample_draws(cfg, 0.0, seed=1, n=3).height == 3
    mc = pl.read_parquet(out / "monte_carlo.parquet")
    flaps = sorted(manifest.filter(pl.col("kind") == "straight")["flap_deg"].unique().to_list())
    assert mc.height == 4 * len(flaps)
    again = ro.monte_carlo(4, seed=3, flap_deg=0.0, config=cfg)
    assert again.equals(mc.filter(pl.col("flap_deg") == 0.0))
    cmp = json.loads((out / "mc_comparison.json").read_text())
    assert {c["quantity"] for c in cmp} == {"onset_alpha_deg", "max_bank_deg"}
    max_roll = pl.read_csv(out / "max_roll.csv")
    assert max_roll.height == manifest.filter(pl.col("kind") == "straight").height
    figs = sorted(p.name for p in (out / "figures").iterdir())
    assert "drc.png" in figs and "max_roll.png" in figs
    assert sum(f.startswith("event_") for f in figs) == min(3, acc.height)
    assert sum(f.startswith("mc_histograms_") for f in figs) == len(flaps)
    for f in (out / "figures").iterdir():
        assert f.read_bytes()[:8] == PNG_MAGIC
    summary = json.loads((out / "summary.json").read_text())
    assert summary["accepted"] == acc.height
    assert not list(out.glob("*.tmp-*"))


def test_cli_rolloff_rejects_a_bad_level(campaign: Path, tmp_path: Path) -> None:
    rc = main(["rolloff", "--data", str(campaign), "--out", str(tmp_path), "--level", "1.5"])
    assert rc == 1


def test_drc_figure_plots_eq_3_20_and_the_envelope(tmp_path: Path) -> None:
    t = np.linspace(0.0, 5.0, 51)
    d = pl.DataFrame(
        {
            "maneuver_id": ["a"] * 51,
            "kind": ["straight"] * 51,
            "phi_deg": 10.0 * np.sin(t),
            "p_dps": 10.0 * np.cos(t),
            "q_dps": np.full(51, 2.0),
            "r_dps": np.full(51, 1.0),
            "theta_deg": np.full(51, 8.0),
            "da_deg": np.linspace(-5, 5, 51),
        }
    )
    fig = rp.drc_figure(d, phi_limit_deg=45.0)
    lines = fig.axes[0].get_lines()
    x, y = lines[0].get_data()
    ph = np.radians(d["phi_deg"].to_numpy())
    th = math.radians(8.0)
    phidot = d["p_dps"].to_numpy() + (2.0 * np.sin(ph) + np.cos(ph)) * math.tan(th)
    np.testing.assert_allclose(x, d["phi_deg"].to_numpy() + phidot, rtol=1e-12)
    np.testing.assert_allclose(y, d["da_deg"].to_numpy())
    env_x, env_y = lines[1].get_data()
    assert max(env_x) == 45.0 and max(env_y) == rp.AILERON_LIMIT_DEG
    path = rp.save_figure(fig, tmp_path / "drc.png")
    assert path.read_bytes()[:8] == PNG_MAGIC
    assert not list(tmp_path.glob("*.tmp-*"))


def test_event_max_roll_and_histogram_figures() -> None:
    t = np.arange(0.0, 10.0, 0.1)
    rec = pl.DataFrame(
        {
            "maneuver_id": ["m1"] * t.size,
            "t": t,
            "Cl_meas": 0.01 * np.exp(-0.5 * ((t - 5.0) / 0.3) ** 2),
            "Cl_model": np.zeros(t.size),
            "da_deg": np.where(t > 5.5, -8.0, 0.0),
            "alpha_deg": 10.0 + t,
        }
    )
    ev = {"t_onset": 4.5, "t_peak": 5.0, "alpha_onset_deg": 14.5, "peak": 0.01, "accepted": True}
    fig = rp.event_figure(rec, ev, model_column="Cl_model")
    assert len(fig.axes) == 3  # C_l, aileron (twin), alpha
    marks = [ln.get_xdata()[0] for ln in fig.axes[0].get_lines()[2:]]
    assert marks == [4.5, 5.0]
    mr = pl.DataFrame(
        {"maneuver_id": ["a_p", "b_n", "c_n"], "flap_deg": [0.0, 0.0, 5.0],
         "max_roll_deg": [8.0, 26.0, 12.0]}
    )  # fmt: skip
    fig = rp.max_roll_figure(mr)
    assert "1 of 3 above 20" in fig.axes[0].get_title()
    rng = np.random.default_rng(0)
    mc = pl.DataFrame(
        {"onset_alpha_deg": rng.normal(16, 1, 200), "max_bank_deg": rng.gamma(3, 4, 200)}
    )
    fig = rp.mc_histograms(
        mc,
        pl.DataFrame({"alpha_onset_deg": rng.normal(16, 1, 20), "accepted": [True] * 20}),
        mr,
    )
    assert len(fig.axes) == 2
    with pytest.raises(ad.DataError, match="missing"):
        rp.event_figure(rec.drop("da_deg"))


def test_cli_rolloff_removes_a_delta_model(campaign: Path, tmp_path: Path) -> None:
    # the --model path: a Δ model that adds nothing leaves the events byte-identical
    zero = {
        "schema": "aerodelta.model/1",
        "flaps_deg": [0.0, 35.0],
        "coefficients": {
            "Cl": {
                "terms": [
                    {
                        "name": "dCl_0",
                        "regressor": "1",
                        "alpha_deg": [10.0, 20.0],
                        "values": [[0.0, 0.0], [0.0, 0.0]],
                    }
                ],
                "alpha_l_deg": [8.0, 8.0],
                "alpha_u_deg": [10.0, 10.0],
            }
        },
    }
    model = tmp_path / "zero.json"
    ad.DeltaModel.from_spec(zero).save(model)
    base = ["rolloff", "--data", str(campaign), "--no-progress", "--no-figures"]
    assert main([*base, "--out", str(tmp_path / "a")]) == 0
    assert main([*base, "--out", str(tmp_path / "b"), "--model", str(model)]) == 0
    a = (tmp_path / "a" / "events.csv").read_bytes()
    assert a == (tmp_path / "b" / "events.csv").read_bytes()
