"""Channel maps (TOML): rename a user's channels onto the canonical schema and convert their
units once, explicitly.

Format::

    [channels]
    t = { source = "Time", unit = "s" }
    alpha_deg = { source = "AOA", unit = "rad" }
    tas_mps = { source = "KTAS", unit = "kt" }
    ay_mps2 = { source = "NY", unit = "g", scale = 1.0, offset = 0.0 }

Each entry: ``source`` (the user's column), ``unit`` (declared unit of that column) and
optional ``scale`` and ``offset`` applied in the declared unit before conversion:
``canonical = convert(raw * scale + offset, unit -> canonical unit)``. Canonical columns not in
the map pass through unchanged (they are taken to be in canonical units already).

A line still carrying a ``# REVIEW`` comment (a guess of :mod:`aerodelta.map_template`) is
refused, naming the lines: the guesses are checked by a person before they are used.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import polars as pl

from aerodelta._toml import read_toml
from aerodelta.channels import CHANNELS
from aerodelta.exceptions import DataError
from aerodelta.units import canonical_name, factor_offset

#: The keys of one channel's entry.
_ENTRY_KEYS = ("source", "unit", "scale", "offset")

_STRING = re.compile(r'"(?:[^"\\\n]|\\.)*"|\'[^\'\n]*\'')
_REVIEW = re.compile(r"#\s*REVIEW\b")


def unreviewed_lines(text: str) -> list[tuple[int, str]]:
    """``(line number, key)`` of every line with a ``# REVIEW`` comment outside strings.

    >>> unreviewed_lines('[channels]\\nt = { source = "T", unit = "s" }  # REVIEW: guessed\\n')
    [(2, 't')]
    """
    out = []
    for n, line in enumerate(text.splitlines(), start=1):
        code = _STRING.sub('""', line)
        if _REVIEW.search(code):
            out.append((n, code.split("=")[0].strip().lstrip("#").strip() or "(comment)"))
    return out


@dataclass(frozen=True)
class ChannelEntry:
    """One mapped channel: canonical ``name`` <- user ``source`` in ``unit``."""

    name: str
    source: str
    unit: str
    scale: float = 1.0
    offset: float = 0.0


@dataclass(frozen=True)
class ChannelMap:
    """A validated channel map; see the module docstring for the TOML format."""

    entries: tuple[ChannelEntry, ...]
    source: str = "<dict>"

    @classmethod
    def from_toml(cls, path: str | Path) -> ChannelMap:
        """Read and validate a channel map TOML file.

        Raises
        ------
        DataError
            Unknown canonical names, units or dimension mismatches, naming the entry.
        """
        path = Path(path)
        doc, text = read_toml(path, "channel map")
        review = unreviewed_lines(text)
        if review:
            shown = ", ".join(f"line {n} {key}" for n, key in review[:12])
            more = f" and {len(review) - 12} more" if len(review) > 12 else ""
            raise DataError(
                f"{path}: {len(review)} guess(es) of aerodelta map-template not reviewed yet "
                f"({shown}{more}): check each line's column, unit and sign against the data, "
                "fix what is wrong, then delete its '# REVIEW' mark"
            )
        return cls.from_dict(doc, source=str(path))

    @classmethod
    def from_dict(cls, doc: dict[str, Any], source: str = "<dict>") -> ChannelMap:
        """Build from the parsed TOML structure."""
        chans = doc.get("channels")
        if not isinstance(chans, dict) or not chans:
            raise DataError(f"{source}: a [channels] table with at least one entry is required")
        entries = []
        problems = [
            f"unknown table or key '{k}' (a channel map holds one [channels] table)"
            for k in doc
            if k != "channels"
        ]
        for name, spec in chans.items():
            if name not in CHANNELS:
                problems.append(f"'{name}' is not a canonical channel (docs/data.md)")
                continue
            if not isinstance(spec, dict) or "source" not in spec or "unit" not in spec:
                problems.append(f'\'{name}\' needs {{ source = "COLUMN", unit = "UNIT" }}')
                continue
            unknown = sorted(set(spec) - set(_ENTRY_KEYS))
            if unknown:
                problems.append(
                    f"'{name}': unknown key(s) {', '.join(unknown)} (known: "
                    f"{', '.join(_ENTRY_KEYS)})"
                )
                continue
            src, unit = spec["source"], spec["unit"]
            if not isinstance(src, str) or not src:
                problems.append(f"'{name}': source = {src!r} must be a column name (a string)")
                continue
            if not isinstance(unit, str):
                problems.append(f"'{name}': unit = {unit!r} must be a string (e.g. \"deg\")")
                continue
            try:
                factor_offset(unit, CHANNELS[name].unit)
            except DataError as e:
                problems.append(f"'{name}': {e}")
                continue
            nums = {k: spec.get(k, d) for k, d in (("scale", 1.0), ("offset", 0.0))}
            bad = [
                f"'{name}': {k} = {v!r} must be a finite number"
                for k, v in nums.items()
                if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v)
            ]
            if not bad and nums["scale"] == 0:
                bad.append(f"'{name}': scale = 0 would make every value the offset")
            if bad:
                problems += bad
                continue
            entries.append(
                ChannelEntry(
                    name=name,
                    source=src,
                    unit=canonical_name(unit),
                    scale=float(nums["scale"]),
                    offset=float(nums["offset"]),
                )
            )
        seen: dict[str, str] = {}
        for e in entries:
            if e.source in seen:
                problems.append(
                    f"column '{e.source}' is mapped to both '{seen[e.source]}' and '{e.name}'; "
                    "map each column once"
                )
            seen.setdefault(e.source, e.name)
        if problems:
            raise DataError(f"{source}: invalid channel map: " + "; ".join(problems))
        return cls(tuple(entries), source)

    def apply(self, lf: pl.LazyFrame, file: str) -> pl.LazyFrame:
        """Rename and convert the mapped columns of ``lf`` (lazily).

        Raises
        ------
        DataError
            When a mapped source column is absent from ``file``.
        """
        schema = lf.collect_schema()
        have = set(schema.names())
        missing = [f"'{e.source}' (for {e.name})" for e in self.entries if e.source not in have]
        if missing:
            raise DataError(
                f"{file}: channel map {self.source} names columns the file lacks: "
                + ", ".join(missing)
                + f"; the file has: {', '.join(sorted(have))}"
            )
        for e in self.entries:
            dtype = schema[e.source]
            if not (dtype.is_numeric() or dtype == pl.Utf8):
                what = "true/false" if dtype == pl.Boolean else str(dtype)
                raise DataError(
                    f"{file}: column '{e.source}' (mapped to {e.name}) holds {what} values, not "
                    "numbers"
                )
        mapped = {e.name for e in self.entries}
        sources = {e.source for e in self.entries}
        exprs = []
        for e in self.entries:
            k, o = factor_offset(e.unit, CHANNELS[e.name].unit)
            expr = pl.col(e.source).cast(pl.Float64)
            if e.scale != 1.0 or e.offset != 0.0:
                expr = expr * e.scale + e.offset
            if k != 1.0 or o != 0.0:
                expr = expr * k + o
            exprs.append(expr.alias(e.name))
        passthrough = [
            pl.col(c)
            for c in sorted(have)
            if c not in mapped and c not in sources and (c in CHANNELS or c == "maneuver_id")
        ]
        return lf.select(exprs + passthrough)
