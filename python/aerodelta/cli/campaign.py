"""Generate a virtual flight test campaign: the ADX-37 truth aircraft flown by the
pilot model through the stall maneuvers of the thesis (Section 3.2.1), written in
the campaign layout that ``aerodelta ingest`` reads. With ``--simulator jsbsim`` a JSBSim
aircraft (``--aircraft f15`` or ``DHC6``) is flown instead, and its truth written beside
the records (``docs/jsbsim_campaign.md``)."""

from __future__ import annotations

import argparse
import math
import sys

import polars as pl

from aerodelta.campaign import effect_library, generate_campaign
from aerodelta.cli._data import check_at_least, output_folder
from aerodelta.exceptions import InvalidInputError

HELP = "generate a virtual flight test campaign (synthetic stall maneuvers)"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta campaign``."""
    parser.add_argument(
        "--effects",
        help="truth effects: 'default' (the default), 'none', or name[=magnitude],... (1 = design "
        "magnitude)",
    )
    parser.add_argument("--seed", type=int, default=0, help="campaign seed (same seed, same files)")
    parser.add_argument("--quick", action="store_true", help="40 maneuvers instead of 200")
    parser.add_argument("--noise-scale", type=float, default=1.0, help="sensor noise scale")
    parser.add_argument(
        "--turbulence",
        type=float,
        default=None,
        help="Dryden RMS gust, m/s (builtin, default 0.5); with --simulator jsbsim: JSBSim's "
        "MIL-spec severity (default 0, calm)",
    )
    parser.add_argument(
        "--simulator",
        choices=("builtin", "jsbsim"),
        default="builtin",
        help="builtin ADX-37 truth aircraft, or a JSBSim aircraft (pip install "
        "'aerodelta[jsbsim]')",
    )
    parser.add_argument("--aircraft", help="JSBSim aircraft (f15, the default, or DHC6)")
    parser.add_argument(
        "--withhold",
        help="JSBSim: lateral terms the qualified model freezes past --withhold-alpha "
        "(comma list of XML term names, 'default' or 'none'; --list-terms)",
    )
    parser.add_argument(
        "--withhold-alpha",
        type=float,
        default=None,
        help="JSBSim: alpha (deg) above which withheld terms are frozen (default: the "
        "aircraft's, 12 deg F-15, 10 deg DHC6)",
    )
    parser.add_argument(
        "--list-terms", action="store_true", help="JSBSim: list the aircraft's lateral terms"
    )
    parser.add_argument("--no-turbulence", action="store_true", help="calm air")
    parser.add_argument("--no-progress", action="store_true", help="no progress bars")
    parser.add_argument("--no-rolloff", action="store_true", help="no stochastic roll-off")
    parser.add_argument(
        "--excitation", type=float, default=1.0, help="pilot doublets/stick-noise scale"
    )
    parser.add_argument(
        "--cg-range",
        metavar="X,Y,Z",
        help="builtin: per-maneuver CG variation, total range per body axis in m from the datum "
        "(x forward, y right, z down; uniform within +-range/2), e.g. 0.21,0.05,0.10 (10 %% of "
        "c-bar in x); writes mass and inertia columns to the manifest",
    )
    parser.add_argument(
        "--mass-range",
        type=float,
        default=None,
        metavar="F",
        help="builtin: per-maneuver mass variation, total relative range (0.1 = +-5 %%)",
    )
    parser.add_argument(
        "--inertia-range",
        type=float,
        default=None,
        metavar="F",
        help="builtin: per-maneuver variation of each inertia, total relative range (0.1 = +-5 %%)",
    )
    parser.add_argument(
        "--vane-scale",
        metavar="KA,KB",
        help="builtin: scale errors of the alpha and beta vanes (upwash, sidewash), e.g. "
        "0.05,-0.05: each reads (1 + k) times the flow angle at it",
    )
    parser.add_argument(
        "--flank-vane",
        action="store_true",
        help="builtin: the beta vane is a boom yaw vane reading the flank angle atan(v/u)",
    )
    parser.add_argument(
        "--buffet",
        action="store_true",
        help="builtin: stall buffet at the accelerometers (onset 2 deg below each flap's "
        "C_L,max alpha, modes 7.5, 9.2, 12.6 Hz; truth in truth/campaign.json; docs/stall.md)",
    )
    parser.add_argument(
        "--longitudinal-stall",
        choices=("static", "kirchhoff"),
        default=None,
        help="builtin: the truth's lift and pitching moment: the qualified static curves "
        "(default) or a Kirchhoff flow-separation stall (docs/longitudinal.md)",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace an existing folder")
    parser.add_argument("--list-effects", action="store_true", help="list the effect vocabulary")
    parser.add_argument("--out", help="campaign folder to write")


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta campaign``."""
    if args.list_effects:
        for e in effect_library():
            rng = e.get("alpha_range_deg")
            where = f"alpha {rng[0]:g}-{rng[1]:g} deg" if rng else e.get("channels", "")
            terms = ", ".join(
                f"d{t['coef']}/{t['regressor']}={t['design']:+g}" for t in e.get("terms", [])
            )
            print(f"{e['name']:24s} {e['kind']:12s} {where:22s} {terms}")
            print(f"{'':24s} {e['description']}")
        return 0
    _check_options(args)
    if args.simulator == "jsbsim":
        return _run_jsbsim(args)
    if not args.out:
        print("aerodelta campaign: error: --out DIR is required", file=sys.stderr)
        return 2
    _check_out(args)
    info = generate_campaign(
        args.out,
        effects="default" if args.effects is None else args.effects,
        seed=args.seed,
        size="quick" if args.quick else "default",
        noise=args.noise_scale,
        turbulence=0.0
        if args.no_turbulence
        else (0.5 if args.turbulence is None else args.turbulence),
        rolloff=not args.no_rolloff,
        excitation=args.excitation,
        cg_range_m=_cg_range(args.cg_range),
        mass_range=args.mass_range,
        inertia_range=args.inertia_range,
        vane_scale=_pair(args.vane_scale),
        flank_vane=args.flank_vane,
        buffet=args.buffet,
        longitudinal_stall=args.longitudinal_stall or "static",
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    eff = ", ".join(f"{k}={v:g}" for k, v in info.effects.items()) or "none"
    print(f"wrote {info.n_maneuvers} maneuvers to {info.path} (seed {info.seed}; effects: {eff})")
    return 0


def _check_options(args: argparse.Namespace) -> None:
    """Refuse values without meaning and options of the other simulator."""
    for value, option in (
        (args.noise_scale, "--noise-scale"),
        (args.excitation, "--excitation"),
        (args.turbulence, "--turbulence"),
    ):
        if value is not None and not (math.isfinite(value) and value >= 0.0):
            raise InvalidInputError(f"{option} {value:g}: give a finite scale >= 0 (0: none)")
    if args.turbulence is not None and args.no_turbulence:
        raise InvalidInputError("--turbulence and --no-turbulence contradict; give one")
    if args.simulator == "builtin":
        other = {
            "--aircraft": args.aircraft,
            "--withhold": args.withhold,
            "--withhold-alpha": args.withhold_alpha,
            "--list-terms": args.list_terms,
        }
        needs = "--simulator jsbsim"
    else:
        other = {
            "--effects": args.effects,
            "--no-rolloff": args.no_rolloff,
            "--cg-range": args.cg_range,
            "--mass-range": args.mass_range is not None,
            "--inertia-range": args.inertia_range is not None,
            "--vane-scale": args.vane_scale,
            "--flank-vane": args.flank_vane,
            "--buffet": args.buffet,
            "--longitudinal-stall": args.longitudinal_stall,
        }
        needs = "--simulator builtin"
    given = [o for o, v in other.items() if v]
    if given:
        raise InvalidInputError(f"{given[0]} applies to {needs} only; drop it or give {needs}")


def _cg_range(text: str | None) -> tuple[float, float, float] | None:
    """``--cg-range X,Y,Z`` (m) as three floats; ``None`` when not given."""
    if text is None:
        return None
    parts = text.split(",")
    try:
        x, y, z = (float(p) for p in parts)
    except ValueError:
        raise InvalidInputError(
            f"--cg-range {text}: give three total ranges in m, X,Y,Z (e.g. 0.21,0.05,0.10)"
        ) from None
    return (x, y, z)


def _pair(text: str | None) -> tuple[float, float] | None:
    """``--vane-scale KA,KB`` as two floats; ``None`` when not given."""
    if text is None:
        return None
    try:
        ka, kb = (float(p) for p in text.split(","))
    except ValueError:
        raise InvalidInputError(
            f"--vane-scale {text}: give the two vanes' scale errors, KA,KB (e.g. 0.05,-0.05)"
        ) from None
    return (ka, kb)


def _check_out(args: argparse.Namespace) -> None:
    """Refuse a negative seed and an existing --out without --overwrite, before flying."""
    check_at_least(args.seed, "--seed", 0)
    out = output_folder(args.out)
    if out.exists() and not args.overwrite:
        raise InvalidInputError(
            f"--out {out}: exists; choose another folder or give --overwrite to replace it"
        )


def _run_jsbsim(args: argparse.Namespace) -> int:
    from aerodelta.jsbsim_campaign import (  # noqa: PLC0415
        SIDESLIP_NOTE,
        generate_jsbsim_campaign,
        lateral_terms,
    )

    aircraft = args.aircraft or "f15"
    if args.list_terms:
        for t in lateral_terms(aircraft):
            flag = "alpha-dependent" if t["alpha_dependent"] else ""
            print(f"{t['name']:12s} {t['coefficient']:3s} {flag}")
        return 0
    if not args.out:
        print("aerodelta campaign: error: --out DIR is required", file=sys.stderr)
        return 2
    _check_out(args)
    info = generate_jsbsim_campaign(
        args.out,
        aircraft=aircraft,
        seed=args.seed,
        size="quick" if args.quick else "default",
        withhold="default" if args.withhold is None else args.withhold,
        withhold_alpha_deg=args.withhold_alpha,
        noise=args.noise_scale,
        turbulence=0.0 if args.no_turbulence or args.turbulence is None else args.turbulence,
        overwrite=args.overwrite,
        progress=not args.no_progress,
    )
    held = ", ".join(info.withheld) or "none"
    print(
        f"wrote {info.n_maneuvers} maneuvers of JSBSim {info.aircraft} to {info.path} "
        f"(seed {info.seed}; withheld past {info.withhold_alpha_deg:g} deg: {held})"
    )
    short = info.manifest.filter(pl.col("notes").str.contains(SIDESLIP_NOTE, literal=True))
    if short.height:
        flaps = ", ".join(f"{f:g}" for f in sorted(set(short["flap_deg"].to_list())))
        print(
            f"note: {short.height} of {info.manifest.filter(pl.col('entry') == 'sideslip').height}"
            f" sideslip entries held less than half their commanded sideslip (flaps {flaps} deg;"
            " the manifest's notes give each one's sideslip and rudder)"
        )
    return 0
