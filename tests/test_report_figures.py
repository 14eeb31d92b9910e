"""Report figures: drawn in worker processes they are the same bytes as drawn in the caller
(PNG, SVG without a date and with fixed ids, the HTML fragment, the file order); a failing or
dead worker leaves the figure to the caller; the workers load neither polars nor the engine;
titles clear an offset text; the batched effect derivatives equal one-at-a-time evaluations;
SOURCE_DATE_EPOCH fixes the report's stamp."""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg

import _figure_probe
from _report_data import diagnosis_fixture, quick_fit, quick_report
from aerodelta.exceptions import InvalidInputError
from aerodelta.plots import FigureSink, draw_and_render, figures, render, style
from aerodelta.report import POOL_MIN_SAMPLES, build_report, default_workers
from aerodelta.report.context import ReportContext
from aerodelta.report.effects import derivative, derivatives
from aerodelta.report.html import generated_at, page


def _jobs() -> list[tuple[Any, str, dict[str, Any]]]:
    rng = np.random.default_rng(11)
    t = np.linspace(0.0, 40.0, 20_000)
    meas = 0.01 * np.sin(t) + 0.001 * rng.standard_normal(t.size)
    a_edges = np.arange(-6.0, 25.0)
    b_edges = np.arange(-15.0, 16.0)
    level = rng.integers(0, 4, size=(a_edges.size - 1, b_edges.size - 1))
    x = rng.standard_normal(1500)
    return [
        (
            figures.time_history,
            "th",
            {
                "t": t,
                "meas": meas,
                "qual": 0.9 * meas,
                "ext": 1.05 * meas,
                "alpha": 10 + 8 * np.sin(t / 7),
                "active": np.sin(t / 7) > 0.5,
                "ylabel": "$C_l$",
                "title": "a maneuver\nsecond line",
            },
        ),
        (
            figures.envelope,
            "envelope",
            {
                "panels": [
                    {
                        "flap": f,
                        "a_edges": a_edges,
                        "b_edges": b_edges,
                        "level": level,
                        "stall": 17.5,
                    }
                    for f in (0.0, 10.0)
                ],
                "levels": ["none", "low", "moderate", "high"],
            },
        ),
        (
            figures.error_vs_regressor,
            "scatter",
            {
                "rows": [
                    {
                        "ylabel": "Cl error",
                        "panels": [
                            {
                                "xlabel": "beta_deg",
                                "x": x,
                                "z": 0.002 * x + 1e-4 * x**2,
                                "fit": (np.array([-3.0, 3.0]), np.array([-0.006, 0.006]), "s"),
                            },
                            {"xlabel": "phat", "x": -x, "z": x, "fit": None},
                        ],
                    }
                ]
            },
        ),
        (
            figures.shrink,
            "shrink",
            {
                "panels": [
                    {
                        "coef": "Cl",
                        "y": np.array([3.0, 2.0, 1.5]),
                        "labels": ["qualified", "aileron_reversal", "time_skew"],
                    }
                ]
            },
        ),
    ]


def _draw_all(sink: FigureSink) -> list[str]:
    out = [sink.plot(draw, name, f"caption {name}", **kw) for draw, name, kw in _jobs()]
    sink.finish()
    return [sink.fill(h) for h in out]


def test_workers_draw_the_same_bytes_as_the_caller(tmp_path: Path) -> None:
    with FigureSink(tmp_path / "here", workers=0) as here:
        html_here = _draw_all(here)
    with FigureSink(tmp_path / "pool", workers=2) as pool:
        assert pool._pool is not None  # the workers started
        html_pool = _draw_all(pool)
    assert html_pool == html_here
    names = [p.name for p in here.written]
    assert names == [p.name for p in pool.written]
    assert names[:4] == ["001_th.png", "001_th.svg", "002_envelope.png", "002_envelope.svg"]
    for a, b in zip(here.written, pool.written, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name
    svg = (tmp_path / "pool" / "002_envelope.svg").read_bytes()
    assert b"<svg" in svg[:2000]
    assert b"dc:date" not in svg  # no clock in the bytes
    # the envelope's cells are one image, drawn unsmoothed, not a path per cell
    assert svg.count(b"<image") == 2 and b"image-rendering:pixelated" in svg
    # the point cloud is rasterized inside the SVG, the fitted line stays a vector path
    scatter = (tmp_path / "pool" / "003_scatter.svg").read_bytes()
    assert scatter.count(b"<image") == 2
    assert b"bin slope" not in scatter  # no legend label: the fit was labelled "s"


def test_a_figure_drawn_twice_here_is_the_same_bytes() -> None:
    draw, _, kw = _jobs()[0]
    assert draw_and_render(draw, kw, dpi=60, svg=True) == draw_and_render(
        draw, kw, dpi=60, svg=True
    )


def test_a_failing_draw_raises_in_the_caller() -> None:
    with FigureSink(None, workers=1) as sink:
        token = sink.plot(_figure_probe.failing, "bad", "bad", message="probe failure 17")
        with pytest.raises(ValueError, match="probe failure 17"):
            sink.fill(token)


def test_a_dead_worker_leaves_its_figures_to_the_caller(tmp_path: Path) -> None:
    draw, name, kw = _jobs()[3]
    with FigureSink(tmp_path / "here") as here:
        expected = here.plot(draw, name, "c", **kw)
    with FigureSink(tmp_path / "dead", workers=1) as sink:
        assert sink._pool is not None
        sink._pool._proc.kill()
        sink._pool._proc.wait()
        got = [sink.fill(sink.plot(draw, name, "c", **kw)) for _ in range(2)]
    assert got[0] == expected
    assert (tmp_path / "dead" / "001_shrink.svg").read_bytes() == here.written[1].read_bytes()


def test_workers_load_neither_polars_nor_the_engine(tmp_path: Path) -> None:
    with FigureSink(tmp_path, workers=1) as sink:
        sink.fill(sink.plot(_figure_probe.modules, "probe", "probe"))
    svg = (tmp_path / "001_probe.svg").read_text(encoding="utf-8")
    assert "loaded: none" in svg
    # this process has them: the probe would name them if drawn here
    here = draw_and_render(_figure_probe.modules, {}, dpi=50, svg=True)[1]
    assert here is not None and b"loaded: polars" in here


def test_default_workers_follow_the_cpus_and_the_record_count(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0, 1}, raising=False)
    assert default_workers(POOL_MIN_SAMPLES) == 2
    assert default_workers(POOL_MIN_SAMPLES - 1) == 0
    monkeypatch.setattr(os, "sched_getaffinity", lambda _pid: {0}, raising=False)
    assert default_workers(100 * POOL_MIN_SAMPLES) == 0


def test_report_drawn_here_matches_the_report_drawn_in_workers(tmp_path: Path) -> None:
    pooled = quick_report()  # the default: the quick campaign is drawn in two workers
    root, data, _, held = quick_fit()
    assert data.height >= POOL_MIN_SAMPLES
    here = build_report(
        root / "model.json",
        data,
        tmp_path,
        held_out=held,
        diagnosis_doc=diagnosis_fixture(),
        replay_count=2,
        workers=0,
    )
    assert [p.name for p in here.figures] == [p.name for p in pooled.figures]
    for a, b in zip(here.figures, pooled.figures, strict=True):
        assert a.read_bytes() == b.read_bytes(), a.name

    def unstamped(p: Path) -> str:
        return re.sub(r"generated \d{4}-\d\d-\d\d \d\d:\d\d UTC", "", p.read_text("utf-8"))

    assert unstamped(here.html) == unstamped(pooled.html)


def test_titles_clear_an_offset_text_and_sit_on_the_axes_otherwise() -> None:
    c = np.array([2.0, 6.0, 10.0])

    def series(scale: float) -> dict[str, Any]:
        return {"flap": 0.0, "c": c, "est": scale * (1 + c), "half": scale * np.ones(3),
                "c_bad": np.array([]), "table": None}  # fmt: skip

    panels = [
        {"title": "dCl_tiny  [a rather long regressor * name]", "series": [series(3e-6)]},
        {"title": "dCl_plain  [a rather long regressor * name]", "series": [series(1.0)]},
    ]
    with style():
        fig = figures.parameters(panels=panels, flaps=[0.0])
        render(fig, dpi=50, svg=False)
    tiny, plain = fig.axes[0], fig.axes[1]
    assert tiny.yaxis.offsetText.get_text()  # the exponent sits above the axes ...
    assert tiny.title.get_position()[1] > 1.0  # ... and the title moved above it
    r = FigureCanvasAgg(fig).get_renderer()
    off, title = tiny.yaxis.offsetText.get_window_extent(r), tiny.title.get_window_extent(r)
    assert title.y0 >= off.y1 - 1e-6
    assert not plain.yaxis.offsetText.get_text()
    assert plain.title.get_position()[1] == 1.0


def test_effect_derivatives_in_one_batch_equal_one_at_a_time() -> None:
    _, data, res, _ = quick_fit()
    ctx = ReportContext(
        model=res.model, data=data.head(0), params=None, coefficients=["Cl", "Cn", "CY"],
        held_out=[], qualified="adx37",
    )  # fmt: skip
    alpha = np.linspace(-2.0, 30.0, 33)
    specs = [
        ("Cl", "beta_deg", 1.0, 0.0, alpha),
        ("Cn", "dr_deg", 5.0, 10.0, alpha[::2]),
        ("CY", "beta_deg", 1.0, 35.0, alpha),
        ("Cl", "phat", 0.01, 10.0, alpha[:5]),
    ]
    batch = derivatives(ctx, specs)
    for (coef, ch, h, flap, a), (dq, dd) in zip(specs, batch, strict=True):
        q1, d1 = derivative(ctx, coef, ch, h, flap=flap, alpha=a)
        assert dq is not None and q1 is not None
        np.testing.assert_array_equal(dq, q1)
        np.testing.assert_array_equal(dd, d1)
        assert dd.shape == a.shape and np.isfinite(dd).all()


def test_source_date_epoch_fixes_the_stamp(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1700000000")
    assert "generated 2023-11-14 22:13 UTC" in page("t", "s", "", [])
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "soon")
    with pytest.raises(InvalidInputError, match="SOURCE_DATE_EPOCH='soon'"):
        generated_at()


def _wide_jobs() -> list[tuple[Any, dict[str, Any]]]:
    """Figures with long tick labels (-0.00025), an offset text and two-line titles."""
    t = np.linspace(0.0, 30.0, 500)
    tiny = -2.5e-4 + 2e-4 * np.sin(t)
    offset = 1000.0 + 1e-3 * np.sin(t)  # an axis with an offset (+1e3) above it
    panel = {"flap": 0.0, "alpha": t, "dq": tiny, "ext": tiny * 1.1, "stall": 15.0, "bins": None}
    return [
        (
            figures.time_history,
            {
                "t": t,
                "meas": tiny,
                "qual": tiny,
                "ext": tiny,
                "alpha": offset,
                "active": None,
                "ylabel": "$C_l$",
                "title": "first line\nsecond line",
            },
        ),
        (
            figures.effect,
            {"panels": [panel, panel, panel], "ylabel": "Cl_beta [1/deg]", "ext_label": "extended"},
        ),
        (
            figures.replay,
            {
                "panels": [
                    {
                        "title": f"s{k}",
                        "t": t,
                        "y": offset if k else tiny,
                        "runs": [(t, tiny, "#d62728", "replay")],
                    }
                    for k in range(4)
                ]
            },
        ),
        (
            figures.tic_scatter,
            {
                "panels": [
                    {"coef": c, "fitted": (t, tiny), "held": None, "hi": 30.0} for c in ("Cl", "Cn")
                ]
            },
        ),
        (
            figures.error_vs_regressor,
            {
                "rows": [
                    {
                        "ylabel": f"row {i}",
                        "panels": [
                            {"xlabel": "x", "x": offset, "z": tiny, "fit": None},
                            {"xlabel": "y", "x": t, "z": offset, "fit": None},
                        ],
                    }
                    for i in range(2)
                ]
            },
        ),
        (
            figures.rolloff_drc_maxroll,
            {
                "drc": [{"x": 40 * np.sin(t), "y": 20 * np.cos(t)}] * 2,
                "max_roll": [
                    {"x": np.zeros(3) + k, "y": np.array([5.0, 25.0, 60.0])} for k in range(2)
                ],
                "flaps": [0.0, 35.0],
                "limit_deg": 20.0,
            },
        ),
        (
            figures.shrink,
            {
                "panels": [
                    {
                        "coef": c,
                        "y": np.array([3e-4, 2e-4, 1.5e-4]),
                        "labels": ["qualified", "a_rather_long_effect_name", "time_skew"],
                    }
                    for c in ("Cl", "Cn", "CY (long)")
                ]
            },
        ),
    ]


@pytest.mark.parametrize("job", range(7))
def test_panels_of_the_fixed_layout_fit_the_figure_and_clear_each_other(job: int) -> None:
    # the reference is matplotlib's own measure of everything drawn around each panel
    draw, kw = _wide_jobs()[job]
    with style():
        fig = draw(**kw)
        render(fig, dpi=110, svg=False)
        canvas = FigureCanvasAgg(fig)
        canvas.draw()
        r = canvas.get_renderer()
        boxes = [a.get_tightbbox(r) for a in fig.axes if a.get_visible()]
    page_box = fig.bbox
    for b in boxes:
        assert b.x0 >= page_box.x0 - 1 and b.y0 >= page_box.y0 - 1, (b, page_box)
        assert b.x1 <= page_box.x1 + 1 and b.y1 <= page_box.y1 + 1, (b, page_box)
    for k, a in enumerate(boxes):
        for b in boxes[k + 1 :]:
            w = min(a.x1, b.x1) - max(a.x0, b.x0)
            h = min(a.y1, b.y1) - max(a.y0, b.y0)
            assert w <= 1 or h <= 1, (a, b)
