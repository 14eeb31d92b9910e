"""Export a fitted extended model (qualified + blended Δ, thesis Eq. 3.12).

DAVE-ML (--daveml): the qualified DAVE-ML file (--qualified, default the built-in ADX-37
model) with the Δ tables, regressors and blend weights merged in, outputs dC, w_C and C_ext
per coefficient, and check cases at sampled states verified against the engine; check it with
``aerodelta check-daveml``. JSBSim (--jsbsim): an <aerodynamics> file adding w ΔC to the
SIDE, ROLL and YAW axes of an aircraft that holds the qualified model (with --jsbsim-qualified:
the built-in qualified CY, Cl, Cn too); see docs/export.md for the properties it reads. A
model carrying its Kirchhoff stall exports it to DAVE-ML as the state x_sep, and to JSBSim as
lift and pitching-moment increments whose separation state a <system> file (--jsbsim-system)
carries between frames; --no-longitudinal leaves it out of both."""

from __future__ import annotations

import argparse
import itertools
import re
import sys
from contextlib import ExitStack

from aerodelta.cli._data import (
    check_at_least,
    check_outputs,
    created,
    existing_file,
    load_model,
    output_file,
)
from aerodelta.exceptions import DataError
from aerodelta.export import export_extended_daveml
from aerodelta.jsbsim import (
    export_jsbsim,
    jsbsim_properties,
    stall_axes_for,
    stall_system_problem,
)

HELP = "export the extended model to DAVE-ML and/or JSBSim"


def _pairs(items: list[str] | None, what: str) -> dict[str, str]:
    out = {}
    for item in items or []:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise DataError(f"{what} '{item}': write NAME=VALUE")
        out[key.strip()] = value.strip()
    return out


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``aerodelta export``."""
    parser.add_argument("--model", required=True, help="Δ model file from aerodelta fit (.json)")
    parser.add_argument(
        "--qualified", help="qualified model as DAVE-ML (default: the built-in ADX-37 model)"
    )
    parser.add_argument("--daveml", help="extended model to write as DAVE-ML (.dml)")
    parser.add_argument("--jsbsim", help="Δ increments to write as JSBSim <aerodynamics> (.xml)")
    parser.add_argument(
        "--map",
        action="append",
        metavar="CHANNEL=EXPR",
        help="DAVE-ML: a Δ-model channel as an expression of qualified-model variables, "
        "e.g. alpha_deg=alpha (repeatable)",
    )
    parser.add_argument(
        "--coef",
        action="append",
        metavar="C=VARID",
        help="DAVE-ML: the qualified-model variable of a coefficient, e.g. Cl=Cl_total (and "
        "CL=..., Cm=... for the totals a stored Kirchhoff stall reads)",
    )
    parser.add_argument(
        "--property",
        action="append",
        metavar="CHANNEL=PROP",
        help="JSBSim: the property (or '*'-product of properties and numbers) of a channel, "
        "e.g. da_deg=-1*fcs/left-aileron-pos-deg (repeatable)",
    )
    parser.add_argument(
        "--side-axis",
        choices=["SIDE", "Y"],
        help="JSBSim: axis of the side force (SIDE for AXIAL/NORMAL or DRAG/LIFT aircraft, "
        "the default; Y for X/Y/Z aircraft); a stored stall's lift goes on LIFT with SIDE "
        "(DRAG/LIFT aircraft), on X and Z with Y",
    )
    parser.add_argument(
        "--stall-axes",
        choices=["LIFT", "AXIAL", "X"],
        help="JSBSim: axes of a stored stall's lift and drag increments: LIFT (LIFT, DRAG; "
        "the default with --side-axis SIDE), AXIAL (AXIAL, NORMAL: an AXIAL/SIDE/NORMAL "
        "aircraft) or X (X, Z; with --side-axis Y)",
    )
    parser.add_argument(
        "--jsbsim-qualified",
        action="store_true",
        help="JSBSim: also write the built-in ADX-37 qualified CY, Cl, Cn, so the axes carry "
        "the whole extended lateral-directional model",
    )
    parser.add_argument(
        "--jsbsim-system",
        metavar="OUT.xml",
        help="JSBSim: the <system> file carrying the separation state of the model's "
        "Kirchhoff stall from frame to frame (needed when the model stores one; load it with "
        "the aircraft)",
    )
    parser.add_argument("--seed", type=int, default=0, help="seed of the sampled check states")
    parser.add_argument(
        "--no-longitudinal",
        action="store_true",
        help="leave out the Kirchhoff stall the model stores (aerodelta longitudinal "
        "--model M --out-model M2); by default DAVE-ML carries it as the state x_sep with "
        "x_sep_dot, CL_ext, Cm_ext (CD_ext with a stored drag), and JSBSim as increments on "
        "LIFT (DRAG; or X, Z) and PITCH reading the --jsbsim-system file",
    )


def _usage(message: str) -> int:
    """A refused combination of options: one error line, status 2 (as argparse's)."""
    print(f"aerodelta export: error: {message} (see aerodelta export --help)", file=sys.stderr)
    return 2


def _known(pairs: dict[str, str], option: str, known: list[str], what: str) -> None:
    unknown = [k for k in pairs if k not in known]
    if unknown:
        k = unknown[0]
        raise DataError(
            f"{option} {k}={pairs[k]}: the model has no {what} '{k}' (it has: {', '.join(known)})"
        )


def run(args: argparse.Namespace) -> int:
    """Run ``aerodelta export``."""
    if not args.daveml and not args.jsbsim:
        return _usage("give --daveml OUT.dml and/or --jsbsim OUT.xml")
    if args.jsbsim_qualified and args.qualified:
        return _usage(
            "--jsbsim-qualified writes the built-in ADX-37 qualified model; a --qualified "
            "DAVE-ML file is not translated to JSBSim"
        )
    for given, option, needs, value in (
        (args.property, "--property", "--jsbsim", args.jsbsim),
        (args.side_axis, "--side-axis", "--jsbsim", args.jsbsim),
        (args.stall_axes, "--stall-axes", "--jsbsim", args.jsbsim),
        (args.jsbsim_qualified, "--jsbsim-qualified", "--jsbsim", args.jsbsim),
        (args.map, "--map", "--daveml", args.daveml),
        (args.coef, "--coef", "--daveml", args.daveml),
        (args.qualified, "--qualified", "--daveml", args.daveml),
        (args.jsbsim_system, "--jsbsim-system", "--jsbsim", args.jsbsim),
    ):
        if given and not value:
            return _usage(f"{option} applies to the {needs} export; give {needs} OUT too")
    if args.no_longitudinal and not (args.daveml or args.jsbsim):
        return _usage("--no-longitudinal applies to an export; give --daveml or --jsbsim")
    if args.jsbsim_system and args.no_longitudinal:
        return _usage("--jsbsim-system carries the stall that --no-longitudinal leaves out")
    check_at_least(args.seed, "--seed", 0)
    model_file = existing_file(args.model, "--model")
    qualified = existing_file(args.qualified, "--qualified")
    outs = {
        o: output_file(v, o, example)
        for v, o, example in (
            (args.daveml, "--daveml", "extended.dml"),
            (args.jsbsim, "--jsbsim", "delta.xml"),
            (args.jsbsim_system, "--jsbsim-system", "stall-system.xml"),
        )
        if v
    }
    for a, b in itertools.combinations(outs, 2):
        if outs[a].resolve() == outs[b].resolve():
            raise DataError(f"{a} and {b} name the same file {outs[a]}; give two files")
    check_outputs(None, "--daveml" if args.daveml else "--jsbsim", files=list(outs.values()),
                  inputs=[model_file, qualified])  # fmt: skip
    model = load_model(model_file)
    if args.jsbsim:  # before anything is written
        problem = stall_system_problem(model, not args.no_longitudinal, args.jsbsim_system)
        if problem is not None:
            return _usage(problem)
    channel_map = _pairs(args.map, "--map")
    coefs = _pairs(args.coef, "--coef")
    props = _pairs(args.property, "--property")
    _known(channel_map, "--map", model.input_columns, "channel")
    # a stored stall also reads the qualified CL and Cm totals
    stall_coefs = (
        ["CL", "Cm", *(["CD"] if model.kirchhoff_drag else [])]
        if model.kirchhoff and not args.no_longitudinal
        else []
    )
    _known(coefs, "--coef", [*model.coefficients, *stall_coefs], "coefficient")
    _known(props, "--property", model.input_columns, "channel")
    if args.jsbsim:
        try:  # every property checked before anything is written
            jsbsim_properties(model, props, longitudinal=not args.no_longitudinal)
        except DataError as e:
            raise DataError(f"--property: {e}") from None
    side_axis = args.side_axis or "SIDE"
    if args.jsbsim:
        try:  # checked before anything is written
            stall_axes_for(side_axis, args.stall_axes)
        except DataError as e:
            return _usage(str(e))
    with ExitStack() as stack:
        for p in outs.values():  # folders made for the files; removed if the export fails
            stack.enter_context(created(p.parent))
        if args.daveml:
            out = export_extended_daveml(
                args.daveml,
                model,
                args.qualified,
                channel_map=channel_map,
                coefficients=coefs,
                seed=args.seed,
                longitudinal=not args.no_longitudinal,
            )
            print(
                f"wrote {args.daveml}: outputs {', '.join(out.model.outputs)}; {out.n_checks} "
                f"check cases, largest relative difference to the engine {out.max_rel_error:.2e}"
            )
            if model.kirchhoff and not args.no_longitudinal:
                print(
                    f"  longitudinal stall at flaps "
                    f"{', '.join(f'{f:g}' for f in sorted(model.kirchhoff))} deg: the host "
                    "integrates the input x_sep from x_sep_dot (start at x_sep_0) and flies "
                    + ("CL_ext, Cm_ext, CD_ext" if model.kirchhoff_drag else "CL_ext, Cm_ext")
                )
        if args.jsbsim:
            export_jsbsim(
                args.jsbsim,
                model,
                props,
                side_axis=side_axis,
                qualified=args.jsbsim_qualified,
                longitudinal=not args.no_longitudinal,
                system_path=args.jsbsim_system,
                stall_axes=args.stall_axes,
            )
    if args.jsbsim:
        print(f"wrote {args.jsbsim}: channels read from JSBSim properties:")
        mapped = jsbsim_properties(model, props, longitudinal=not args.no_longitudinal)
        for ch, prop in mapped.items():
            print(f"  {ch:<14} {prop}")
        # properties the file declares (value 0): nothing in JSBSim sets them by itself
        undriven = sorted(
            {p for p in re.findall(r"(?<![\w/])aerodelta/[\w.-]+", " ".join(mapped.values()))}
        )
        if args.jsbsim_system:
            kind = args.stall_axes or ("X" if side_axis == "Y" else "LIFT")
            axes = {
                "X": "X, Z",
                "AXIAL": "AXIAL, NORMAL",
                "LIFT": "LIFT, DRAG" if model.kirchhoff_drag else "LIFT",
            }[kind]
            print(
                f"wrote {args.jsbsim_system}: the <system> carrying the separation state of "
                f"the stall at flaps {', '.join(f'{f:g}' for f in sorted(model.kirchhoff or {}))}"
                f" deg; load it with the aircraft (the aerodynamics' {axes} and PITCH "
                "increments read it)"
            )
        if undriven:
            print(
                f"aerodelta export: warning: the file declares {', '.join(undriven)} (value "
                "0): your aircraft must set them (e.g. from a <system> with its sign "
                "convention), or map the channels to its own properties with --property "
                "CHANNEL=PROPERTY; left at 0, every Δ term reading them is zero",
                file=sys.stderr,
            )
    return 0
