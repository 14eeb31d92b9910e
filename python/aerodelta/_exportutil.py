"""Shared pieces of the extended-model exports (DAVE-ML and JSBSim).

- :func:`parse_regressor`: the regressor language of ``aero_core::regressor`` as a small tree
  (it is a subset of Python's expression syntax once ``^`` is written ``**``); too deep an
  expression is a ``DataError``, never a ``RecursionError`` or ``MemoryError``;
- :data:`DERIVED_CHANNELS`: Δ-model channels computed from others, as the ingestion does;
- :func:`check_states`: the sampled states where exported models are checked against the engine
  (below, inside and beyond the blend region of Eq. 3.12, at and between flap settings).
"""

from __future__ import annotations

import ast
import itertools
from dataclasses import dataclass
from os import PathLike
from typing import Any

import numpy as np

from aerodelta._fsutil import write_text_atomic
from aerodelta.exceptions import DataError


def write_atomic(path: str | PathLike[str], text: str) -> None:
    """Write ``text`` to ``path`` via ``path.tmp-<pid>`` in the same folder, then rename."""
    write_text_atomic(path, text)


#: Channels of the Δ model that are computed from other channels (as in
#: ``aerodelta.preprocess``: ``ct_diff = ct_left - ct_right``; the combined roll spoiler
#: ``ds = dsr - dsl``, thesis Eq. 3.18 with signed sides).
DERIVED_CHANNELS: dict[str, str] = {
    "ct_diff": "ct_left - ct_right",
    "ds_deg": "dsr_deg - dsl_deg",
}

_FUNCS = {
    "pos": 1, "neg": 1, "deadband": 2, "step": 1, "abs": 1, "sqrt": 1, "sin": 1, "cos": 1,
    "exp": 1, "min": 2, "max": 2,
}  # fmt: skip


@dataclass(frozen=True)
class Node:
    """A regressor expression node: ``op`` is ``const`` (value), ``col`` (name), ``minus``
    (negation), ``+ - * / ^`` (two args) or a function name (``pos``, ``neg``, ...)."""

    op: str
    args: tuple[Node, ...] = ()
    value: float = 0.0
    name: str = ""


#: Limits of the regressor language, as ``aero_core::regressor::MAX_NESTING`` and
#: ``MAX_DEPTH``: levels of parentheses, function arguments, unary minus and ``^`` open at
#: once, and nodes from the root of the expression tree to its deepest leaf.
MAX_NESTING = 64
MAX_DEPTH = 256


def shown(src: str) -> str:
    """``src`` for messages: whole up to 200 characters, else its start and its length."""
    return src if len(src) <= 200 else f"{src[:120]}... ({len(src)} characters)"


def _tree_depth(tree: ast.AST) -> int:
    """Depth of an expression tree in nodes (a leaf is 1, ``a + b`` is 2), without recursion;
    a negated number is one leaf, as the engine folds it."""
    deepest = 0
    stack: list[tuple[ast.AST, int]] = [(tree, 1)]
    while stack:
        n, d = stack.pop()
        deepest = max(deepest, d)
        if isinstance(n, ast.UnaryOp):
            inner = n.operand
            while isinstance(inner, ast.UnaryOp):
                inner = inner.operand
            if not isinstance(inner, ast.Constant):
                stack.append((n.operand, d + 1))
        elif isinstance(n, ast.BinOp):
            stack += [(n.left, d + 1), (n.right, d + 1)]
        elif isinstance(n, ast.Call):
            stack += [(a, d + 1) for a in n.args]
    return deepest


def parse_regressor(src: str) -> Node:
    """Parse a regressor expression (grammar of ``aero_core::regressor``).

    Raises
    ------
    DataError
        Naming the expression and the unsupported construct; or an expression deeper than
        :data:`MAX_DEPTH`, or nested too deeply for Python's parser (the engine refuses more
        than :data:`MAX_NESTING` levels already).
    """
    try:
        tree = ast.parse(src.replace("^", "**"), mode="eval").body
    except SyntaxError as e:
        if "too many nested" in str(e.msg):
            raise DataError(_too_nested(src)) from None
        raise DataError(f"regressor '{shown(src)}': not an expression ({e.msg})") from None
    except (MemoryError, RecursionError):
        # CPython's parser gives up on deep nesting (unary minus, **) this way
        raise DataError(_too_nested(src)) from None
    depth = _tree_depth(tree)
    if depth > MAX_DEPTH:
        raise DataError(
            f"regressor '{shown(src)}': is {depth} operations deep (each operator and function "
            f"call on the way down counts, so a chain a + b + c is 3); at most {MAX_DEPTH} are "
            "supported; split it into several regressors"
        )

    def walk(n: ast.AST) -> Node:
        if isinstance(n, ast.Constant) and isinstance(n.value, int | float):
            return Node("const", value=float(n.value))
        if isinstance(n, ast.Name):
            return Node("col", name=n.id)
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.USub):
            return Node("minus", (walk(n.operand),))
        if isinstance(n, ast.UnaryOp) and isinstance(n.op, ast.UAdd):
            return walk(n.operand)
        ops = {ast.Add: "+", ast.Sub: "-", ast.Mult: "*", ast.Div: "/", ast.Pow: "^"}
        if isinstance(n, ast.BinOp) and type(n.op) in ops:
            return Node(ops[type(n.op)], (walk(n.left), walk(n.right)))
        if (
            isinstance(n, ast.Call)
            and isinstance(n.func, ast.Name)
            and _FUNCS.get(n.func.id) == len(n.args)
            and not n.keywords
        ):
            return Node(n.func.id, tuple(walk(a) for a in n.args))
        raise DataError(
            f"regressor '{shown(src)}': unsupported construct '{shown(ast.unparse(n))}'"
        )

    return walk(tree)


def _too_nested(src: str) -> str:
    return (
        f"regressor '{shown(src)}': nests too deeply to parse; at most {MAX_NESTING} levels of "
        "parentheses, function arguments, unary minus and ^ exponents are supported; simplify "
        "the expression"
    )


def columns(node: Node) -> list[str]:
    """Column names an expression reads, in first-use order."""
    out: list[str] = []

    def walk(n: Node) -> None:
        if n.op == "col" and n.name not in out:
            out.append(n.name)
        for a in n.args:
            walk(a)

    walk(node)
    return out


def units_of(channel: str) -> str:
    """DAVE-ML units of a channel from its name's suffix (``_deg``, ``_dps``, ``_rad``, ...)."""
    for suffix, units in (("_deg", "deg"), ("_dps", "deg_s"), ("_rad", "rad"), ("_rps", "rad_s")):
        if channel.endswith(suffix):
            return units
    return "nd"


#: Ranges (low, high) the sampled check states draw each channel from.
_RANGES: dict[str, tuple[float, float]] = {
    "beta_deg": (-12.0, 12.0),
    "beta_rad": (-0.2, 0.2),
    "phat": (-0.04, 0.04),
    "qhat": (-0.02, 0.02),
    "rhat": (-0.04, 0.04),
    "alphadot_hat": (-0.01, 0.01),
    "alphadot_dps": (-8.0, 8.0),
    "betadot_dps": (-8.0, 8.0),
    "da_deg": (-15.0, 15.0),
    "dr_deg": (-15.0, 15.0),
    "de_deg": (-10.0, 10.0),
    "de_rad": (-0.15, 0.15),
    "ct_left": (0.0, 0.4),
    "ct_right": (0.0, 0.4),
    "x_sep": (0.0, 1.0),
}


def check_states(
    flaps_deg: list[float],
    blend: dict[str, tuple[list[float], list[float]]],
    alpha_max_deg: float,
    channels: list[str],
    seed: int = 0,
) -> list[dict[str, Any]]:
    """Sampled states where an exported model is checked against the engine.

    Flap settings: each of the model's, the midpoints between them and one beyond each end.
    Angles of attack, per flap: below the blend start ``alpha_l``, inside the blend, just past
    ``alpha_u``, half way to the table end and beyond the table end (held values). Other
    channels are drawn uniformly from representative ranges (seeded); the roll spoiler
    deploys one side at a time.

    Returns
    -------
    list of dict
        ``{"name": str, "inputs": {channel: value}}`` (angles in deg as the channels name).
    """
    rng = np.random.default_rng(seed)
    f = sorted(flaps_deg)
    mids = [0.5 * (a + b) for a, b in itertools.pairwise(f)]
    flap_cases = [*f, *mids, f[0] - 5.0, f[-1] + 5.0]
    states = []
    for flap in flap_cases:
        ls = [float(np.interp(flap, f, bl)) for bl, _ in blend.values()]
        us = [float(np.interp(flap, f, bu)) for _, bu in blend.values()]
        al, au = min(ls), max(us)
        alphas = {
            "below blend": al - 3.0,
            "in blend": al + 0.37 * max(au - al, 0.5),
            "past blend": au + 0.8,
            "stall": 0.5 * (au + alpha_max_deg),
            "beyond tables": alpha_max_deg + 4.0,
        }
        for label, alpha in alphas.items():
            inputs: dict[str, float] = {"alpha_deg": float(alpha), "flap_deg": float(flap)}
            for c in channels:
                if c in inputs:
                    continue
                if c in _RANGES:
                    a, b = _RANGES[c]
                    inputs[c] = float(rng.uniform(a, b))
            side = "dsl_deg" if rng.uniform() < 0.5 else "dsr_deg"
            for s in ("dsl_deg", "dsr_deg"):
                if s in channels:
                    inputs[s] = float(rng.uniform(0.0, 25.0)) if s == side else 0.0
            states.append({"name": f"flap {flap:g}, {label} (alpha {alpha:.3f})", "inputs": inputs})
    return states
