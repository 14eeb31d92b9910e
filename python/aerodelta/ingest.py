"""Public ingestion API: read, map, validate and preprocess a campaign of flight test records.

>>> # result = aerodelta.ingest("campaign/", aircraft="campaign/aircraft.toml")
>>> # result.data.filter(pl.col("alpha_cg_deg") > 12)
"""

from __future__ import annotations

import json
import re
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import polars as pl
import polars.selectors as cs
from tqdm import tqdm

from aerodelta import _core
from aerodelta._fsutil import write_atomic
from aerodelta._threads import engine_threads
from aerodelta.aircraft import BUILTIN_COLUMN, BUILTINS, Aircraft
from aerodelta.channel_map import ChannelMap
from aerodelta.channels import ALTERNATIVES, CHANNELS, REQUIRED
from aerodelta.exceptions import DataError
from aerodelta.loading import cg_warnings, loading_array, manifest_loadings
from aerodelta.plausibility import check_plausibility
from aerodelta.preprocess import preprocess_frame
from aerodelta.readers import RecordSource, find_records, read_manifest, scan_record
from aerodelta.validate import (
    Finding,
    ValidationReport,
    az_medians,
    screen_many,
    unit_checks_only,
    validate,
)

#: Practical thresholds above which an estimated bias is reported as a warning (and more than
#: four standard errors from zero): SI units and radians.
COMPAT_THRESHOLDS = {
    "b_ax_mps2": 0.05,
    "b_ay_mps2": 0.05,
    "b_az_mps2": 0.05,
    "b_p_rps": 0.2 * np.pi / 180,
    "b_q_rps": 0.2 * np.pi / 180,
    "b_r_rps": 0.2 * np.pi / 180,
    "b_alpha_rad": 0.3 * np.pi / 180,
    "b_beta_rad": 0.3 * np.pi / 180,
    "lambda_v": 0.02,
    "k_alpha": 0.02,
    "k_beta": 0.02,
}


@dataclass
class IngestResult:
    """What :func:`ingest` returns.

    Attributes
    ----------
    data : polars.DataFrame
        All maneuvers, canonical channels plus the derived columns, and ``maneuver_id``,
        ``flap_deg``, ``kind``, ``pusher`` from the manifest.
    reports : list[ValidationReport]
        One per maneuver (all findings, including compatibility warnings).
    compat : polars.DataFrame or None
        Data compatibility estimates: ``maneuver_id, parameter, estimate, std_err, applied``.
    smoothing : polars.DataFrame
        Smoother cut-off (Hz) and noise standard deviation per maneuver and channel.
    plausibility : polars.DataFrame or None
        Kinematic scale of each checked channel over the campaign (``check, channel, k,
        std_err, blocks, verdict``); None when the check was off.
    """

    data: pl.DataFrame
    reports: list[ValidationReport]
    compat: pl.DataFrame | None = None
    smoothing: pl.DataFrame = field(default_factory=pl.DataFrame)
    plausibility: pl.DataFrame | None = None

    def report_frame(self) -> pl.DataFrame:
        """Every finding of every maneuver as one frame."""
        frames = [r.to_frame() for r in self.reports]
        return pl.concat(frames) if frames else ValidationReport("", "").to_frame()

    def write(self, out_dir: str | Path) -> list[Path]:
        """Write ``data.parquet``, ``validation.json``, ``smoothing.csv`` and ``compat.csv``
        atomically (temporary file in the same folder, then rename). Returns the paths."""
        out = Path(out_dir)
        out.mkdir(parents=True, exist_ok=True)
        written = []

        def atomic(name: str, write: Callable[[Path], object]) -> None:
            written.append(write_atomic(out / name, write))

        atomic("data.parquet", self.data.write_parquet)
        payload = [json.loads(r.to_json()) for r in self.reports]
        atomic("validation.json", lambda p: p.write_text(json.dumps(payload, indent=2)))
        atomic("smoothing.csv", self.smoothing.write_csv)
        if self.compat is not None:
            atomic("compat.csv", self.compat.write_csv)  # type: ignore[union-attr]
        return written


def _load_aircraft(aircraft: Aircraft | str | Path | None, data: object) -> Aircraft:
    if isinstance(aircraft, Aircraft):
        return aircraft
    if aircraft is not None:
        return Aircraft.from_toml(aircraft)
    if isinstance(data, (str, Path)) and (Path(data) / "aircraft.toml").is_file():
        return Aircraft.from_toml(Path(data) / "aircraft.toml")
    raise DataError("no aircraft reference: pass aircraft=PATH (TOML) or put aircraft.toml in DIR")


def ingest(  # noqa: PLR0917
    data: str | Path | Sequence[str | Path],
    aircraft: Aircraft | str | Path | None = None,
    channel_map: ChannelMap | str | Path | None = None,
    manifest: pl.DataFrame | str | Path | None = None,
    allow_interpolation: bool = False,
    compat: bool = True,
    apply_compat: bool = False,
    smooth: bool = True,
    progress: bool = True,
    plausibility: bool = True,
    vane_scale: bool = False,
    compat_method: str = "auto",
) -> IngestResult:
    """Read, map, validate and preprocess flight test records.

    Parameters
    ----------
    data : path or list of paths
        A campaign folder (``manifest.csv``, ``aircraft.toml``, ``records/``), one record file,
        or a list of record files (CSV, Parquet, MATLAB ``.mat``).
    aircraft : Aircraft, path or None
        Aircraft reference; default ``DIR/aircraft.toml``.
    channel_map : ChannelMap, path or None
        How the user's columns map onto the canonical schema; None: already canonical.
    manifest : DataFrame, path or None
        Maneuver metadata; default ``DIR/manifest.csv`` when present. Its loading columns
        (``mass_kg``, ``Ixx_kgm2`` ... ``Iyz_kgm2``, ``cg_x_m``, ``cg_y_m``, ``cg_z_m``:
        :mod:`aerodelta.loading`) give each maneuver its own mass properties.
    allow_interpolation : bool
        Fill short NaN dropouts (warned) instead of refusing them.
    compat : bool
        Run the data compatibility check (thesis Section 2.4) on every maneuver.
    apply_compat : bool
        Remove the estimated biases and airspeed scale factor from the channels and preprocess
        again (needs ``compat``).
    vane_scale : bool
        Also estimate the alpha and beta vanes' scale factors (upwash, sidewash:
        ``alpha_measured = (1 + k_alpha) alpha + b_alpha``) in the compatibility check (needs
        ``compat``). They separate from the biases only where the angle varies within a
        maneuver, and gusts scatter their per-maneuver estimates: the campaign median is
        reported (a sensor's scale is the same in every maneuver).
    compat_method : str
        How the compatibility check reconstructs the flight path: ``"output-error"`` (steady
        air), ``"innovations"`` (the one-step predictor with estimated gains, for turbulence:
        gusts no longer bias the vane scale factors; about 3x the time) or ``"auto"`` (the
        innovations form when ``vane_scale`` is set, else output error). See docs/data.md.
    smooth : bool
        Smooth before differentiating (recommended; off only for exact synthetic data).
    progress : bool
        tqdm progress bar on stderr.
    plausibility : bool
        Refuse units and signs that kinematic consistency contradicts (radians declared as
        degrees, knots as m/s, ft as m, g as m/s², an axis of the other sign), pooled over the
        campaign (:mod:`aerodelta.plausibility`).

    Returns
    -------
    IngestResult

    Raises
    ------
    DataError
        Every refused finding of every maneuver at once (file, channel and rows named).
    """
    if vane_scale and not (compat or apply_compat):
        raise DataError("vane_scale=True needs the compatibility check: drop compat=False")
    if compat_method not in COMPAT_METHODS:
        raise DataError(
            f"compat_method={compat_method!r}: give one of {', '.join(map(repr, COMPAT_METHODS))}"
        )
    if compat_method != "auto" and not (compat or apply_compat):
        raise DataError(
            f"compat_method={compat_method!r} needs the compatibility check: drop compat=False"
        )
    gusts = compat_method == "innovations" or (compat_method == "auto" and vane_scale)
    ac = _load_aircraft(aircraft, data)
    cmap = (
        channel_map
        if isinstance(channel_map, ChannelMap) or channel_map is None
        else ChannelMap.from_toml(channel_map)
    )
    man: pl.DataFrame | None
    man_name = "manifest"
    if isinstance(manifest, pl.DataFrame):
        man = manifest
    elif manifest is not None:
        man, man_name = read_manifest(manifest), str(manifest)
    elif isinstance(data, (str, Path)) and (Path(data) / "manifest.csv").is_file():
        man_name = str(Path(data) / "manifest.csv")
        man = read_manifest(man_name)
    else:
        man = None
    loadings = manifest_loadings(man, ac, man_name)
    sources = find_records(list(data) if isinstance(data, (list, tuple)) else data, man, man_name)
    frames: list[pl.DataFrame] = []
    kept: list[tuple[str, int]] = []
    reports: list[ValidationReport] = []

    def lazy(path: Path) -> pl.LazyFrame:
        lf = scan_record(path)
        try:
            if cmap is not None:
                return cmap.apply(lf, str(path))
            return lf.select(cs.by_name(*CHANNELS, "maneuver_id", require_all=False))
        except pl.exceptions.PolarsError as e:
            raise read_error(path, e, cmap) from e

    # files holding several maneuvers are read once and split by maneuver_id
    multi: dict[Path, dict[str, pl.DataFrame]] = {}

    def split(path: Path) -> dict[str, pl.DataFrame]:
        if path not in multi:
            try:
                df = lazy(path).with_columns(pl.col("maneuver_id").cast(pl.Utf8)).collect()
            except pl.exceptions.PolarsError as e:
                raise read_error(path, e, cmap) from e
            parts = df.partition_by("maneuver_id", as_dict=True, maintain_order=True)
            multi[path] = {str(k[0]): g for k, g in parts.items()}
        return multi[path]

    def collect_singles(part: Sequence[RecordSource]) -> list[pl.DataFrame]:
        paths = [s.path for s in part if not s.multi]
        lfs = [lazy(p) for p in paths]
        try:
            return pl.collect_all(lfs)
        except pl.exceptions.PolarsError as e:  # name the file: read them one by one
            for p, lf in zip(paths, lfs, strict=True):
                try:
                    lf.collect()
                except pl.exceptions.PolarsError as e1:
                    raise read_error(p, e1, cmap) from e1
            raise DataError(f"cannot read the records: {_first_line(e)}") from e

    if not sources:
        raise DataError(f"{data}: no maneuver to ingest")
    bar = tqdm(total=len(sources), desc="ingest", unit="maneuver", disable=not progress)
    raws: list[pl.DataFrame] = []
    chunk = 64  # single-maneuver files read in parallel by one polars collect_all
    for i0 in range(0, len(sources), chunk):
        part = sources[i0 : i0 + chunk]
        singles = iter(collect_singles(part))
        for s in part:
            raw = split(s.path)[s.maneuver_id] if s.multi else next(singles)
            raws.append(raw.drop("maneuver_id") if "maneuver_id" in raw.columns else raw)
            bar.update(1)
    bar.close()
    allc = _fast_validate(raws, sources, reports)
    if allc is None:
        reports.clear()
        for src, raw in zip(sources, raws, strict=True):
            df, rep = validate(raw, str(src.path), src.maneuver_id, allow_interpolation)
            reports.append(rep)
            if rep.ok:
                if any(dt != pl.Float64 for dt in df.schema.values()):
                    frames.append(df.select(pl.all().cast(pl.Float64)))
                else:
                    frames.append(df)
                kept.append((src.maneuver_id, df.height))
    if loadings is not None:
        by_id = {r.maneuver_id: r for r in reports}
        for mid, msg in cg_warnings(loadings, ac):
            if mid in by_id:
                by_id[mid].add("warning", "manifest", "", msg)
    errors = [f for r in reports for f in r.errors]
    if errors:
        lines = summarise(errors)
        if len(lines) == 1:  # one problem (or one repeated alike): one line
            raise DataError(lines[0])
        shown = lines[:25]
        more = f"\n... and {len(lines) - 25} more" if len(lines) > 25 else ""
        raise DataError(
            f"{len(errors)} problem(s) refused the data:\n  " + "\n  ".join(shown) + more
        )
    if allc is None:
        ids = pl.Series("maneuver_id", [m for m, _ in kept], dtype=pl.Utf8)
        rows = np.repeat(np.arange(len(kept)), [k for _, k in kept])
        same = all(f.schema == frames[0].schema for f in frames)
        allc = pl.concat(frames, how="vertical" if same else "diagonal_relaxed", rechunk=True)
        allc = allc.with_columns(ids.gather(rows))
    out, smoothing = preprocess_frame(allc, ac, smooth=smooth, loadings=loadings)
    plaus_df = None
    if plausibility:
        files = {r.maneuver_id: Path(r.file).name for r in reports}
        bad, plaus_df = check_plausibility(out, cmap, files)
        if bad:
            raise DataError(
                f"{len(bad)} channel(s) contradict the kinematics (units or signs; "
                "plausibility check):\n  " + "\n  ".join(bad)
            )
    compat_df = None
    if compat or apply_compat:
        compat_df = _run_compat(out, reports, ac, loadings, vane_scale, gusts=gusts)
        if apply_compat:
            allc = _apply_compat(allc, compat_df)
            out, smoothing = preprocess_frame(allc, ac, smooth=smooth, loadings=loadings)
            compat_df = compat_df.with_columns(pl.lit(True).alias("applied"))
    out = _attach_manifest(out, man, reports, man_name)
    if ac.builtin is not None:  # the virtual flight test's data: its simulator is known
        out = out.with_columns(pl.lit(ac.builtin, dtype=pl.Enum(BUILTINS)).alias(BUILTIN_COLUMN))
    return IngestResult(out, reports, compat_df, smoothing, plaus_df)


#: The data compatibility check runs on at most this many samples per maneuver (every k-th
#: sample of the smoothed channels; the RK4 reconstruction keeps its accuracy at 8-25 Hz
#: for aircraft motion) and at most this many Gauss-Newton iterations (consistent data
#: converge in 3-5; inconsistent data gain nothing from more), so that a campaign of 200
#: one-minute maneuvers is checked in seconds.
COMPAT_MAX_SAMPLES = 500

#: Flight-path reconstructions of the compatibility check (``compat_method``).
COMPAT_METHODS = ("auto", "output-error", "innovations")
COMPAT_MAX_ITER = 10
#: Gauss-Newton iterations of the innovations form: its three gains start far from where the
#: data put them (near 0 in calm air, 0.7-1 in turbulence) and take 15-20 iterations.
COMPAT_MAX_ITER_INNOVATIONS = 30


#: RMS output residuals after the reconstruction above which the data are reported as not
#: kinematically consistent: tas (m/s), alpha, beta, phi, theta, psi (deg).
_COMPAT_RMS_LIMITS = (1.0, 0.5, 0.5, 1.0, 1.0, 2.0)


def _fast_validate(
    raws: list[pl.DataFrame], sources: Sequence[RecordSource], reports: list[ValidationReport]
) -> pl.DataFrame | None:
    """Validate every maneuver at once over the concatenated columns when all records share
    one canonical float64 schema with the required channels (the usual campaign). Returns the
    concatenated frame with ``maneuver_id`` and fills ``reports`` when every maneuver passed
    the vectorised screen; None (reports untouched) when any needs the detailed per-record
    :func:`validate` (it then runs on all, so the findings are exactly its own)."""
    if not raws:
        return None
    schema = raws[0].schema
    names = raws[0].columns
    cols = set(names)
    if (
        any(c not in CHANNELS for c in names)
        or any(dt != pl.Float64 for dt in schema.values())
        or any(c not in cols for c in REQUIRED)
        or any(
            c not in cols and not all(a in cols for a in alts) for c, alts in ALTERNATIVES.items()
        )
        or any(r.height < 20 or r.columns != names for r in raws)
    ):
        return None
    try:  # a vertical concat refuses any other column type
        big = pl.concat(raws, how="vertical", rechunk=True)
    except pl.exceptions.PolarsError:
        return None
    if big.schema != schema:
        return None
    arrays = {c: big[c].to_numpy() for c in big.columns}
    lengths = np.array([r.height for r in raws])
    offsets = np.concatenate(([0], np.cumsum(lengths)))
    clean, views = screen_many(arrays, offsets)
    if not clean.all():
        return None
    med = az_medians(arrays, offsets)
    for i, (src, data) in enumerate(zip(sources, views, strict=True)):
        m = None if med is None else float(med[i])
        reports.append(unit_checks_only(data, str(src.path), src.maneuver_id, m))
    if any(not r.ok for r in reports):
        reports.clear()
        return None
    ids = pl.Series("maneuver_id", [s.maneuver_id for s in sources], dtype=pl.Utf8)
    return big.with_columns(ids.gather(np.repeat(np.arange(len(raws)), lengths)))


def _compat_one(
    g: pl.DataFrame,
    vanes: tuple[list[float], list[float], bool],
    scale_factors: bool = False,
    gusts: bool = False,
) -> dict[str, object]:
    """One maneuver's check: the vane readings (``alpha_deg``, ``beta_deg``) against the
    reconstructed flow at the vanes, ``vanes`` = (alpha vane, beta vane from this maneuver's
    CG, m; whether the beta vane reads the flank angle)."""
    d2r = np.pi / 180.0
    step = -(-g.height // COMPAT_MAX_SAMPLES)

    def a(c: str, k: float = 1.0) -> np.ndarray:
        return np.ascontiguousarray(g[c].to_numpy()[::step] * k, dtype=np.float64)

    return _core.compat_check(
        a("t"),
        [a("ax_cg_mps2"), a("ay_cg_mps2"), a("az_cg_mps2")],
        [a("p_s_dps", d2r), a("q_s_dps", d2r), a("r_s_dps", d2r)],
        a("tas_s_mps"),
        a("alpha_deg", d2r),
        a("beta_deg", d2r),
        [a("phi_deg", d2r), a("theta_deg", d2r), a("psi_deg", d2r)],
        max_iter=COMPAT_MAX_ITER_INNOVATIONS if gusts else COMPAT_MAX_ITER,
        scale_factors=scale_factors,
        r_alpha=vanes[0],
        r_beta=vanes[1],
        flank=vanes[2],
        gusts=gusts,
    )


#: The vane scale factors (estimated with ``vane_scale=True``): judged on the campaign median
#: only, a sensor's scale being the same in every maneuver.
SCALE_FACTORS = ("k_alpha", "k_beta")

#: A maneuver's estimate is reported on its own when it departs from the campaign median by
#: more than this many robust standard deviations of the spread between maneuvers (and the
#: practical threshold). The apparent biases that gusts cause are heavy-tailed: on the clean
#: demo campaign (200 maneuvers, 0.5 m/s Dryden turbulence) the largest departures are 5.2
#: (az) and 5.9 (beta) robust standard deviations, so a Gaussian 4-5 would cry wolf.
COMPAT_OUTLIER_SPREADS = 8.0

#: Campaigns of at least this many maneuvers judge the compatibility estimates against their
#: spread between maneuvers; smaller ones against each maneuver's Cramér-Rao bound.
COMPAT_MIN_CAMPAIGN = 5

_COMPAT_UNITS = {
    "mps2": ("m/s²", 1.0),
    "rps": ("deg/s", 180.0 / np.pi),
    "rad": ("deg", 180.0 / np.pi),
}


def _compat_show(name: str, v: float) -> str:
    """An estimate in the units the report speaks: deg, deg/s, m/s², % for the scale."""
    if name in ("lambda_v", *SCALE_FACTORS):
        return f"{100.0 * v:.3g} %"
    unit, k = _COMPAT_UNITS[name.rsplit("_", 1)[1]]
    return f"{k * v:.3g} {unit}"


def _compat_word(name: str) -> str:
    return {
        "b_alpha_rad": "alpha vane bias",
        "b_beta_rad": "beta vane bias",
        "lambda_v": "airspeed scale error",
        "k_alpha": "alpha vane scale error (upwash)",
        "k_beta": "beta vane scale error (sidewash)",
    }.get(name, f"{name.split('_')[1]} bias")


def _run_compat(
    out: pl.DataFrame,
    reports: list[ValidationReport],
    ac: Aircraft,
    loadings: pl.DataFrame | None = None,
    scale_factors: bool = False,
    *,
    gusts: bool = False,
) -> pl.DataFrame:
    """Run the check per maneuver and report what the campaign supports.

    A sensor bias or airspeed scale error belongs to the sensor, so it shows in every maneuver
    alike; gusts (the reconstruction drives the air-relative velocity with the inertial
    accelerations, so turbulence enters its outputs as coloured noise) give each maneuver an
    apparent bias of its own, scattered about zero, with Cramér-Rao bounds far below that
    scatter (the bounds assume white residuals). With at least :data:`COMPAT_MIN_CAMPAIGN`
    maneuvers a bias is therefore reported when the campaign median exceeds the practical
    threshold and four standard errors of the median from the spread between maneuvers (one
    finding, given to every maneuver); a single maneuver only when it departs from the median
    by more than the threshold and :data:`COMPAT_OUTLIER_SPREADS` robust standard deviations of
    that spread. Residual RMS
    above :data:`_COMPAT_RMS_LIMITS` is reported when also above three times the campaign
    median (the campaign's own turbulence level). Smaller campaigns are judged maneuver by
    maneuver against the Cramér-Rao bounds.
    """
    groups = out.partition_by("maneuver_id", maintain_order=True)
    mids = [str(g["maneuver_id"][0]) for g in groups]
    cgs = loading_array(loadings, mids)
    flank = ac.beta_vane_type == "flank"

    def vanes(i: int) -> tuple[list[float], list[float], bool]:
        cg = np.asarray(ac.cg_m) if cgs is None else cgs[i, 7:10]
        return (
            list(np.asarray(ac.alpha_vane_m) - cg),
            list(np.asarray(ac.beta_vane_m) - cg),
            flank,
        )

    with ThreadPoolExecutor(max_workers=engine_threads()) as ex:
        results = list(
            ex.map(
                lambda i: _compat_one(groups[i], vanes(i), scale_factors, gusts),
                range(len(groups)),
            )
        )
    by_id = {r.maneuver_id: r for r in reports}
    nm = len(mids)
    campaign = nm >= COMPAT_MIN_CAMPAIGN
    rows = []
    for mid, res in zip(mids, results, strict=True):
        for name, est, se in zip(res["names"], res["params"], res["std_err"], strict=False):  # type: ignore[call-overload]
            rows.append((mid, name, float(est), float(se), False))
    table = pl.DataFrame(
        rows,
        schema={
            "maneuver_id": pl.Utf8,
            "parameter": pl.Utf8,
            "estimate": pl.Float64,
            "std_err": pl.Float64,
            "applied": pl.Boolean,
        },
        orient="row",
    )
    # residual RMS per maneuver and output, in m/s and deg
    rms = np.array(
        [
            [
                float(r) * (1.0 if o == "tas" else 180.0 / np.pi)
                for o, r in zip(res["outputs"], res["rms_after"], strict=False)
            ]  # type: ignore[call-overload]
            for res in results
        ]
    )
    rms_ref = np.median(rms, axis=0) if campaign and rms.size else np.zeros(len(_COMPAT_RMS_LIMITS))
    outputs = list(results[0]["outputs"]) if results else []  # type: ignore[call-overload]
    for i, (mid, res) in enumerate(zip(mids, results, strict=True)):
        rep = by_id.get(mid)
        if rep is None:
            continue
        worst = [
            (o, v)
            for o, v, lim, ref in zip(outputs, rms[i], _COMPAT_RMS_LIMITS, rms_ref, strict=False)
            if v > lim and v > 3.0 * ref
        ]
        # in a campaign, a maneuver that stopped at the iteration limit with residuals like the
        # others' (turbulence slows the convergence) is no finding; its estimates are judged
        # with the others'
        if not res["converged"] and (worst or not campaign):
            rep.add(
                "warning",
                "compat",
                "",
                f"data compatibility check did not converge in {res['iterations']} iterations "
                "(inconsistent or unexcited data); its estimates are unreliable",
            )
        if worst:
            what = ", ".join(f"{o} {v:.3g} {'m/s' if o == 'tas' else 'deg'} RMS" for o, v in worst)
            rep.add(
                "warning",
                "compat",
                "",
                f"the flight path reconstruction leaves {what}: the data are not kinematically "
                "consistent (check time alignment between channels, units, sensor positions, "
                "gusts); the compatibility estimates are unreliable",
            )
    for name, thr in COMPAT_THRESHOLDS.items():
        sub = table.filter(pl.col("parameter") == name)
        if sub.height == 0:
            continue
        est = sub["estimate"].to_numpy()
        se = sub["std_err"].to_numpy()
        ids = sub["maneuver_id"].to_list()
        word = _compat_word(name)
        fix = "pass apply_compat=True to remove it, or check the sensor"
        if not campaign:
            for mid, e, s in zip(ids, est, se, strict=True):
                if abs(e) > thr and abs(e) > 4 * s and mid in by_id:
                    by_id[mid].add(
                        "warning",
                        name.split("_")[1],
                        "",
                        f"data compatibility check: {word} {_compat_show(name, e)} ± "
                        f"{_compat_show(name, s)} (flight path reconstruction, thesis Section "
                        f"2.4); the data are not self-consistent: {fix}",
                    )
            continue
        med = float(np.median(est))
        spread = 1.4826 * float(np.median(np.abs(est - med)))
        se_med = 1.2533 * spread / np.sqrt(len(est))
        if abs(med) > thr and abs(med) > 4 * se_med:
            for mid in ids:
                if mid in by_id:
                    by_id[mid].add(
                        "warning",
                        name.split("_")[1],
                        "",
                        f"data compatibility check: {word} {_compat_show(name, med)} (median of "
                        f"{len(est)} maneuvers, ± {_compat_show(name, se_med)}; flight path "
                        f"reconstruction, thesis Section 2.4) in every maneuver alike: {fix}",
                    )
        if name in SCALE_FACTORS:  # a property of the sensor: the median says it all
            continue
        lim = max(thr, COMPAT_OUTLIER_SPREADS * spread)
        for mid, e, s in zip(ids, est, se, strict=True):
            if abs(e - med) > lim and abs(e - med) > 4 * s and mid in by_id:
                by_id[mid].add(
                    "warning",
                    name.split("_")[1],
                    "",
                    f"data compatibility check: {word} {_compat_show(name, e)} in this maneuver, "
                    f"{_compat_show(name, e - med)} from the campaign median (spread "
                    f"{_compat_show(name, spread)}): check the sensor in this record",
                )
    return table


#: Parameters that belong to the air-data sensors, the same in every maneuver: in a campaign
#: (:data:`COMPAT_MIN_CAMPAIGN` maneuvers or more) ``apply_compat`` removes their campaign
#: median, not each maneuver's own estimate, which gusts scatter (±0.6-0.7 deg for the vane
#: biases at 0.5 m/s turbulence) with no sensor error behind it. The inertial sensors' biases
#: may differ from record to record: each maneuver's is shrunk toward the median by how much
#: of the spread its standard error leaves unexplained (:func:`_shrunk`).
SENSOR_PARAMETERS = ("b_alpha_rad", "b_beta_rad", "lambda_v", *SCALE_FACTORS)


def _shrunk(compat: pl.DataFrame) -> pl.DataFrame:
    """Each maneuver's inertial-sensor bias shrunk toward the campaign median by the share of
    its spread that the maneuvers' own standard errors do not explain (empirical Bayes,
    random-effects weight ``w = tau² / (tau² + se²)``, ``tau²`` by moments: the robust
    between-maneuver variance less the typical ``se²``; DerSimonian & Laird 1986). Biases that
    really differ from record to record (gyros powered up per flight) keep their own estimate
    (``se`` far below the spread: ``w`` near 1); apparent ones that gusts give each maneuver
    shrink to the median, where the innovations form's standard errors account for the
    spread (``w`` near 0)."""
    stats = compat.group_by("parameter").agg(
        pl.col("estimate").median().alias("median"),
        ((pl.col("estimate") - pl.col("estimate").median()).abs().median() * 1.4826)
        .pow(2)
        .alias("spread2"),
        pl.col("std_err").pow(2).median().alias("se2"),
    )
    tau2 = (pl.col("spread2") - pl.col("se2")).clip(lower_bound=0.0)
    se2 = pl.col("std_err").pow(2)
    w = (
        pl.when(pl.col("std_err").is_finite() & (tau2 + se2 > 0.0))
        .then(tau2 / (tau2 + se2))
        .otherwise(pl.lit(0.0))
    )
    return compat.join(stats, on="parameter").with_columns(
        pl.when(pl.col("parameter").is_in(SENSOR_PARAMETERS))
        .then(pl.col("median"))
        .otherwise(pl.col("median") + w * (pl.col("estimate") - pl.col("median")))
        .alias("estimate")
    )


def _apply_compat(df: pl.DataFrame, compat: pl.DataFrame) -> pl.DataFrame:
    if compat["maneuver_id"].n_unique() >= COMPAT_MIN_CAMPAIGN:
        compat = _shrunk(compat)
    wide = compat.pivot(on="parameter", index="maneuver_id", values="estimate")
    wide = wide.with_columns(pl.lit(0.0).alias(k) for k in SCALE_FACTORS if k not in wide.columns)
    r2d = 180.0 / np.pi
    j = df.join(wide, on="maneuver_id", how="left", maintain_order="left")
    fixes = [
        (pl.col("ax_mps2") - pl.col("b_ax_mps2")).alias("ax_mps2"),
        (pl.col("ay_mps2") - pl.col("b_ay_mps2")).alias("ay_mps2"),
        (pl.col("az_mps2") - pl.col("b_az_mps2")).alias("az_mps2"),
        (pl.col("p_dps") - r2d * pl.col("b_p_rps")).alias("p_dps"),
        (pl.col("q_dps") - r2d * pl.col("b_q_rps")).alias("q_dps"),
        (pl.col("r_dps") - r2d * pl.col("b_r_rps")).alias("r_dps"),
        # the estimates are of the vane readings themselves (the check models each vane's
        # local flow), so they correct the readings before the CG transfer
        ((pl.col("alpha_deg") - r2d * pl.col("b_alpha_rad")) / (1.0 + pl.col("k_alpha"))).alias(
            "alpha_deg"
        ),
        ((pl.col("beta_deg") - r2d * pl.col("b_beta_rad")) / (1.0 + pl.col("k_beta"))).alias(
            "beta_deg"
        ),
        (pl.col("tas_mps") / (1.0 + pl.col("lambda_v"))).alias("tas_mps"),
    ]
    return j.with_columns(fixes).select(df.columns)


def _attach_manifest(
    out: pl.DataFrame,
    man: pl.DataFrame | None,
    reports: list[ValidationReport],
    man_name: str = "manifest",
) -> pl.DataFrame:
    if man is None:
        for r in reports:
            r.add("info", "manifest", "", "no manifest: kind 'other', pusher unknown")
        flap = (
            pl.col("flap_deg").median().over("maneuver_id")
            if "flap_deg" in out.columns
            else pl.lit(None, dtype=pl.Float64)
        )
        return out.with_columns(
            flap.alias("flap_deg"),
            pl.lit("other").alias("kind"),
            pl.lit(None, dtype=pl.Boolean).alias("pusher"),
        )
    meta = man.select("maneuver_id", "flap_deg", "kind", "pusher").rename(
        {"flap_deg": "flap_manifest_deg"}
    )
    missing = sorted(set(out["maneuver_id"].unique()) - set(meta["maneuver_id"]))
    if missing:
        files = {r.maneuver_id: Path(r.file).name for r in reports}
        shown = ", ".join(f"{m} ({files.get(m, '?')})" for m in missing[:5])
        more = f" and {len(missing) - 5} more" if len(missing) > 5 else ""
        raise DataError(
            f"{man_name}: no row for maneuver(s) {shown}{more}; add a row per record (or a "
            "'file' column naming the records to read)"
        )
    # maneuvers are contiguous: join the manifest on the run values, then repeat each row
    runs = out.select(pl.col("maneuver_id").rle()).unnest("maneuver_id")
    per = runs.select(pl.col("value").alias("maneuver_id")).join(
        meta, on="maneuver_id", how="left", maintain_order="left"
    )
    if per.height == runs.height:
        idx = np.repeat(np.arange(per.height), runs["len"].to_numpy())
        j = pl.concat([out, per.drop("maneuver_id")[idx]], how="horizontal")
    else:  # duplicated manifest rows: the plain join (rows repeated as the manifest says)
        j = out.join(meta, on="maneuver_id", how="left", maintain_order="left")
    if "flap_deg" in out.columns:
        return j.drop("flap_deg").rename({"flap_manifest_deg": "flap_deg"})
    return j.rename({"flap_manifest_deg": "flap_deg"})


def summarise(findings: Sequence[Finding]) -> list[str]:
    """One line per channel and kind of finding: the first maneuver's message, then how many
    other maneuvers repeat it and their files (findings of one kind differ only in numbers).
    Findings of one maneuver that differ only in their channel (a row missing every value, a
    file without the channels) are one line naming the channels."""
    merged: dict[tuple[str, str, str, str, str], list[Finding]] = {}
    for f in findings:
        merged.setdefault((f.severity, f.file, f.maneuver_id, f.rows, f.message), []).append(f)
    groups: dict[tuple[str, str, str], list[tuple[Finding, list[str]]]] = {}
    for fs in merged.values():
        chans = [f.channel for f in fs]
        key = (fs[0].severity, ", ".join(chans), re.sub(r"[-+]?\d[\d.eE+-]*", "#", fs[0].message))
        groups.setdefault(key, []).append((fs[0], chans))
    lines = []
    for fs in groups.values():
        first, chans = fs[0]
        text = str(first) if len(chans) == 1 else _channels_line(first, chans)
        if len(fs) == 1:
            lines.append(text)
            continue
        names = sorted({Path(f.file).name for f, _ in fs})
        shown = ", ".join(names[:3]) + (f" and {len(names) - 3} more" if len(names) > 3 else "")
        lines.append(f"{text} [and {len(fs) - 1} more maneuver(s) alike; files: {shown}]")
    return lines


def _channels_line(f: Finding, channels: list[str]) -> str:
    rows = f", rows {f.rows}" if f.rows else ""
    shown = ", ".join(channels[:6]) + (
        f" and {len(channels) - 6} more" if len(channels) > 6 else ""
    )
    return f"{f.file} [{f.maneuver_id}] {len(channels)} channels ({shown}){rows}: {f.message}"


def _first_line(e: BaseException) -> str:
    text = str(e).strip()
    return text.splitlines()[0] if text else type(e).__name__


def read_error(path: Path, e: Exception, cmap: ChannelMap | None = None) -> DataError:
    """A polars error reading the record ``path`` as one line naming the file; a cell that is
    not a number is located (column and row) by reading the file as text."""
    msg = _first_line(e)
    if path.suffix.lower() == ".csv" and re.search(r"conver|parse|could not", msg):
        try:
            text = pl.read_csv(path, infer_schema=False)
        except pl.exceptions.PolarsError:
            text = None
        if text is not None:
            wanted = set(CHANNELS) | ({x.source for x in cmap.entries} if cmap else set())
            for c in text.columns:
                if c not in wanted:
                    continue
                s = text[c].str.strip_chars()
                bad = np.flatnonzero(
                    (
                        s.is_not_null() & (s != "") & s.cast(pl.Float64, strict=False).is_null()
                    ).to_numpy()
                )
                if bad.size:
                    r = int(bad[0])
                    n = f" ({bad.size} cells in this column)" if bad.size > 1 else ""
                    return DataError(
                        f"{path}: column '{c}', row {r} (line {r + 2} of the file): "
                        f"{text[c][r]!r} is not a number{n}; fix or clear the cell"
                    )
    hint = " (check the records against the channel map)" if cmap is not None else ""
    return DataError(f"{path}: cannot read the record: {msg}{hint}")
