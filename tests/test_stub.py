"""The type stub python/aerodelta/_core.pyi names exactly what the built extension exports."""

from __future__ import annotations

import ast
import inspect
from pathlib import Path

import aerodelta._core as core

STUB = Path(__file__).resolve().parent.parent / "python" / "aerodelta" / "_core.pyi"


def _stub_names() -> dict[str, set[str]]:
    tree = ast.parse(STUB.read_text())
    names: dict[str, set[str]] = {}
    for node in tree.body:
        if isinstance(node, ast.ClassDef):
            names[node.name] = {
                n.name for n in node.body if isinstance(n, ast.FunctionDef | ast.AsyncFunctionDef)
            }
        elif isinstance(node, ast.FunctionDef):
            names[node.name] = set()
        elif isinstance(node, ast.AnnAssign) and isinstance(node.target, ast.Name):
            names[node.target.id] = set()
    return names


def test_stub_matches_extension() -> None:
    stub = _stub_names()
    runtime = {n for n in dir(core) if not n.startswith("_")} | {"__version__"}
    assert set(stub) - runtime == set(), "stub names missing from the extension"
    assert runtime - set(stub) == set(), "extension names missing from the stub"
    for name, methods in stub.items():
        obj = getattr(core, name)
        if inspect.isclass(obj) and not issubclass(obj, BaseException):
            public = {m for m in vars(obj) if not m.startswith("_")}
            declared = {m for m in methods if not m.startswith("_")}
            assert declared == public, (
                f"{name}: stub {sorted(declared)} vs runtime {sorted(public)}"
            )
