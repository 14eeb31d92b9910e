"""Virtual flight test campaigns (engine: ``aero_core::sim``).

A campaign is flown by the pilot model on the *truth* aircraft (the qualified
model of the representative ADX-37 turboprop plus switchable post-stall
effects and the stochastic roll-off of thesis Section 3.4.3) and written in the
contract layout read by ``aerodelta ingest``::

    DIR/manifest.csv          maneuver_id, flap_deg, kind, pusher, file, + metadata
    DIR/aircraft.toml         aircraft reference
    DIR/records/<id>.parquet  canonical channels (float64)
    DIR/truth/<id>.parquet    truth only: Cl/Cn/CY true and qualified, per-effect dC*_<effect>
    DIR/truth/campaign.json   effects, magnitudes, shapes, seeds, roll-off draws

The same seed gives byte-identical files. See ``docs/aircraft.md``. With ``cg_range_m``,
``mass_range`` or ``inertia_range`` each maneuver is flown with its own mass, CG (body axes, m,
from the aircraft's datum, the nominal CG and the truth model's moment reference centre) and
inertia, written to the manifest (:data:`MASS_COLUMNS`). A maneuver in which the
truth aircraft departs (a spin entry the pilot model cannot hold, possible with several
destabilising effects at once) is terminated one second before a channel leaves its physical
range, as a flight test would be; the manifest's ``departed_at_s`` says when.
"""

from __future__ import annotations

import functools
import json
import math
import os
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import numpy.typing as npt
import polars as pl
from tqdm import tqdm

from aerodelta import _core
from aerodelta._fsutil import replace_dir
from aerodelta.channels import CHANNELS
from aerodelta.exceptions import DataError, InvalidInputError
from aerodelta.model import DeltaModel

Size = Literal["default", "quick"]

#: Aerodynamic effects switched on by ``effects="default"`` (thesis Chapter 4 findings).
DEFAULT_EFFECTS: tuple[str, ...] = (
    "aileron_effectiveness",
    "roll_damping",
    "dihedral",
    "directional_stability",
    "rudder_effectiveness",
    "lateral_asymmetry",
)

#: Repetitions of each (flap, kind, pusher) cell: 5 flaps x 4 kinds x 2 x reps maneuvers.
SIZES: dict[str, int] = {"default": 5, "quick": 1}

#: The truth's longitudinal stall options (:func:`generate_campaign`).
LONGITUDINAL_STALLS = ("static", "kirchhoff")

#: Units of the Kirchhoff parameters in the engine's order.
KIRCHHOFF_UNITS: dict[str, str] = {
    "tau1": "s", "tau2": "s", "alpha_star": "rad", "a1": "1/rad", "CL_alpha": "1/rad",
    "alpha0": "rad", "Cm0": "-", "Cm_alpha": "1/rad", "Cm_x": "-",
    "CD0": "-", "CD_k": "-", "CD_x": "-",
}  # fmt: skip

#: Manifest columns of a campaign with per-maneuver mass properties: mass (kg), CG from the
#: datum (body axes x forward, y right, z down; m) and the inertia about that CG (kg m^2;
#: Etkin's sign, the tensor holds -Ixz off the diagonal; Ixy = Iyz = 0).
MASS_COLUMNS: tuple[str, ...] = (
    "mass_kg",
    "cg_x_m",
    "cg_y_m",
    "cg_z_m",
    "Ixx_kgm2",
    "Iyy_kgm2",
    "Izz_kgm2",
    "Ixz_kgm2",
)


@dataclass(frozen=True)
class CampaignInfo:
    """What :func:`generate_campaign` wrote.

    Attributes
    ----------
    path
        The campaign folder.
    n_maneuvers
        Number of maneuvers.
    seed
        Campaign seed.
    effects
        Effects switched on, name -> magnitude (1 = design magnitude).
    manifest
        The manifest table (as written to ``manifest.csv``).
    """

    path: Path
    n_maneuvers: int
    seed: int
    effects: dict[str, float]
    manifest: pl.DataFrame


def effect_library() -> list[dict[str, Any]]:
    """The effect vocabulary with design magnitudes, terms and alpha shapes.

    Returns
    -------
    list of dict
        One entry per effect: ``name``, ``kind`` (aerodynamic, measurement,
        stochastic), ``description`` and, for aerodynamic effects, ``terms``
        (coefficient, regressor, design value), ``flap_factor``, ``shape`` and
        ``alpha_range_deg``.
    """
    return json.loads(_core.sim_effect_library())


def effect_names() -> list[str]:
    """All effect names the campaign generator knows."""
    return list(_effect_names())


@functools.cache
def _effect_names() -> tuple[str, ...]:
    return tuple(e["name"] for e in effect_library())


def parse_effects(
    effects: str | Sequence[str] | Mapping[str, float] | None,
) -> dict[str, float]:
    """Normalise an effect selection to ``{name: magnitude}``.

    Parameters
    ----------
    effects
        ``"default"`` (the thesis's Chapter 4 effects), ``"none"``/``None``, a
        comma list ``"name[=magnitude],..."``, a list of names or a mapping.

    Raises
    ------
    InvalidInputError
        For an unknown name or a bad magnitude, naming both.
    """
    if effects is None:
        return {}
    if isinstance(effects, Mapping):
        items = [(str(k), float(v)) for k, v in effects.items()]
    else:
        parts = effects.split(",") if isinstance(effects, str) else list(effects)
        items = []
        for raw in parts:
            p = raw.strip()
            if not p or p == "none":
                continue
            if p == "default":
                items.extend((n, 1.0) for n in DEFAULT_EFFECTS)
                continue
            name, _, mag = p.partition("=")
            try:
                m = float(mag) if mag else 1.0
            except ValueError:
                raise InvalidInputError(
                    f"effect '{name}': magnitude '{mag}' is not a number (use name=1.5)"
                ) from None
            items.append((name.strip(), m))
    known = set(_effect_names())
    out: dict[str, float] = {}
    for name, m in items:
        if name not in known:
            raise InvalidInputError(
                f"unknown effect '{name}'; `aerodelta campaign --list-effects` lists them"
            )
        if not np.isfinite(m):
            raise InvalidInputError(f"effect '{name}': magnitude must be finite")
        out[name] = m
    return out


def mass_variation(
    cg_range_m: Sequence[float] | None = None,
    mass_range: float | None = None,
    inertia_range: float | None = None,
) -> dict[str, Any] | None:
    """The spec's ``mass_properties`` entry, or ``None`` when no range is given (nominal).

    Parameters
    ----------
    cg_range_m
        Total CG range per body axis (x forward, y right, z down), m: each maneuver's CG is
        uniform within +-range/2 of the datum (the nominal CG of ``aircraft.toml``).
    mass_range
        Total relative mass range, -: mass = nominal * (1 + U(-range/2, +range/2)).
    inertia_range
        Total relative range of each of Ixx, Iyy, Izz, Ixz (drawn independently), -.

    Raises
    ------
    InvalidInputError
        For a CG range that is not three numbers (the engine refuses the values, see
        ``docs/aircraft.md``).
    """
    if cg_range_m is None and mass_range is None and inertia_range is None:
        return None
    cg = [0.0, 0.0, 0.0] if cg_range_m is None else [float(v) for v in cg_range_m]
    if len(cg) != 3:
        raise InvalidInputError(
            f"cg_range_m {tuple(cg)}: give three total ranges (x, y, z) in m, "
            "e.g. (0.21, 0.05, 0.1)"
        )
    out = {
        "cg_range_m": cg,
        "mass_range": 0.0 if mass_range is None else float(mass_range),
        "inertia_range": 0.0 if inertia_range is None else float(inertia_range),
    }
    named = [(f"cg_range_m {a}", v) for a, v in zip("xyz", cg, strict=True)]
    for name, v in [
        *named,
        ("mass_range", out["mass_range"]),
        ("inertia_range", out["inertia_range"]),
    ]:
        if not math.isfinite(v):
            raise InvalidInputError(f"{name} = {v}: give a finite total range >= 0")
    return out


def _spec(
    effects: dict[str, float],
    *,
    seed: int,
    size: Size | int,
    noise: float,
    turbulence: float,
    rolloff: bool,
    excitation: float,
    only: Sequence[int] = (),
    record_hz: float = 50.0,
    mass: dict[str, Any] | None = None,
    vanes: dict[str, Any] | None = None,
    buffet: dict[str, Any] | None = None,
    longitudinal_stall: str = "static",
) -> dict[str, Any]:
    if longitudinal_stall not in LONGITUDINAL_STALLS:
        raise InvalidInputError(
            f"longitudinal_stall '{longitudinal_stall}': use one of "
            + ", ".join(LONGITUDINAL_STALLS)
        )
    reps = SIZES.get(size, 0) if isinstance(size, str) else int(size)
    if reps <= 0:
        raise InvalidInputError(f"size '{size}': use 'default', 'quick' or a positive integer")
    eff = dict(effects)
    if rolloff:
        eff.setdefault("stochastic_rolloff", 1.0)
    else:
        eff.pop("stochastic_rolloff", None)
    spec = json.loads(_core.sim_default_spec())
    spec.update(
        seed=int(seed),
        repetitions=reps,
        effects=[{"name": k, "magnitude": v} for k, v in sorted(eff.items())],
        noise_scale=float(noise),
        turbulence_mps=float(turbulence),
        excitation=float(excitation),
        only=list(only),
        record_hz=float(record_hz),
    )
    if mass is not None:
        spec["mass_properties"] = mass
    if vanes is not None:
        spec["vanes"] = vanes
    if buffet is not None:
        spec["buffet"] = buffet
    if longitudinal_stall != "static":
        spec["longitudinal_stall"] = longitudinal_stall
    if mass is not None or vanes is not None or buffet is not None:
        _core.sim_plan(json.dumps(spec))  # refuses meaningless ranges and errors before flying
    return spec


def buffet_spec(buffet: bool | Mapping[str, Any] | None) -> dict[str, Any] | None:
    """The spec's ``buffet`` entry: ``None``/``False`` for none, ``True`` for the virtual
    aircraft's default buffet (``docs/stall.md``, "Buffet"), or a mapping of the fields to
    change (``onset_below_alpha_max_deg``, ``full_above_alpha_max_deg``, ``onset_rms_g``,
    ``max_rms_g``, ``modes``: list of ``freq_hz``, ``damping``, ``nz_gain``, ``ny_gain``)."""
    if buffet is None or buffet is False:
        return None
    if buffet is True:
        return {}
    if not isinstance(buffet, Mapping):
        raise InvalidInputError(
            f"buffet {buffet!r}: give True (the default buffet), False or a mapping of buffet "
            "fields (docs/stall.md)"
        )
    return dict(buffet)


def vane_calibration(vane_scale: Sequence[float] | None, flank_vane: bool) -> dict[str, Any] | None:
    """The spec's ``vanes`` entry (scale errors of the alpha and beta vanes, flank-angle beta
    vane), or ``None`` for ideal vanes."""
    if vane_scale is None and not flank_vane:
        return None
    ks = [0.0, 0.0] if vane_scale is None else [float(v) for v in vane_scale]
    if len(ks) != 2 or not all(np.isfinite(ks)):
        raise InvalidInputError(
            f"vane_scale {tuple(ks)}: give the alpha and beta vanes' scale errors (k_alpha, "
            "k_beta), e.g. (0.05, -0.05) for 5 % upwash and -5 % sidewash"
        )
    return {"alpha_scale": ks[0], "beta_scale": ks[1], "beta_flank": bool(flank_vane)}


def simulate_campaign(
    *,
    effects: str | Sequence[str] | Mapping[str, float] | None = "default",
    seed: int = 0,
    size: Size | int = "default",
    noise: float = 1.0,
    turbulence: float = 0.5,
    rolloff: bool = True,
    excitation: float = 1.0,
    only: Sequence[int] = (),
    record_hz: float = 50.0,
    cg_range_m: Sequence[float] | None = None,
    mass_range: float | None = None,
    inertia_range: float | None = None,
    vane_scale: Sequence[float] | None = None,
    flank_vane: bool = False,
    buffet: bool | Mapping[str, Any] | None = None,
    longitudinal_stall: str = "static",
) -> list[dict[str, Any]]:
    """Fly a campaign in memory (no files).

    Parameters
    ----------
    effects, seed, size, noise, turbulence, rolloff, excitation
        As :func:`generate_campaign`.
    vane_scale, flank_vane, buffet, longitudinal_stall
        As :func:`generate_campaign`; with a buffet the maneuver's ``meta["buffet"]`` holds
        its flap's ``schedule`` and the ``modes``.
    cg_range_m, mass_range, inertia_range
        As :func:`generate_campaign`; the maneuver's ``meta["mass_properties"]`` then holds
        ``mass_kg``, ``cg_m`` (x, y, z from the datum), ``ixx``, ``iyy``, ``izz``, ``ixz``.
    only
        Maneuver indices to fly (empty: all).
    record_hz
        Record rate, Hz (a divisor of the 100 Hz simulation rate).

    Returns
    -------
    list of dict
        Per maneuver: ``id``, ``meta`` (dict), ``record`` and ``truth``
        (polars DataFrames).
    """
    spec = _spec(
        parse_effects(effects),
        seed=seed,
        size=size,
        noise=noise,
        turbulence=turbulence,
        rolloff=rolloff,
        excitation=excitation,
        only=only,
        record_hz=record_hz,
        mass=mass_variation(cg_range_m, mass_range, inertia_range),
        vanes=vane_calibration(vane_scale, flank_vane),
        buffet=buffet_spec(buffet),
        longitudinal_stall=longitudinal_stall,
    )
    out = []
    for m in _core.sim_run_campaign(json.dumps(spec)):
        out.append(
            {
                "id": m["id"],
                "meta": json.loads(m["meta"]),
                "record": pl.DataFrame(m["record"]),
                "truth": pl.DataFrame(m["truth"]),
            }
        )
    return out


def _departure_row(record: pl.DataFrame, margin_s: float = 1.0) -> int | None:
    """First row of a record ``margin_s`` before any channel leaves its physical range
    (:data:`aerodelta.channels.CHANNELS`), or ``None`` when the record stays inside."""
    first = None
    for c in record.columns:
        spec = CHANNELS.get(c)
        if spec is None:
            continue
        x = record[c].to_numpy()
        with np.errstate(invalid="ignore"):
            bad = np.flatnonzero((x < spec.lo) | (x > spec.hi))
        if bad.size and (first is None or bad[0] < first):
            first = int(bad[0])
    if first is None:
        return None
    t = record["t"].to_numpy()
    return int(np.searchsorted(t, t[first] - margin_s))


def _write_parquet(df: pl.DataFrame, path: Path) -> None:
    df.write_parquet(path, compression="zstd", statistics=False)


def generate_campaign(
    out_dir: str | os.PathLike[str],
    *,
    effects: str | Sequence[str] | Mapping[str, float] | None = "default",
    seed: int = 0,
    size: Size | int = "default",
    noise: float = 1.0,
    turbulence: float = 0.5,
    rolloff: bool = True,
    excitation: float = 1.0,
    cg_range_m: Sequence[float] | None = None,
    mass_range: float | None = None,
    inertia_range: float | None = None,
    vane_scale: Sequence[float] | None = None,
    flank_vane: bool = False,
    buffet: bool | Mapping[str, Any] | None = None,
    longitudinal_stall: str = "static",
    only: Sequence[int] = (),
    overwrite: bool = False,
    progress: bool = False,
) -> CampaignInfo:
    """Generate a virtual flight test campaign and write it in the contract layout.

    Parameters
    ----------
    out_dir
        Campaign folder to create (written into a temporary sibling, then renamed).
    effects
        ``"default"``, ``"none"``, ``"name[=magnitude],..."``, a list or a mapping
        (magnitude 1 = the design magnitude of ``docs/aircraft.md``).
    seed
        Campaign seed; the same seed gives byte-identical files.
    size
        ``"default"`` (200 maneuvers, the thesis's size), ``"quick"`` (40) or
        the number of repetitions per (flap, kind, pusher) cell.
    noise
        Sensor noise scale (0 = noise-free).
    turbulence
        Dryden RMS gust intensity, m/s (0 = calm air).
    rolloff
        Include the stochastic roll-off (thesis Table 3.2).
    excitation
        Pilot excitation scale (doublets, stick noise); 0 = none.
    cg_range_m
        Per-maneuver CG variation: total range per body axis (x forward, y right, z down), m;
        each maneuver's CG is uniform within +-range/2 of the datum (the nominal CG of
        ``aircraft.toml``, the moment reference centre of the truth model). A "10 % c-bar CG
        shift" is ``(0.21, 0.05, 0.10)``. At most 0.39 m in x (the aft-most CG keeps 5 % c-bar
        of the 14.4 % c-bar static margin), 0.1 m in y, 0.5 m in z (``docs/aircraft.md``).
    mass_range
        Per-maneuver mass variation, total relative range: mass = 15 000 kg * (1 + U(-r/2, r/2));
        0.1 = +-5 %; below 2.
    inertia_range
        Per-maneuver inertia variation, total relative range of each of Ixx, Iyy, Izz, Ixz
        (independent draws); below 2. Giving any of the three writes the manifest's
        :data:`MASS_COLUMNS` (the others default to 0); giving none flies the nominal aircraft
        and the files are those of a campaign without the option.
    vane_scale
        Calibration scale errors of the alpha and beta vanes ``(k_alpha, k_beta)``: each reads
        ``(1 + k)`` times the flow angle at it (upwash, sidewash), before its bias (the
        ``alpha_vane_bias``/``beta_vane_bias`` effects); ``None``: ideal vanes. The
        compatibility check estimates them (``aerodelta.ingest(..., vane_scale=True)``).
    flank_vane
        The beta vane is a boom yaw vane reading the flank angle ``atan(v/u)``; the campaign's
        ``aircraft.toml`` then says ``beta_vane_type = "flank"``.
    buffet
        Stall buffet at the accelerometers (structural vibration added to ``ay_mps2`` and
        ``az_mps2``; the flight is unchanged): ``True`` for the virtual aircraft's buffet (onset
        2 deg below each flap's C_L,max alpha, modes at 7.5, 9.2 and 12.6 Hz; ``docs/stall.md``),
        a mapping of fields to change, or ``None`` (no buffet: the files are those of a
        campaign without the option). The truth (onset alpha per flap, mode frequencies) is
        written to ``truth/campaign.json`` under ``"buffet"`` and per sample to the truth
        files (``buffet_ay_true_mps2``, ``buffet_az_true_mps2``, ``buffet_rms_true_mps2``).
    longitudinal_stall
        ``"static"`` (default): the truth's lift, pitching moment and drag follow the
        qualified model's static curves. ``"kirchhoff"``: a Kirchhoff flow-separation stall
        (``docs/longitudinal.md``) with known time constants, breakpoint, steepness and drag per
        flap, written to ``truth/campaign.json`` (``longitudinal_stall``); the truth files then
        carry ``x_sep_true``, ``CL_true``, ``Cm_true`` and ``CD_true``.
    only
        Indices of the maneuvers to fly (:func:`campaign_plan` lists the campaign's maneuvers
        with their index, flap, kind and pusher); empty: all. Each maneuver has its own seeded
        streams, so a maneuver's files are byte for byte those it has in the whole campaign.
        ``truth/campaign.json`` records the indices (``spec.only``).
    overwrite
        Replace an existing folder.
    progress
        Show a tqdm progress bar on stderr.

    Returns
    -------
    CampaignInfo

    Raises
    ------
    DataError
        If ``out_dir`` exists and ``overwrite`` is false.
    InvalidInputError
        For a meaningless mass, CG or inertia range (negative, beyond the limits), or an index
        of ``only`` that is not one of the campaign's maneuvers or comes twice.
    """
    out = Path(out_dir)
    if out.exists() and not overwrite:
        raise DataError(f"{out}: already exists; choose another folder or pass overwrite=True")
    picked = _only(only, seed=seed, size=size)
    eff = parse_effects(effects)
    spec = _spec(
        eff,
        seed=seed,
        size=size,
        noise=noise,
        turbulence=turbulence,
        rolloff=rolloff,
        excitation=excitation,
        mass=mass_variation(cg_range_m, mass_range, inertia_range),
        vanes=vane_calibration(vane_scale, flank_vane),
        buffet=buffet_spec(buffet),
        longitudinal_stall=longitudinal_stall,
        only=picked,
    )
    plan = json.loads(_core.sim_plan(json.dumps(spec)))
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.parent / f".{out.name}.tmp-{os.getpid()}"
    if tmp.exists():
        shutil.rmtree(tmp)
    (tmp / "records").mkdir(parents=True)
    (tmp / "truth").mkdir()
    rows: list[dict[str, Any]] = []
    draws: dict[str, Any] = {}
    seeds: dict[str, int] = {}
    buffet_truth: dict[str, Any] = {}
    bar = None
    if progress:
        bar = tqdm(total=len(plan), desc="campaign", unit="maneuver")
    try:
        chunk = 20
        for start in range(0, len(plan), chunk):
            idx = [p["index"] for p in plan[start : start + chunk]]
            spec["only"] = idx
            for m in _core.sim_run_campaign(json.dumps(spec)):
                meta = json.loads(m["meta"])
                p = meta["plan"]
                mid = m["id"]
                rec, tru = pl.DataFrame(m["record"]), pl.DataFrame(m["truth"])
                cut = _departure_row(rec)
                if cut is not None:
                    # the aircraft departed (spin entry, with the truth's effects the pilot
                    # model could not hold it): the test is terminated there, as a flight
                    # test would be, so the record stays within the sensors' physical ranges
                    departed = float(rec["t"][cut])
                    rec, tru = rec.head(cut), tru.filter(pl.col("t") < departed)
                _write_parquet(rec, tmp / "records" / f"{mid}.parquet")
                _write_parquet(tru, tmp / "truth" / f"{mid}.parquet")
                rows.append(
                    {
                        "maneuver_id": mid,
                        "flap_deg": float(p["flap_deg"]),
                        "kind": _kind_name(p["kind"]),
                        "pusher": bool(p["pusher"]),
                        "file": f"records/{mid}.parquet",
                        "seed": int(p["seed"]),
                        "pusher_fired": bool(meta["pusher_fired"]),
                        "max_alpha_deg": float(meta["max_alpha_deg"]),
                        "load_factor_at_stall": float(meta["load_factor_at_stall"]),
                        "max_bank_deg": float(meta["max_bank_deg"]),
                        "departed_at_s": None if cut is None else departed,
                        "effects": ";".join(f"{k}={v:g}" for k, v in sorted(eff.items())),
                    }
                )
                if "mass_properties" in meta:
                    rows[-1].update(_mass_columns(meta["mass_properties"]))
                if "buffet" in meta:
                    flap_key = f"{float(p['flap_deg']):g}"
                    buffet_truth.setdefault("schedules", {})[flap_key] = meta["buffet"]["schedule"]
                    buffet_truth["modes"] = meta["buffet"]["modes"]
                draws[mid] = meta["rolloff_draws"]
                seeds[mid] = int(p["seed"])
            if bar is not None:
                bar.update(len(idx))
        manifest = pl.DataFrame(rows, infer_schema_length=None)
        manifest.write_csv(tmp / "manifest.csv")
        (tmp / "aircraft.toml").write_text(_aircraft_toml(flank_vane))
        lib = {e["name"]: e for e in effect_library()}
        spec["only"] = picked
        info = {
            "seed": int(seed),
            "spec": spec,
            "effects": {
                k: {
                    "magnitude": v,
                    "shape": lib[k].get("shape"),
                    "alpha_range_deg": lib[k].get("alpha_range_deg"),
                    "terms": lib[k].get("terms"),
                    "flap_factor": lib[k].get("flap_factor"),
                }
                for k, v in sorted(spec_effects(spec).items())
            },
            "maneuver_seeds": seeds,
            "rolloff_draws": draws,
            "rolloff_config": json.loads(_core.sim_rolloff_config()),
        }
        if buffet_truth:
            info["buffet"] = buffet_truth
        if longitudinal_stall == "kirchhoff":
            info["longitudinal_stall"] = kirchhoff_truth()
        (tmp / "truth" / "campaign.json").write_text(json.dumps(info, indent=1, sort_keys=True))
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    finally:
        if bar is not None:
            bar.close()
    replace_dir(tmp, out)
    return CampaignInfo(
        path=out,
        n_maneuvers=len(rows),
        seed=int(seed),
        effects=spec_effects(spec),
        manifest=manifest,
    )


def campaign_plan(*, seed: int = 0, size: Size | int = "default") -> pl.DataFrame:
    """The maneuvers a campaign flies, in order, before flying them.

    Parameters
    ----------
    seed, size
        As :func:`generate_campaign` (the other options do not change the plan).

    Returns
    -------
    polars.DataFrame
        One row per maneuver: ``maneuver_index`` (what ``only`` takes), ``flap_deg`` (deg),
        ``kind`` (as the manifest's), ``pusher`` and ``seed`` (the maneuver's own stream).
    """
    spec = _spec({}, seed=seed, size=size, noise=0.0, turbulence=0.0, rolloff=False, excitation=0.0)
    plan = json.loads(_core.sim_plan(json.dumps(spec)))
    return pl.DataFrame(
        {
            "maneuver_index": [int(p["index"]) for p in plan],
            "flap_deg": [float(p["flap_deg"]) for p in plan],
            "kind": [_kind_name(p["kind"]) for p in plan],
            "pusher": [bool(p["pusher"]) for p in plan],
            "seed": [int(p["seed"]) for p in plan],
        },
        schema={
            "maneuver_index": pl.Int64,
            "flap_deg": pl.Float64,
            "kind": pl.String,
            "pusher": pl.Boolean,
            "seed": pl.UInt64,
        },
    )


def maneuver_index(maneuver_id: str) -> int:
    """The campaign index of a virtual campaign's maneuver id (``m{index:03}_f{flap:02}_...``:
    three digits or more; what ``only`` takes)."""
    head = maneuver_id.split("_", 1)[0]
    if not (head.startswith("m") and head[1:].isdigit()):
        raise InvalidInputError(
            f"maneuver id '{maneuver_id}' is not a virtual campaign's (m<index>_f<flap>_...)"
        )
    return int(head[1:])


def _only(only: Sequence[int], *, seed: int, size: Size | int) -> list[int]:
    """``only`` checked against the campaign's plan: sorted indices, each a maneuver of it."""
    if isinstance(only, (np.ndarray, pl.Series)):
        only = only.tolist()
    if isinstance(only, (str, bytes)) or not isinstance(only, Sequence):
        raise InvalidInputError(f"only {only!r}: give a list of maneuver indices (campaign_plan)")
    if not only:
        return []
    picked: list[int] = []
    for v in only:
        if isinstance(v, bool) or not isinstance(v, (int, np.integer)):
            raise InvalidInputError(f"only: {v!r} is not a maneuver index (an integer)")
        picked.append(int(v))
    n = campaign_plan(seed=seed, size=size).height
    bad = [v for v in picked if not 0 <= v < n]
    if bad:
        raise InvalidInputError(
            f"only: maneuver index {bad[0]} is not in this campaign (size {size!r} flies "
            f"indices 0 to {n - 1}; campaign_plan lists them)"
        )
    if len(set(picked)) != len(picked):
        dup = next(v for v in picked if picked.count(v) > 1)
        raise InvalidInputError(f"only: maneuver index {dup} is given twice")
    return sorted(picked)


def kirchhoff_truth() -> dict[str, Any]:
    """The virtual aircraft's Kirchhoff stall per flap, as written to ``truth/campaign.json``.

    Returns
    -------
    dict
        ``model`` ("kirchhoff"), ``units`` per parameter and ``params_by_flap``: for each flap
        (key: the flap in deg as text) the engine's parameters (radians, seconds), the drag's
        ``CD0``, ``CD_k``, ``CD_x`` (``aero_core::aircraft::truth::kirchhoff_truth_drag``), and
        ``alpha_star_deg``, ``alpha_cl_max_deg`` and ``cl_max`` of the static lift curve.
    """
    flaps: dict[str, Any] = {}
    for f in (0.0, 5.0, 10.0, 15.0, 35.0):
        p = _core.kirchhoff_truth_params(f)
        a_max, cl_max = _core.kirchhoff_cl_max(p)
        flaps[f"{f:g}"] = {
            **p,
            **_core.kirchhoff_truth_drag(f),
            "alpha_star_deg": math.degrees(p["alpha_star"]),
            "alpha_cl_max_deg": math.degrees(a_max),
            "cl_max": cl_max,
        }
    return {"model": "kirchhoff", "units": KIRCHHOFF_UNITS, "params_by_flap": flaps}


def _mass_columns(mp: Mapping[str, Any]) -> dict[str, float]:
    """A maneuver's mass properties (engine meta) as the manifest's :data:`MASS_COLUMNS`."""
    cg = mp["cg_m"]
    values = (mp["mass_kg"], cg[0], cg[1], cg[2], mp["ixx"], mp["iyy"], mp["izz"], mp["ixz"])
    return {k: float(v) for k, v in zip(MASS_COLUMNS, values, strict=True)}


def spec_effects(spec: Mapping[str, Any]) -> dict[str, float]:
    """``{name: magnitude}`` of a campaign spec (as stored in ``truth/campaign.json``)."""
    return {e["name"]: float(e["magnitude"]) for e in spec["effects"]}


def _kind_name(kind: str) -> str:
    return {"asymmetricthrust": "asymmetric_thrust"}.get(kind, kind)


def _aircraft_toml(flank_vane: bool) -> str:
    """The campaign's ``aircraft.toml``: the representative aircraft's, with the flank-angle
    yaw vane declared in its ``[sensors]`` table (the one before ``[simulator]``)."""
    toml = _core.sim_aircraft_toml()
    if not flank_vane:
        return toml
    head, sep, tail = toml.partition("\n\n[simulator]")
    if not sep:
        raise RuntimeError("the aircraft file lost its [simulator] table; declare the vane type")
    return head + '\nbeta_vane_type = "flank"' + sep + tail


def aircraft_toml() -> str:
    """The representative aircraft's reference file (contract ``aircraft.toml``)."""
    return _core.sim_aircraft_toml()


def qualified_model_tables() -> tuple[list[dict[str, Any]], list[dict[str, Any]]]:
    """The qualified model as named tables and the terms combining them.

    Returns
    -------
    tables
        ``{"name", "axes" (input names), "breakpoints", "values" (row-major, last
        axis fastest)}`` per table; alpha in deg, controls in deg.
    terms
        ``{"coef", "table", "inputs", "regressor", "sign"}``: each coefficient is
        the sum of sign * table(inputs) * regressor (see ``docs/aircraft.md``).
    """
    tables, terms = _core.sim_qualified_tables()
    return (
        [{"name": n, "axes": a, "breakpoints": b, "values": v} for n, a, b, v in tables],
        json.loads(terms),
    )


def rolloff_draws(flap_deg: float, seed: int, n: int, stream: int = 0) -> pl.DataFrame:
    """``n`` successive roll-off draws (thesis Section 3.4.3) of one seeded generator.

    Returns
    -------
    polars.DataFrame
        Columns ``sign`` (+1 right), ``factor``, ``alpha_shift_deg``,
        ``center_deg``, ``peak`` (signed peak ΔC_l).
    """
    return pl.DataFrame(_core.sim_rolloff_draws(float(flap_deg), int(seed), int(n), int(stream)))


def trim(flap_deg: float, tas_mps: float, h_m: float) -> dict[str, Any]:
    """Wings-level trim of the qualified ADX-37.

    Returns
    -------
    dict
        ``state`` (12: u v w [m/s], p q r [rad/s], phi theta psi [rad], x y h [m]),
        ``controls_deg`` (da, de, dr, dsl, dsr) and ``ct`` (per engine).
    """
    x, c, ct = _core.sim_trim(float(flap_deg), float(tas_mps), float(h_m))
    return {"state": x, "controls_deg": c, "ct": ct}


def record_state(row: Mapping[str, Any]) -> list[float]:
    """The 12 simulator states (u v w [m/s], p q r [rad/s], φ θ ψ [rad], x y h [m]) at one
    record sample (``row``: column -> value, e.g. ``frame.row(0, named=True)``): the airspeed
    ``tas_mps`` and the CG angles (``alpha_cg_deg``/``beta_cg_deg`` of ingested records, else
    ``alpha_deg``/``beta_deg`` of a model frame, where they are the CG's), the rates and
    attitudes (a missing one is 0), ``h_m`` (missing: 3000 m); x and y are 0."""
    v = float(row["tas_mps"])
    a = math.radians(float(row["alpha_cg_deg"] if "alpha_cg_deg" in row else row["alpha_deg"]))
    b = math.radians(float(row["beta_cg_deg"] if "beta_cg_deg" in row else row["beta_deg"]))
    h = float(row["h_m"]) if row.get("h_m") is not None else 3000.0
    rad = [math.radians(float(row.get(c) or 0.0)) for c in
           ("p_dps", "q_dps", "r_dps", "phi_deg", "theta_deg", "psi_deg")]  # fmt: skip
    uvw = [v * math.cos(a) * math.cos(b), v * math.sin(b), v * math.sin(a) * math.cos(b)]
    return [*uvw, *rad, 0.0, 0.0, h]


def replay(
    flap_deg: float,
    state0: Sequence[float],
    dt: float,
    controls_deg: npt.ArrayLike,
    ct: npt.ArrayLike,
    *,
    effects: str | Sequence[str] | Mapping[str, float] | None = None,
    rolloff_seed: int | None = None,
    delta_model: DeltaModel | None = None,
    lateral_delta: bool = True,
) -> npt.NDArray[np.float64]:
    """Replay recorded controls on the ADX-37 (thesis Section 4.3).

    Parameters
    ----------
    flap_deg
        Flap setting, deg.
    state0
        Initial 12 states (see :func:`trim`).
    dt
        Step, s.
    controls_deg
        ``(n, 5)``: da, de, dr, dsl, dsr in deg, the surfaces' position at the start of each
        step; they move linearly to the next row's over the step (the last row is held), as in
        the virtual flight test.
    ct
        ``(n, 2)``: thrust coefficient per engine per step.
    effects
        Truth effects (``None``: the qualified model).
    rolloff_seed
        Include the stochastic roll-off with this seed.
    delta_model
        A fitted Δ model put on top of the qualified model in the loop (the extended model,
        Eq. 3.12; lateral coefficients CY, Cl, Cn); not with ``effects``. The Kirchhoff stall
        the model stores for the flap (:meth:`aerodelta.model.DeltaModel.with_longitudinal`)
        replaces the qualified static C_L, C_m curves when it was fitted on the ADX-37's known
        terms (``kirchhoff_known == "adx37"``), as in the closed-loop replays.
    lateral_delta
        With ``delta_model``: ``False`` flies the model's stored stall alone, without the
        lateral Δ (the qualified model when the model stores no such stall).

    Returns
    -------
    numpy.ndarray
        ``(n + 1, 12)`` states.
    """
    eff = parse_effects(effects)
    eff.pop("stochastic_rolloff", None)
    c = np.ascontiguousarray(controls_deg, dtype=np.float64)
    k = np.ascontiguousarray(ct, dtype=np.float64)
    if c.ndim != 2 or k.ndim != 2 or c.shape[0] != k.shape[0]:
        raise InvalidInputError(
            f"replay: controls_deg must be (n, 5) and ct (n, 2); got {c.shape} and {k.shape}"
        )
    if delta_model is not None:
        if eff:
            raise InvalidInputError("replay: give either effects (truth) or delta_model, not both")
        return _core.sim_replay_extended(
            float(flap_deg), delta_model._m, list(state0), float(dt), c, k, rolloff_seed,
            bool(lateral_delta),
        )  # fmt: skip
    if not lateral_delta:
        raise InvalidInputError(
            "replay: lateral_delta=False says what to fly of a delta_model; give delta_model"
        )
    spec = json.dumps([{"name": n, "magnitude": m} for n, m in eff.items()])
    return _core.sim_replay(float(flap_deg), spec, list(state0), float(dt), c, k, rolloff_seed)
