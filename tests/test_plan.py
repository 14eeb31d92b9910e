"""``aerodelta plan`` (issue 21): campaign design studies on a Dask LocalCluster.

A tiny matrix (two flaps, two maneuvers per kind, a few bootstrap replicates) keeps each test
within about a minute on two loaded cores. Checked: the same seeds give the same bytes with 1
and 2 workers; a rerun resumes and runs only the missing seed; a failing task is retried and
reported with its seed, never dropped; an unknown key is refused in one line; the aggregates
against numpy over the task files; the roll-off Monte Carlo in chunks against one engine call.
"""

from __future__ import annotations

import json
import operator
import os
import shutil
import signal
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import polars as pl
import pytest

try:
    import distributed  # noqa: F401
except ImportError:  # the plan/test extras install it; CI (CI=1) must run these tests
    if os.environ.get("CI"):
        raise
    pytest.skip(
        "dask[distributed] not installed: pip install 'aerodelta[plan]'", allow_module_level=True
    )

import aerodelta as ad
from aerodelta.campaign import campaign_plan
from aerodelta.cli import main
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.plan import load_matrix, run_plan, run_rolloff_study
from aerodelta.plan import task as plan_task
from aerodelta.plan.aggregate import recommendation
from aerodelta.plan.engine import open_client
from aerodelta.plan.matrix import KINDS, parse_matrix
from aerodelta.plan.plots import band_figure, compare_figure
from aerodelta.plan.rolloff import mc_chunk
from aerodelta.plan.suite import run_cases
from aerodelta.plan.task import _scratch
from aerodelta.rolloff import monte_carlo

JSB = """
[aircraft]
simulator = "jsbsim"
name = "f15"

[flaps.0]
straight = 2
turning = 2
sideslip = 2
"""

TINY = """
[campaign]
noise = 1.0
turbulence_mps = 0.5

[effects]
aileron_effectiveness = 1.0
roll_damping = 1.0
directional_stability = 1.0

[flaps.0]
straight = 2
turning = 2
accelerated = 2
asymmetric_thrust = 2

[flaps.15]
straight = 3
turning = 2
accelerated = 1
asymmetric_thrust = 2
pusher = "off"

[fit]
bootstrap = 6

[diagnosis]
enabled = true

[targets]
alpha_edges_deg = [8, 14, 20]
"""
SEEDS = 3


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    """A LocalCluster with 2 worker processes (one thread each), shared by the module."""
    with open_client(workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def tiny(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("plan_matrix") / "tiny.toml"
    p.write_text(TINY)
    return p


@pytest.fixture(scope="module")
def study(tiny: Path, client: Any, tmp_path_factory: pytest.TempPathFactory) -> Path:
    """The tiny study on 2 workers (seeds 1-3)."""
    out = tmp_path_factory.mktemp("plan_study") / "two"
    r = run_plan(tiny, campaigns=SEEDS, seed=1, out=out, client=client, progress=False)
    assert r.failures == [] and r.ran == [1, 2, 3]
    return out


def _tasks(out: Path) -> list[dict[str, Any]]:
    return [
        json.loads(p.read_text())["summary"] for p in sorted((out / "tasks").glob("seed-*.json"))
    ]


def test_one_two_and_four_workers_give_the_same_bytes(
    study: Path, tiny: Path, tmp_path: Path
) -> None:
    # issue 21: the same study result with 1, 2 and 4 workers (4 on this 2-core machine: more
    # worker processes than cores, the tasks land and finish in another order)
    for workers in (1, 4):
        out = tmp_path / f"w{workers}"
        r = run_plan(tiny, campaigns=SEEDS, seed=1, out=out, workers=workers, progress=False)
        assert r.ran == [1, 2, 3]
        for name in ("summary.json", "params.csv", "effects.csv", "coverage.csv"):
            assert (out / name).read_bytes() == (study / name).read_bytes(), (workers, name)
        for a, b in zip(_tasks(out), _tasks(study), strict=True):
            assert a == b
        assert json.loads((out / "run.json").read_text())["workers"] == f"local:{workers}"


def test_summary_holds_the_matrix_counts_and_aggregates_match_numpy(
    study: Path, tiny: Path
) -> None:
    m = load_matrix(tiny)
    tasks = _tasks(study)
    assert [t["seed"] for t in tasks] == [1, 2, 3]
    # the maneuvers flown per flap and kind are the matrix's counts (pusher split as asked)
    for t in tasks:
        assert t["maneuvers"] == m.n_maneuvers() == 16
        seen = {(c["flap_deg"], c["kind"]): c["maneuvers"] for c in t["coverage"]}
        want = {(f.flap_deg, k): n for f in m.flaps for k, n in f.counts.items() if n}
        assert seen == want
    # the study's table against numpy over the task files
    params = pl.read_csv(study / "params.csv")
    rows = [r for t in tasks for r in t["params"]]
    key = ("Cl", 0.0, "dCl_p", 14.0)
    sel = [
        r for r in rows if (r["coefficient"], r["flap_deg"], r["param"], r["alpha_lo_deg"]) == key
    ]
    assert len(sel) == SEEDS
    ok = [r for r in sel if r["identified"]]
    got = params.filter(
        (pl.col("coefficient") == "Cl")
        & (pl.col("flap_deg") == 0.0)
        & (pl.col("param") == "dCl_p")
        & (pl.col("alpha_lo_deg") == 14.0)
    ).row(0, named=True)
    assert got["p_identified"] == pytest.approx(len(ok) / SEEDS)
    se = np.array([r["se"] for r in ok])
    assert got["se_bootstrap"] == pytest.approx(float(np.sqrt(np.mean(se**2))), rel=1e-12)
    assert got["band_width"] == pytest.approx(float(np.median([r["band"] for r in ok])), rel=1e-12)
    est = np.array([r["estimate"] for r in ok])
    assert got["se_predicted"] == pytest.approx(float(np.std(est, ddof=1)), rel=1e-9)
    assert got["bias"] == pytest.approx(float(np.mean(est)) - sel[0]["truth"], rel=1e-9)
    # expected Δ: roll damping is in the truth, so the relative band is defined there
    assert got["truth_max"] > 0
    assert got["band_relative"] == pytest.approx(got["band_width"] / got["truth_max"])
    # the figure shows the table: each Cl cell is band_relative (capped at 3x the target)
    assert (study / "band.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    fig = band_figure(params, m.relative_band_width, m.alpha_edges_deg, m.name)
    shown = fig.axes[0].images[0].get_array()
    cl = params.filter((pl.col("coefficient") == "Cl") & (pl.col("truth_max") > 0))
    labels = sorted(set(cl.select("param", "flap_deg").iter_rows()))
    for r in cl.iter_rows(named=True):
        v = shown[
            labels.index((r["param"], r["flap_deg"])), m.alpha_edges_deg.index(r["alpha_lo_deg"])
        ]
        want = r["band_relative"]
        if want is None or not np.isfinite(want):
            assert np.ma.is_masked(v) or not np.isfinite(v)
        else:
            assert float(v) == pytest.approx(min(want, 3 * m.relative_band_width))
    eff = pl.read_csv(study / "effects.csv")
    named = [t["effects"]["roll_damping"] for t in tasks]
    assert eff.filter(pl.col("effect") == "roll_damping")["p_named"][0] == pytest.approx(
        float(np.mean(named))
    )


def test_resume_runs_only_the_missing_seed_and_a_failing_task_is_reported(
    study: Path, tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "resume"
    shutil.copytree(study, out)
    (out / "tasks" / "seed-000002.json").unlink()
    # the same matrix with seed 2 drilled to fail (the drill is not part of the matrix's digest)
    drill = tmp_path / "drill.toml"
    drill.write_text(TINY + "\n[engine]\nretries = 1\nfault_drill_seeds = [2]\n")
    argv = ["plan", str(drill), "--campaigns", "3", "--seed", "1", "--out", str(out)]
    rc = main([*argv, "--workers", "2", "--no-progress"])
    assert rc == 1
    stdout = capsys.readouterr().out
    assert "seed 2 failed: FaultDrillError: seed 2: fault drill" in stdout
    s = json.loads((out / "summary.json").read_text())
    assert [f["seed"] for f in s["failures"]] == [2] and s["campaigns"] == 2
    run = json.loads((out / "run.json").read_text())
    assert run["ran"] == [] and run["failed"] == [2] and run["resumed"] == [1, 3]
    assert not (out / "tasks" / "seed-000002.json").exists()
    # rerun without the drill: only seed 2 runs, and the study is byte-identical to the original
    r = run_plan(tiny, campaigns=3, seed=1, out=out, workers=1, progress=False)
    assert r.ran == [2] and r.failures == []
    assert (out / "summary.json").read_bytes() == (study / "summary.json").read_bytes()
    assert (out / "params.csv").read_bytes() == (study / "params.csv").read_bytes()


def _record_campaigns(monkeypatch: pytest.MonkeyPatch, module: Any, name: str) -> list[Any]:
    """Wrap the campaign generator ``module.name`` so that each call's returned info is
    appended to the list returned here (the campaigns a task flew, in order)."""
    infos: list[Any] = []
    real = getattr(module, name)

    def spy(*args: Any, **kw: Any) -> Any:
        info = real(*args, **kw)
        infos.append(info)
        return info

    monkeypatch.setattr(module, name, spy)
    return infos


def test_a_task_flies_only_the_matrix_maneuvers_and_summarises_as_from_the_whole_campaign(
    tiny: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The tiny matrix's largest cell (3 straight stalls at flap 15, pusher off) makes a
    campaign of 120 maneuvers of which it uses 16. The task flies those 16 only; its summary
    equals the one from flying the whole campaign and selecting them."""
    spec = load_matrix(tiny).task_spec()
    picked = plan_task.maneuvers_to_fly(2, spec)
    plan = campaign_plan(seed=2, size=3)
    assert plan.height == 120 and len(picked) == 16
    rows = plan.filter(pl.col("maneuver_index").is_in(picked))
    counts = {
        (f, k, p): n for f, k, p, n in rows.group_by("flap_deg", "kind", "pusher").len().rows()
    }
    assert counts[(15.0, "straight", False)] == 3 and counts[(0.0, "straight", True)] == 1
    assert not any(p for f, _, p in counts if f == 15.0)
    infos = _record_campaigns(monkeypatch, plan_task, "generate_campaign")
    few = plan_task.run_task(spec, 2)
    monkeypatch.setattr(plan_task, "maneuvers_to_fly", lambda seed, spec: [])
    whole = plan_task.run_task(spec, 2)
    assert [i.n_maneuvers for i in infos] == [16, 120]
    few.pop("peak_rss_mib")
    whole.pop("peak_rss_mib")
    assert few == whole and few["maneuvers"] == 16


def _worker_env() -> tuple[str | None, str | None]:
    return os.environ.get("MALLOC_TRIM_THRESHOLD_"), os.environ.get("MALLOC_ARENA_MAX")


def _polars_threads() -> int:
    import polars  # noqa: PLC0415

    return polars.thread_pool_size()


def _worker_folder(dask_worker: Any) -> str:
    return str(dask_worker.local_directory)


def test_workers_keep_glibc_adaptive_malloc_and_fly_in_their_own_folder(client: Any) -> None:
    """Dask's default MALLOC_TRIM_THRESHOLD_ pins glibc's mmap threshold at 128 kB (a default
    campaign task then faulted in 2.7 million pages, a quarter of its CPU in the kernel): the
    local workers start without it and with at most 2 arenas. A task flies its campaign in its
    worker's folder, which Dask deletes when a killed worker's folder is left behind."""
    envs = client.run(_worker_env)
    assert len(envs) == 2
    assert set(envs.values()) == {(None, "2")}
    # one polars thread per worker, as one engine thread (WORKER_ENV): two workers on two
    # cores would otherwise run four polars threads
    assert set(client.run(_polars_threads).values()) == {1}
    for address, local in client.run(_worker_folder).items():
        # as a task on that worker, as run_task runs
        scratch = client.submit(_scratch, workers=[address], pure=False).result()
        assert scratch == local and Path(local).is_dir()
    assert _scratch() is None  # not on a worker: the system's temporary folder


def test_a_killed_worker_loses_no_result(study: Path, tiny: Path, tmp_path: Path) -> None:
    """SIGKILL one of two workers once the first seed is saved: Dask moves its task to the
    other worker (the nanny restarts the dead one) and the study ends with the same bytes."""
    out = tmp_path / "killed"
    killed: list[int] = []
    with open_client(workers=2) as c:
        pids = sorted(c.run(os.getpid).values())

        def kill_one() -> None:
            deadline = time.monotonic() + 120
            while not list((out / "tasks").glob("seed-*.json")) and time.monotonic() < deadline:
                time.sleep(0.2)
            os.kill(pids[0], signal.SIGKILL)
            killed.append(pids[0])

        t = threading.Thread(target=kill_one, daemon=True)
        t.start()
        r = run_plan(tiny, campaigns=SEEDS, seed=1, out=out, client=c, progress=False)
        t.join(timeout=5)
    assert killed == [pids[0]]
    assert r.failures == [] and r.ran == [1, 2, 3]
    assert (out / "summary.json").read_bytes() == (study / "summary.json").read_bytes()


def test_cli_on_a_scheduler_address_runs_the_missing_seed(
    study: Path, tiny: Path, client: Any, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "sched"
    shutil.copytree(study, out)
    (out / "tasks" / "seed-000003.json").unlink()
    addr = client.scheduler.address
    argv = ["plan", str(tiny), "--campaigns", "3", "--seed", "1", "--out", str(out)]
    assert main([*argv, "--scheduler", addr, "--no-progress"]) == 0
    assert "seeds run now: 1, resumed: 2" in capsys.readouterr().out
    run = json.loads((out / "run.json").read_text())
    assert run["ran"] == [3] and run["workers"] == addr
    assert (out / "summary.json").read_bytes() == (study / "summary.json").read_bytes()


def test_a_scheduler_that_does_not_answer_is_one_line(
    tiny: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["plan", str(tiny), "--campaigns", "1", "--out", str(tmp_path / "o")]
    assert main([*argv, "--scheduler", "tcp://127.0.0.1:9", "--no-progress"]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1
    assert "--scheduler tcp://127.0.0.1:9: no Dask scheduler answered" in err


def test_a_task_folder_of_another_matrix_is_refused(study: Path, tmp_path: Path) -> None:
    out = tmp_path / "other"
    shutil.copytree(study, out)
    other = tmp_path / "other.toml"
    other.write_text(TINY.replace("bootstrap = 6", "bootstrap = 7"))
    with pytest.raises(DataError, match=r"seed-000001\.json: a task of another matrix"):
        run_plan(other, campaigns=3, seed=1, out=out, workers=1, progress=False)


@pytest.mark.parametrize(
    ("text", "needle"),
    [
        (
            "[campaign]\nnoize = 1\n",
            "[campaign]: unknown key 'noize'; allowed: noise, turbulence_mps",
        ),
        (
            "[flaps.0]\nstraigth = 2\n",
            "[flaps.0]: unknown key 'straigth'; allowed: straight, turning",
        ),
        (
            "[flaps.20]\nstraight = 2\n",
            "[flaps.20]: flap 20 deg is not flown by the virtual aircraft",
        ),
        ("[flaps.0]\nstraight = 2\n[effects]\nwing_rock = 1\n", "unknown effect 'wing_rock'"),
        ("[flaps.0]\nstraight = -1\n", "[flaps.0] straight = -1: give an integer >= 0"),
        ("[flaps.0]\nstraight = 1\n[fit]\nreplicates = 5\n", "[fit]: unknown key 'replicates'"),
        (
            "[flaps.0]\nstraight = 1\n[plan]\nx = 1\n",
            "unknown key 'plan'; allowed: campaign, effects",
        ),
        (
            '[aircraft]\nname = "f15"\n[flaps.0]\nstraight = 1\n',
            "[aircraft] name: applies to a JSBSim aircraft",
        ),
        (
            JSB.replace('name = "f15"', 'name = "f16"'),
            "[aircraft] name = 'f16': give a JSBSim aircraft, one of f15, DHC6",
        ),
        (JSB + "[effects]\ndihedral = 1\n", "[effects] is the virtual aircraft's"),
        (JSB.replace("[flaps.0]", "[flaps.5]"), "flap 5 deg is not flown by JSBSim's f15"),
        (JSB.replace("sideslip = 2", "asymmetric_thrust = 2"), "unknown key 'asymmetric_thrust'"),
        (
            JSB.replace('name = "f15"', 'name = "f15"\nwithhold = ["Cmq"]'),
            "'Cmq' is not a lateral term of f15 tabulated over alpha",
        ),
        (
            JSB + "[campaign]\nturbulence_mps = 1\n",
            "[campaign] turbulence_mps: the virtual aircraft's; a JSBSim campaign takes noise",
        ),
    ],
)
def test_bad_matrix_is_refused_in_one_line(
    text: str, needle: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    p = tmp_path / "bad.toml"
    p.write_text(text)
    rc = main(["plan", str(p), "--campaigns", "1", "--out", str(tmp_path / "o"), "--no-progress"])
    assert rc == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("aerodelta plan: error: ")
    assert str(p) in err and needle in err
    assert not (tmp_path / "o").exists()


def test_a_jsbsim_aircraft_study_reports_its_fit_against_the_xml_truth(
    client: Any, tmp_path: Path
) -> None:
    """A matrix of JSBSim's F-15 (its default withheld terms Clb, Clp, Cnb): the study's
    numbers are those of the same campaign flown, fitted and compared with the aircraft's XML
    directly (``generate_jsbsim_campaign``, ``fit(qualified="columns")``,
    ``true_delta_derivative``)."""
    pytest.importorskip("jsbsim")
    from aerodelta.jsbsim_campaign import (  # noqa: PLC0415
        generate_jsbsim_campaign,
        true_delta_derivative,
    )

    m = tmp_path / "f15.toml"
    m.write_text(JSB + "[fit]\nbootstrap = 5\n[targets]\nalpha_edges_deg = [12, 16, 20]\n")
    r = run_plan(m, campaigns=1, seed=3, out=tmp_path / "study", client=client, progress=False)
    assert r.failures == [] and r.matrix.simulator == "jsbsim"
    camp = tmp_path / "camp"
    generate_jsbsim_campaign(camp, aircraft="f15", seed=3, size=2, withhold=["Clb", "Clp", "Cnb"])
    data = ad.ingest(camp, compat=False, progress=False).data
    fit = ad.fit(data, qualified="columns", config=ad.FitConfig(bootstrap=5, seed=3))
    expected = r.params.filter(pl.col("truth_max") > 0)
    assert set(expected["param"]) == {"dCl_beta", "dCl_p", "dCn_beta"}
    for row in expected.iter_rows(named=True):
        sm = fit.smoothed.filter(
            (pl.col("coefficient") == row["coefficient"])
            & (pl.col("param") == row["param"])
            & (pl.col("alpha_deg") >= row["alpha_lo_deg"])
            & (pl.col("alpha_deg") < row["alpha_hi_deg"])
        )
        grid = sm["alpha_deg"].to_numpy()
        truth = true_delta_derivative(camp, row["coefficient"], row["regressor"], 0.0, grid)
        assert row["truth"] == pytest.approx(float(truth.mean()), rel=1e-12)
        assert row["estimate_mean"] == pytest.approx(float(sm["value"].mean()), rel=1e-12)
    # the maneuver kinds are the JSBSim pilot's: 2 of each per campaign
    kinds = set(pl.read_csv(tmp_path / "study" / "coverage.csv")["kind"])
    assert kinds == {"straight", "turning", "sideslip"}


def test_a_jsbsim_task_flies_only_the_matrix_maneuvers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """An uneven F-15 matrix (3 straight entries, 1 turning, 1 sideslip) takes the campaign of
    3 of each kind (9 maneuvers) and flies its first straight ones, the first turning and the
    first sideslip only: 5 maneuvers. ``jsbsim_campaign_plan`` lists the whole campaign as its
    manifest does, and the summary equals the one from flying the whole campaign."""
    pytest.importorskip("jsbsim")
    import aerodelta.jsbsim_campaign as jc  # noqa: PLC0415

    m = tmp_path / "uneven.toml"
    m.write_text(
        '[aircraft]\nsimulator = "jsbsim"\nname = "f15"\n\n[flaps.0]\nstraight = 3\n'
        "turning = 1\nsideslip = 1\n\n[fit]\nbootstrap = 5\n[targets]\n"
        "alpha_edges_deg = [12, 16, 20]\n"
    )
    spec = load_matrix(m).task_spec()
    real_plan = jc.jsbsim_campaign_plan
    infos = _record_campaigns(monkeypatch, jc, "generate_jsbsim_campaign")
    few = plan_task.run_task(spec, 4)
    monkeypatch.setattr(jc, "jsbsim_campaign_plan", lambda *a, **k: real_plan(*a, **k).head(0))
    whole = plan_task.run_task(spec, 4)
    flown, everything = (i.manifest for i in infos)
    plan = real_plan("f15", seed=4, size=3)
    assert everything.height == plan.height == 9
    for col in ("flap_deg", "kind", "pusher"):
        assert everything[col].to_list() == plan[col].to_list(), col
    assert [int(mid.rsplit("_", 1)[1]) for mid in everything["maneuver_id"]] == list(range(9))
    kinds = flown["kind"].to_list()
    assert kinds == ["straight"] * 3 + ["turning", "other"]
    assert (
        flown["maneuver_id"].to_list()
        == everything["maneuver_id"].gather([0, 1, 2, 3, 6]).to_list()
    )
    few.pop("peak_rss_mib")
    whole.pop("peak_rss_mib")
    assert few == whole and few["maneuvers"] == 5


def test_recommendation_follows_the_numbers() -> None:
    """A hand-built table: one parameter at flap 15 with a band twice the target over 8
    maneuvers needs (0.4 / 0.2)² x 8 = 32 maneuvers, as the kind with the most samples per
    maneuver in that alpha range (turning, 300 against 120); one five times the target would
    need 200, beyond 4x the flap's 8, and is reported as not fixable by the count."""
    m = parse_matrix(
        {"flaps": {"15": {"straight": 2, "turning": 2, "accelerated": 2, "asymmetric_thrust": 2}}},
        "hand.toml",
        "hand",
    )
    params = pl.DataFrame(
        {
            "coefficient": ["Cn", "Cn", "Cl"],
            "flap_deg": [15.0, 15.0, 15.0],
            "param": ["dCn_beta", "dCn_beta", "dCl_0"],
            "regressor": ["beta_deg", "beta_deg", "1"],
            "alpha_lo_deg": [8.0, 16.0, 8.0],
            "alpha_hi_deg": [16.0, 24.0, 16.0],
            "p_identified": [1.0, 0.9, 1.0],
            "band_relative": [0.1, 0.4, 1.0],
            "meets_target": [True, False, False],
        }
    )
    coverage = pl.DataFrame(
        {
            "flap_deg": [15.0] * 8,
            "kind": [k for k in KINDS for _ in range(2)],
            "alpha_lo_deg": [8.0, 16.0] * 4,
            "alpha_hi_deg": [16.0, 24.0] * 4,
            "maneuvers": [2] * 8,
            "samples_per_maneuver": [500.0, 120.0, 400.0, 300.0, 50.0, 20.0, 90.0, 100.0],
        }
    )
    effects = pl.DataFrame({"effect": ["dihedral"], "campaigns": [4], "p_named": [0.5]})
    text = recommendation(m, params, effects, coverage, 4)
    assert "flap 15: 2 parameter/alpha ranges miss a target (8 maneuvers flown)" in text
    assert "Cn dCn_beta (beta_deg), alpha 16-24 deg: band 40% of its largest expected |Δ|" in text
    assert "raise flap 15 from 8 to about 32 maneuvers (+24) for 1 of these, as turning" in text
    # only the fixable miss's range (16-24 deg) chooses the kind: turning 300 against straight 120
    assert "(300 per maneuver, against 120 for straight)" in text
    # dCl_0's band is 5x the target: 25 x 8 = 200 maneuvers, beyond 4x: not proposed as a count
    assert "1 of these need more than 4x the flap's maneuvers (up to 200 for dCl_0" in text
    assert "the diagnosis names dihedral in 50% of 4 campaigns (target 80%)" in text
    assert "dCn_beta (beta_deg), alpha 8-16" not in text


def test_compare_two_matrices_side_by_side(tiny: Path, client: Any, tmp_path: Path) -> None:
    from aerodelta.plan import compare_plans  # noqa: PLC0415

    lean = tmp_path / "lean.toml"
    lean.write_text(TINY.replace("turning = 2\naccelerated = 1", "turning = 4\naccelerated = 1"))
    a, b, table = compare_plans(
        tiny, lean, campaigns=1, seed=4, out=tmp_path / "cmp", client=client, progress=False
    )
    assert a.matrix.n_maneuvers() == 16 and b.matrix.n_maneuvers() == 18
    csv = pl.read_csv(tmp_path / "cmp" / "compare.csv")
    assert {"band_width_tiny", "band_width_lean"} <= set(csv.columns)
    assert csv.height == table.height >= max(a.params.height, b.params.height)
    row = table.filter(
        (pl.col("param") == "dCl_p") & (pl.col("flap_deg") == 0.0) & (pl.col("alpha_lo_deg") == 8.0)
    ).row(0, named=True)
    assert (
        row["band_width_tiny"]
        == a.params.filter(
            (pl.col("param") == "dCl_p")
            & (pl.col("flap_deg") == 0.0)
            & (pl.col("alpha_lo_deg") == 8.0)
        )["band_width"][0]
    )
    assert (tmp_path / "cmp" / "tiny" / "summary.json").is_file()
    assert (tmp_path / "cmp" / "lean" / "summary.json").is_file()
    # the side-by-side figure: each Cl cell is log2 of lean's band width over tiny's
    assert (tmp_path / "cmp" / "compare.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    edges = a.matrix.alpha_edges_deg
    fig = compare_figure(table, ("tiny", "lean"), a.matrix.relative_band_width, edges)
    shown = fig.axes[0].images[0].get_array()
    cl = table.filter(
        (pl.col("coefficient") == "Cl")
        & (pl.col("band_relative_tiny").is_finite() | pl.col("band_relative_lean").is_finite())
    )
    labels = sorted(set(cl.select("param", "flap_deg").iter_rows()))
    checked = 0
    for r in cl.iter_rows(named=True):
        a_w, b_w = r["band_width_tiny"], r["band_width_lean"]
        if a_w and b_w and r["alpha_lo_deg"] in edges[:-1]:
            i, j = labels.index((r["param"], r["flap_deg"])), edges.index(r["alpha_lo_deg"])
            assert shown[i, j] == pytest.approx(np.log2(b_w / a_w), rel=1e-12)
            checked += 1
    assert checked > 0


def test_rolloff_monte_carlo_in_chunks_equals_one_engine_call(client: Any, tmp_path: Path) -> None:
    out = tmp_path / "ro"
    r = run_rolloff_study(30, seed=4, out=out, chunk=8, client=client, progress=False)
    assert r.ran == [0, 8, 16, 24] and r.failures == []
    chunks = pl.read_parquet(sorted((out / "chunks").glob("chunk-*.parquet")))
    direct = monte_carlo(30, 4, threads=1)
    assert chunks.equals(direct)
    s = r.summary
    assert s["stalls"] == 30
    assert s["far25_203_pass"] == pytest.approx(float(direct["far25_203_pass"].mean()))
    bank = direct["max_bank_deg"].to_numpy()
    assert s["max_bank_deg_p95"] == pytest.approx(float(np.percentile(bank, 95)), rel=1e-12)
    first = (out / "summary.json").read_bytes()
    (out / "chunks" / "chunk-000000016.parquet").unlink()
    again = run_rolloff_study(30, seed=4, out=out, chunk=8, workers=1, progress=False)
    assert again.ran == [16]
    assert (out / "summary.json").read_bytes() == first
    with pytest.raises(DataError, match="other settings"):
        run_rolloff_study(31, seed=4, out=out, chunk=8, client=client, progress=False)


def test_suite_cases_on_the_engine_equal_the_cases_in_process_and_resume(
    client: Any, tmp_path: Path
) -> None:
    """``run_cases`` (the benchmark suites on the engine): the roll-off Monte Carlo's seeded
    chunks give the same frames on the workers as in this process, in case order; a rerun
    reads the saved cases back; a case that raises is retried, reported and its slot empty."""
    settings = {
        "seed": 4, "flap_deg": 0.0, "turbulence_mps": 0.5, "excitation": 1.0, "config": None,
    }  # fmt: skip
    cases = [(settings, first, 5) for first in (0, 5, 10)]
    local = run_cases(mc_chunk, cases, workers=0, progress=False)
    folder = tmp_path / "cases"
    engine = run_cases(mc_chunk, cases, client=client, resume=folder, progress=False, name="mc")
    assert engine.failures == [] and engine.resumed == 0
    for a, b in zip(local.results, engine.results, strict=True):
        assert a.equals(b)
    assert pl.concat(engine.results).equals(monte_carlo(15, 4, threads=1))
    assert len(list(folder.glob("mc-*.pkl"))) == 3
    again = run_cases(mc_chunk, cases, client=client, resume=folder, progress=False, name="mc")
    assert again.resumed == 3
    assert all(a.equals(b) for a, b in zip(again.results, engine.results, strict=True))
    # a case that raises: reported with its label after the retries, the others kept
    bad = run_cases(
        operator.truediv, [(1.0, 4.0), (1.0, 0.0)], labels=["quarter", "by zero"],
        client=client, retries=1, progress=False,
    )  # fmt: skip
    assert bad.results == [0.25, None]
    assert [(f.label, f.error.split(":")[0]) for f in bad.failures] == [
        ("by zero", "ZeroDivisionError")
    ]
    with pytest.raises(InvalidInputError, match="--workers -1"):
        run_cases(operator.truediv, [(1.0, 2.0)], workers=-1)
