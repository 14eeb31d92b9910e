"""Run the docstring examples of every public module of the installed package."""

from __future__ import annotations

import doctest
import importlib
import pkgutil

import pytest

import aerodelta

MODULES = sorted(
    m.name
    for m in pkgutil.walk_packages(aerodelta.__path__, prefix="aerodelta.")
    if not m.name.split(".")[-1].startswith("_")
)


@pytest.mark.parametrize("name", MODULES)
def test_docstring_examples(name: str) -> None:
    module = importlib.import_module(name)
    result = doctest.testmod(module, optionflags=doctest.ELLIPSIS | doctest.NORMALIZE_WHITESPACE)
    assert result.failed == 0, f"{result.failed} doctest(s) failed in {name}"
