"""The evidence pack's HTML page: the matrix, the envelope plots, the figures with their data,
a draft Statement of Compliance and the provenance. No script, nothing fetched from the
network; figures are PNG files beside the page; the CSS prints on A4 (one column, figures
kept whole, the navigation bar left out)."""

from __future__ import annotations

import datetime as _dt
from collections.abc import Mapping, Sequence
from typing import Any

import polars as pl

from aerodelta.evidence.matrix import FAIL, NOT_ASSESSED, PASS, SHOWN, Assessment, MatrixRow
from aerodelta.report.html import BASE_CSS, esc, table

#: The placeholder the sponsor replaces in the Statement of Compliance.
TODO = "[to be completed by the sponsor]"

_CSS = (
    BASE_CSS
    + "th,td{border:1px solid #d0d7de;padding:3px 8px;text-align:right;vertical-align:top}\n"
    + """th{background:#f0f3f6} td:first-child,th:first-child{text-align:left}
table.matrix td,table.matrix th{text-align:left} table.matrix td.detail{font-size:11.5px;color:#444}
td.status{font-weight:600;white-space:nowrap}
td.pass{background:#e8f5e9;color:#1b5e20} td.fail{background:#fdecea;color:#b42318}
td.shown{background:#e8f0fb;color:#1f3b57} td.na{background:#f4f4f4;color:#555;white-space:normal;
font-weight:400;font-size:11.5px;min-width:150px}
figure{margin:14px 0} figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:12.5px;color:#555;margin-top:3px}
.note{color:#666;font-size:12.5px}
.todo{background:#fff3cd;padding:0 3px;border-radius:2px;font-weight:600}
.soc p,.soc li{max-width:900px}
code{font-size:12px;background:#f3f3f3;padding:0 3px}
@media print{
 @page{size:A4;margin:14mm}
 body{background:#fff;font-size:11px}
 nav{display:none} header{background:#fff;color:#000;border-bottom:2px solid #000;padding:0 0 6px}
 main{max-width:none;padding:0} section{border:none;padding:0;margin:0 0 10px}
 #envelope-plots,#figures,#soc,#provenance{break-before:page}
 figure,tr{break-inside:avoid} h2,h3{break-after:avoid}
 a{color:inherit;text-decoration:none}
 .todo{border:1px solid #000}
}
"""
)


def status_class(status: str) -> str:
    """CSS class of a status cell: ``pass``, ``fail``, ``shown`` or ``na``."""
    return {PASS: "pass", FAIL: "fail", SHOWN: "shown"}.get(status, "na")


def _status_html(status: str) -> str:
    """A status cell: the verdict in bold, a not-assessed reason in plain text after it."""
    if status.startswith(NOT_ASSESSED):
        return f"<b>{esc(NOT_ASSESSED.rstrip())}</b> {esc(status[len(NOT_ASSESSED) :])}"
    return esc(status)


def _matrix(rows: Sequence[MatrixRow], numbers: Mapping[str, int]) -> str:
    head = (
        "<tr><th>#</th><th>Characteristic</th><th>Rule (as we read it)</th><th>Data used</th>"
        "<th>Figure</th><th>Tolerance</th><th>Status</th></tr>"
    )
    body = []
    for i, r in enumerate(rows, start=1):
        fig = (
            f'<a href="#{esc(r.figure)}">Figure {numbers[r.figure]}</a>'
            if r.figure is not None
            else "none"
        )
        detail = f'<br><span class="note">{esc(r.detail)}</span>' if r.detail else ""
        body.append(
            f'<tr id="row-{esc(r.key)}" data-status="{esc(status_class(r.status))}">'
            f"<td>{i}</td><td><b>{esc(r.item)}</b>{detail}</td><td>{esc(r.rule)}</td>"
            f"<td>{esc(r.data)}</td><td>{fig}</td><td>{esc(r.tolerance)}</td>"
            f'<td class="status {status_class(r.status)}">{_status_html(r.status)}</td></tr>'
        )
    return f'<table class="matrix"><thead>{head}</thead><tbody>{"".join(body)}</tbody></table>'


def _figure(anchor: str, number: int, src: str, caption: str, size: tuple[int, int]) -> str:
    return (
        f'<figure id="{esc(anchor)}"><img src="{esc(src)}" alt="{esc(caption)}" '
        f'width="{size[0]}" height="{size[1]}"><figcaption><b>Figure {number}.</b> '
        f"{esc(caption)}</figcaption></figure>"
    )


#: Tables shown under each figure (key of :attr:`Assessment.tables`, columns, heading).
_FIGURE_TABLES: dict[str, list[tuple[str, Sequence[str] | None, str]]] = {
    "fig-stall-alpha": [("stall_summary", None, "Per flap and maneuver kind")],
    "fig-speeds": [
        (
            "stall",
            (
                "maneuver_id",
                "flap_deg",
                "kind",
                "stall_id_by",
                "stall_id_alpha_deg",
                "v_warning_keas",
                "v_buffet_onset_keas",
                "v_stall_keas",
                "v_min_keas",
            ),
            "Per maneuver (speeds KEAS, kt; alpha deg)",
        ),
        ("closed_loop_summary", None, "Closed-loop replays: simulator minus flight test per flap"),
        (
            "closed_loop",
            (
                "maneuver_id",
                "sim_stall_id_by",
                "recognised_by",
                "v_warning_diff_kt",
                "v_warning_status",
                "v_buffet_onset_diff_kt",
                "v_buffet_onset_status",
                "v_stall_diff_kt",
                "v_stall_status",
                "outside_envelope_s",
            ),
            "Closed-loop replays per maneuver (simulator minus flight test, kt; time outside "
            "the validated envelope, s)",
        ),
    ],
    "fig-rolloff": [("rolloff", None, "Wings-level stalls: bank change after identification")],
    "fig-buffet-spectra": [
        ("buffet_frequencies", None, "Identified predominant frequencies"),
        ("buffet_comparison", None, "Simulator against flight test (compare_frequencies)"),
    ],
    "fig-buffet-amplitude": [("buffet_per_flap", None, "Buffet onset per flap")],
    "fig-validity": [("validity", None, "Validity range per flap (validity_range)")],
    "fig-envelope": [
        ("envelope_counts", None, "Maneuvers and samples per flap and kind"),
        ("envelope_inside", None, "Share of samples inside the model's validated envelope"),
    ],
    "fig-longitudinal": [("kirchhoff", None, "Kirchhoff parameters per flap (engine units)")],
    "fig-prestall": [("prestall", None, "Pre-stall regression per maneuver")],
}


def _figure_block(
    out: Assessment, anchor: str, number: int, *, src: str, caption: str, size: tuple[int, int]
) -> str:
    parts = [_figure(anchor, number, src, caption, size)]
    for key, cols, title in _FIGURE_TABLES.get(anchor, []):
        t = out.tables.get(key)
        if t is None or t.height == 0:
            continue
        if cols is not None:
            t = t.select([c for c in cols if c in t.columns])
        parts.append(
            f"<details><summary>{esc(title)} ({t.height} rows)</summary>"
            f"{table(t, formats={c: '.4g' for c in t.columns})}</details>"
        )
    return "".join(parts)


def _soc(out: Assessment, rows: Sequence[MatrixRow], info: Mapping[str, Any]) -> str:
    f = out.facts
    todo = f'<span class="todo">{esc(TODO)}</span>'
    by = ", ".join(f"{k.replace('_', ' ')} {v}" for k, v in f.get("by", {}).items()) or "none"
    kinds = ", ".join(f"{v} {k}" for k, v in f.get("kinds", {}).items())
    status = {r.key: r.status for r in rows}
    ent = f.get("entries", {})
    model = info.get("model")
    model_text = (
        f"the fitted Δ model <code>{esc(model)}</code> (SHA-256 "
        f"<code>{esc(info.get('model_sha256', ''))}</code>)"
        if model
        else f"no fitted Δ model was given to this pack ({todo}: the model file)"
    )
    val_lines = "".join(f"<li>{esc(v)}</li>" for v in f.get("validity_lines", []))
    mach = f.get("mach") or {}
    mach_text = (
        "Mach "
        + ", ".join(f"{lo:.3f}-{hi:.3f} at flap {fl:g}" for fl, (lo, hi) in sorted(mach.items()))
        + " at stall identification"
        if mach
        else "no identified stall, so no Mach range"
    )
    items = [
        f"<p><b>Sponsor:</b> {todo}. <b>FSTD</b> (identification, qualification level, "
        f"manufacturer): {todo}. <b>Aircraft type and configuration data source:</b> {todo}.</p>",
        "<p>This statement declares that the FSTD's aerodynamic model for full-stall training "
        "meets 14 CFR Part 60 Appendix A, Attachment 7 (FSTD Directive 2) as the sponsor reads "
        f"it; the facts below are taken from the flight-test data of this pack ({esc(info['data'])}"
        ") by aerodelta; every statement marked " + todo + " is the sponsor's.</p>",
        "<ol>",
        f"<li><b>Stall identification.</b> {f['n_maneuvers']} flight-test maneuvers ({esc(kinds)})"
        f" at flap settings {esc(', '.join(f'{x:g}' for x in f['flaps']))} deg were analysed; "
        f"{f['n_identified']} stalls were identified by the first of the Attachment 7 criteria "
        f"({esc(by)}); per flap in matrix row 1. The stall-identification angle of attack the "
        f"FSTD uses per configuration: {todo}.</li>",
        f"<li><b>Validity range</b> (matrix status: {esc(status.get('validity', ''))}):"
        f"<ul>{val_lines}</ul>The model's declared alpha and beta range per configuration, and "
        f"the data behind it where the flight data do not reach (wind tunnel, analysis): {todo}"
        ".</li>",
        f"<li><b>Model coverage.</b> The post-stall model is {model_text}. Degraded "
        f"lateral-directional stability: {esc(status.get('lateral', ''))}; roll-off: "
        f"{esc(status.get('rolloff', ''))}; g-break and pitch break: "
        f"{esc(status.get('breaks', ''))}; longitudinal stall: "
        f"{esc(status.get('longitudinal', ''))}; stall buffet: "
        f"{esc(status.get('buffet_onset', ''))}. The stall data cover {esc(mach_text)} "
        "(matrix row Mach effects; the Δ model has no Mach dependence). How the FSTD implements "
        f"each (and Mach effects beyond that range, where applicable): {todo}.</li>",
        "<li><b>Objective stall tests.</b> The flight-test stall-warning, buffet-onset and stall "
        "speeds are in the pack (matrix rows 2-4) with aerodelta's closed-loop replays of the "
        "stall maneuvers with the extended model against ±3 kt: stall warning "
        f"{esc(status.get('v_warning', ''))}; buffet onset "
        f"{esc(status.get('v_buffet_onset', ''))}; stall {esc(status.get('v_stall', ''))}. "
        f"The FSTD's own QTG test references and results: {todo}. Entries flown: "
        f"{ent.get('wings_level', 0)} wings-level, {ent.get('turning', 0)} turning, "
        f"{ent.get('power_on', 0)} power-on identified stalls (status "
        f"{esc(status.get('entries', ''))}).</li>",
        "<li><b>Stall buffet spectra.</b> Predominant frequencies within ±2 Hz: "
        f"{esc(status.get('buffet_freq', ''))}. The FSTD's buffet model and its test: {todo}."
        "</li>",
        "<li><b>Pre-stall regression.</b> The extended model against the qualified model where "
        "the Δ is blended out (the qualified model's validation tests unchanged): "
        f"{esc(status.get('prestall', ''))}. The FSTD's pre-stall QTG results rerun with the "
        f"stall model installed: {todo}.</li>",
        "<li><b>Validated envelope.</b> The α/β envelope of the flight-test points is plotted per "
        "flap and maneuver kind (section 2). The FSTD shows the instructor when the flight "
        f"leaves the validated envelope by: {todo}.</li>",
        f"<li><b>Subject-matter-expert pilot evaluation</b> of the stall characteristics: {todo}"
        ".</li>",
        "</ol>",
        f"<p><b>Name, title, signature and date:</b> {todo}.</p>",
    ]
    return '<div class="soc">' + "".join(items) + "</div>"


def _provenance(info: Mapping[str, Any]) -> str:
    lines = [
        ("aerodelta", info["version"]),
        ("Python / numpy / polars", info["runtime"]),
        ("command", info["command"]),
        ("data", info["data"]),
        ("data SHA-256", info["data_sha256"]),
        ("model", info.get("model") or "none"),
        ("model SHA-256", info.get("model_sha256") or "-"),
        ("options", info["options"]),
        ("generated", info["generated"]),
    ]
    body = "".join(f"<tr><th>{esc(k)}</th><td>{esc(v)}</td></tr>" for k, v in lines)
    files: pl.DataFrame | None = info.get("files")
    extra = ""
    if files is not None and files.height:
        extra = (
            f"<details><summary>Input files ({files.height}); the data SHA-256 is that of the "
            "list below, one 'sha256  path' line per file, sorted by path</summary>"
            f"{table(files)}</details>"
        )
    return f"<table>{body}</table>{extra}"


def render_page(
    out: Assessment,
    figure_files: Mapping[str, tuple[str, tuple[int, int]]],
    info: Mapping[str, Any],
    generated: _dt.datetime,
) -> str:
    """The whole page: ``figure_files`` maps each figure anchor to its relative PNG path and
    pixel size; ``info`` carries the provenance (version, command, data and its hash, ...)."""
    numbers = {spec.anchor: i for i, spec in enumerate(out.figures, start=1)}
    counts = {s: sum(1 for r in out.rows if status_class(r.status) == s)
              for s in ("pass", "fail", "shown", "na")}  # fmt: skip
    legend = (
        f"<p>{len(out.rows)} characteristics: {counts['pass']} {PASS}, {counts['fail']} {FAIL}, "
        f"{counts['shown']} {SHOWN}, {counts['na']} {esc(NOT_ASSESSED.rstrip(': '))}. "
        f"<b>{PASS}/{FAIL}</b>: a tolerance checked from the data; <b>{SHOWN}</b>: the rule asks "
        "to show it; <b>not assessed</b>: the reason is given (no number is invented). Rules as "
        "we read them (docs/stall.md, docs/evidence.md); alphas at the CG, speeds EAS.</p>"
    )
    env_anchor = "fig-envelope"
    spec_by = {s.anchor: s for s in out.figures}
    envelope = ""
    if env_anchor in figure_files:
        src, size = figure_files[env_anchor]
        envelope = _figure_block(
            out,
            env_anchor,
            numbers[env_anchor],
            src=src,
            caption=spec_by[env_anchor].caption,
            size=size,
        )
    blocks = []
    for s in out.figures:
        if s.anchor == env_anchor or s.anchor not in figure_files:
            continue
        src, size = figure_files[s.anchor]
        item = next((r.item for r in out.rows if r.figure == s.anchor), s.name)
        blocks.append(
            f"<h3>{esc(item)}</h3>"
            + _figure_block(out, s.anchor, numbers[s.anchor], src=src, caption=s.caption, size=size)
        )
    others = "".join(blocks)
    stamp = generated.strftime("%Y-%m-%d %H:%M UTC")
    sections = [
        (
            "matrix",
            "1. Characteristic-by-characteristic matrix",
            legend + _matrix(out.rows, numbers),
        ),
        ("envelope-plots", "2. Envelope plots", envelope or '<p class="note">No samples.</p>'),
        ("figures", "3. Figures and data", others),
        ("soc", "4. Statement of Compliance (draft)", _soc(out, out.rows, info)),
        ("provenance", "5. Provenance", _provenance(info)),
    ]
    nav = "".join(f'<a href="#{k}">{esc(t)}</a>' for k, t, _ in sections)
    body = "".join(f'<section id="{k}"><h2>{esc(t)}</h2>{b}</section>' for k, t, b in sections)
    title = "Part 60 stall-model evidence pack"
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        '<meta name="viewport" content="width=device-width, initial-scale=1">'
        f"<title>{esc(title)}</title><style>{_CSS}</style></head><body>"
        f"<header><h1>{esc(title)}</h1><p>{esc(info['data'])} · aerodelta {esc(info['version'])}"
        f" · generated {stamp}</p></header><nav>{nav}</nav><main>{body}</main></body></html>\n"
    )
