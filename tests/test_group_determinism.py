"""Grouped float aggregations summed in row order (``aerodelta._groups``), and the outputs that
use them: the same bytes for any polars thread count and from one call to the next.

A polars ``group_by(...).agg(pl.col(x).mean())`` (sum, std...) of floats splits its additions
over the thread pool: with few, large groups the last digits followed ``POLARS_MAX_THREADS``
and changed between calls (pola-rs/polars#6157, #25163)."""

from __future__ import annotations

import doctest
import functools
import math
import operator
import os
import subprocess
import sys
import textwrap

import numpy as np
import polars as pl
import pytest

from aerodelta import _groups
from aerodelta._groups import Groups, group_agg

# --- the helper against a per-group reference ---------------------------------------------


def _random_frame(seed: int, n: int = 4000) -> pl.DataFrame:
    """Keys with nulls, NaN and -0.0; values with nulls and NaN (in a few groups only)."""
    rng = np.random.default_rng(seed)
    f = rng.choice([0.0, -0.0, 5.0, 15.0, np.nan], n)
    k = rng.choice(["a", "bb", "c"], n).astype(object)
    k[rng.random(n) < 0.05] = None
    b = rng.integers(-3, 4, n)
    x = rng.standard_normal(n) * 10.0 ** rng.integers(-3, 4, n)
    x[(b == 2) & (rng.random(n) < 0.1)] = np.nan  # NaN only in bin 2
    xs = pl.Series("x", x).scatter(np.flatnonzero(rng.random(n) < 0.1), None)
    y = pl.Series("y", rng.uniform(0.0, 1.0, n)).scatter(np.flatnonzero(b == -3), None)
    return pl.DataFrame(
        {
            "f": pl.Series(f).scatter(np.flatnonzero(rng.random(n) < 0.03), None),
            "k": pl.Series(list(k), dtype=pl.String),
            "b": b,
            "x": xs,
            "y": y,
        }
    )


def _reference(values: list[float | None], how: str) -> float | None:
    """``how`` of one group's values as polars defines it, by math.fsum (exact sums)."""
    v = [x for x in values if x is not None]
    if any(math.isnan(x) for x in v):
        return None if how in ("std", "var") and len(v) <= 1 else math.nan
    if how == "sum":
        return math.fsum(v)
    if not v or (how in ("std", "var") and len(v) <= 1):
        return None
    mean = math.fsum(v) / len(v)
    if how == "mean":
        return mean
    var = math.fsum((x - mean) ** 2 for x in v) / (len(v) - 1)
    return var if how == "var" else math.sqrt(var)


def _same(got: float | None, want: float | None) -> bool:
    if got is None or want is None:
        return got is None and want is None
    if math.isnan(want):
        return math.isnan(got)
    return got == pytest.approx(want, rel=1e-12, abs=1e-12 * (1.0 + abs(want)))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_group_agg_against_per_group_fsum(seed: int) -> None:
    df = _random_frame(seed)
    keys = ["f", "k", "b"]
    aggs = {f"{c}_{h}": (c, h) for c in ("x", "y") for h in ("sum", "mean", "std", "var")}
    got = group_agg(df, keys, aggs, exact=[pl.len().alias("n")])  # type: ignore[arg-type]
    # the groups, their order (sorted by the keys) and the key values: polars' own
    want = df.group_by(keys).agg(pl.len().alias("n")).sort(keys)
    assert got.select(*keys, "n").equals(want)
    assert dict(got.schema) == {
        **dict(df.select(keys).schema),
        "n": pl.UInt32,
        **dict.fromkeys(aggs, pl.Float64),
    }
    # the values: per group by math.fsum on the group's rows
    rows = df.with_row_index("_i").group_by(keys).agg(pl.col("x"), pl.col("y")).sort(keys)
    for r_got, r_rows in zip(got.iter_rows(named=True), rows.iter_rows(named=True), strict=True):
        for name, (col, how) in aggs.items():
            want_v = _reference(r_rows[col], how)
            assert _same(r_got[name], want_v), (r_got, name, want_v)
    # and polars' nulls exactly (NaN where polars gives NaN)
    pol = df.group_by(keys).agg(getattr(pl.col(c), h)().alias(n) for n, (c, h) in aggs.items())
    pol = pol.sort(keys)
    for name in aggs:
        assert got[name].is_null().equals(pol[name].is_null()), name
        assert got[name].is_nan().equals(pol[name].is_nan()), name


def test_group_keys_merge_like_polars() -> None:
    # NaN with NaN, -0.0 with 0.0, null its own group sorted first; string and boolean keys
    df = pl.DataFrame(
        {
            "f": [0.0, -0.0, float("nan"), None, 1.0, float("nan")],
            "s": ["a", "a", "a", "a", "a", "a"],
            "t": [True, True, False, False, None, False],
            "v": [1.0, 2.0, 3.0, 4.0, 5.0, 6.0],
        }
    )
    got = group_agg(df, ["f", "s", "t"], {"v": ("v", "sum")})
    want = df.group_by(["f", "s", "t"]).agg(pl.col("v").sum()).sort(["f", "s", "t"])
    assert got.equals(want)
    assert got["v"].to_list() == [4.0, 3.0, 5.0, 9.0]


@pytest.mark.parametrize("dtype", [pl.Float64, pl.Int32])
def test_whole_number_keys_group_as_polars_sorts_them(dtype: pl.DataType) -> None:
    """One key of whole numbers (negative, -0.0 with 0.0, gaps) takes the table instead of
    the sort: the same groups, order and first rows as polars' group-by sorted by the key;
    a wild value (1e9 among small ones) takes the sort and agrees too."""
    rng = np.random.default_rng(4)
    v = rng.integers(-30, 30, 500).astype(float)
    v[v == 0] = -0.0
    v[:7] = 0.0
    for values in (v, np.append(v, 1e9)):
        if dtype == pl.Int32 and values.max() > 1e6:
            continue
        df = pl.DataFrame({"k": pl.Series(values).cast(dtype)})
        g = Groups.of(df, ["k"])
        want = (
            df.with_row_index("row")
            .group_by("k")
            .agg(pl.col("row").min().alias("first"), pl.len().alias("n"))
            .sort("k")
        )
        assert g.keys["k"].to_list() == want["k"].to_list()
        assert g.first.tolist() == want["first"].to_list()
        assert np.bincount(g.index).tolist() == want["n"].to_list()
        assert (g.keys["k"].to_numpy()[g.index] == df["k"].to_numpy()).all()


def _polars_groups(df: pl.DataFrame, keys: list[str]) -> pl.DataFrame:
    """The reference: polars' own group-by, its first row and size per group, sorted by the
    keys (nulls first)."""
    return (
        df.with_row_index("row")
        .group_by(keys)
        .agg(pl.col("row").min().alias("first"), pl.len().alias("n"))
        .sort(keys, nulls_last=False)
    )


@pytest.mark.parametrize(
    "keys",
    [
        ["i8"],  # the whole range of a narrow integer (offsets past its dtype)
        ["u64"],  # values past Int64 and far apart: the rank, not the table
        ["i64n", "s"],  # integers with nulls, strings with nulls and an empty string
        ["s", "f", "t"],  # strings, floats with NaN, -0.0 and null, booleans
        ["i8", "u64", "s", "f", "i64n", "t"],  # past the table: compacted by a sort midway
    ],
)
def test_keys_of_every_dtype_group_as_polars_sorts_them(keys: list[str]) -> None:
    """Each key is coded by its dense rank (a table for whole numbers over a short span, the
    sorted distinct values for strings, polars' rank otherwise), the codes mixed into one
    integer: the groups, their order and their first rows are polars' group-by sorted by the
    keys, whichever path a key takes."""
    rng = np.random.default_rng(11)
    n = 3000
    s = rng.choice(["", "a", "b", "ab", "Z", "é"], n).astype(object)
    s[rng.random(n) < 0.05] = None
    f = rng.choice([0.0, -0.0, 2.5, -1.0, np.nan], n)
    df = pl.DataFrame(
        {
            "i8": pl.Series(rng.integers(-128, 128, n), dtype=pl.Int8),
            "u64": pl.Series(
                np.array([0, 5, 2**63 + 7, 2**64 - 1], dtype=np.uint64)[rng.integers(0, 4, n)]
            ),
            "i64n": pl.Series(rng.integers(-5, 6, n)).scatter(
                np.flatnonzero(rng.random(n) < 0.05), None
            ),
            "s": pl.Series(list(s), dtype=pl.String),
            "f": pl.Series(f).scatter(np.flatnonzero(rng.random(n) < 0.05), None),
            "t": pl.Series(rng.random(n) < 0.5).scatter(np.flatnonzero(rng.random(n) < 0.05), None),
        }
    )
    g = Groups.of(df, keys)
    want = _polars_groups(df, keys)
    assert g.keys.equals(want.select(keys))
    assert g.first.tolist() == want["first"].to_list()
    assert np.bincount(g.index, minlength=g.size).tolist() == want["n"].to_list()
    # every row's group holds its keys (nulls and NaN compared as values)
    back = g.keys[g.index]
    for k in keys:
        assert back[k].equals(df[k], check_names=True) or back[k].cast(pl.String).fill_null(
            "<null>"
        ).equals(df[k].cast(pl.String).fill_null("<null>")), k


def test_over_matches_the_groups_per_row_and_float32_stays_float32() -> None:
    df = _random_frame(5).with_columns(pl.col("y").cast(pl.Float32).alias("y32"))
    g = Groups.of(df, ["k", "b"])
    over = g.over(df["x"], "mean")
    want = df.select(pl.col("x").mean().over("k", "b"))["x"]
    np.testing.assert_allclose(over.to_numpy(), want.to_numpy(), rtol=1e-12, atol=1e-15)
    assert over.is_null().equals(want.is_null())
    assert g.reduce(df["y32"], "mean").dtype == pl.Float32
    assert g.reduce(np.arange(df.height, dtype=np.float64), "sum").sum() == pytest.approx(
        df.height * (df.height - 1) / 2
    )


def test_empty_frame_and_bad_arguments() -> None:
    df = pl.DataFrame(schema={"k": pl.String, "v": pl.Float64})
    out = group_agg(df, ["k"], {"m": ("v", "mean")}, exact=[pl.len()])
    assert out.height == 0 and out.columns == ["k", "len", "m"]
    with pytest.raises(ValueError, match="key"):
        Groups.of(df, [])
    with pytest.raises(ValueError, match="aggregation"):
        Groups.of(df, ["k"]).reduce(df["v"], "median")  # type: ignore[arg-type]


def test_module_examples() -> None:
    assert doctest.testmod(_groups).failed == 0


def test_sums_follow_the_row_order_only() -> None:
    # the sum of a group is the left-to-right sum of its rows: the same bits from a frame whose
    # other groups' rows are interleaved differently
    rng = np.random.default_rng(7)
    x = rng.standard_normal(1000) * 10.0 ** rng.integers(-8, 8, 1000)
    a = pl.DataFrame({"k": np.repeat([0, 1], 500), "x": x})
    b = pl.DataFrame({"k": np.tile([0, 1], 500), "x": np.stack([x[:500], x[500:]], 1).ravel()})
    want = [
        functools.reduce(operator.add, x[:500].tolist()),
        functools.reduce(operator.add, x[500:].tolist()),
    ]
    for df in (a, b):
        s = group_agg(df, ["k"], {"s": ("x", "sum")})["s"].to_list()
        assert s == want


# --- outputs: the same bytes for 1, 2 and 3 polars threads ----------------------------------


def _run_threads(script: str) -> set[str]:
    """The lines the script prints (each call's digest) with 1, 2 and 3 polars threads."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(p for p in sys.path if p))
    seen: set[str] = set()
    for threads in (1, 2, 3):
        env["POLARS_MAX_THREADS"] = str(threads)
        out = subprocess.run(
            [sys.executable, "-c", script], env=env, capture_output=True, text=True, check=True
        )
        lines = out.stdout.split()
        assert len(lines) == 4
        seen |= set(lines)
    return seen


_GAP_MAP = textwrap.dedent(
    """
    import hashlib, json
    import numpy as np
    import polars as pl
    from aerodelta.diagnosis.where import gap_map, worst_segments

    # few, large groups: one flap, two alpha bins, three maneuvers, two 2-s windows
    rng = np.random.default_rng(0)
    n = 400_000
    frame = pl.DataFrame(
        {
            "maneuver_id": [f"m{k}" for k in rng.integers(0, 3, n)],
            "flap_deg": np.zeros(n),
            "alpha_deg": rng.uniform(0.0, 2.0, n),
            "t": rng.uniform(0.0, 4.0, n),
        }
    )
    gap = rng.standard_normal(n) + 0.3
    phase = pl.Series(np.array(["pre_stall", "stall", "recovery"])[rng.integers(0, 3, n)])
    for _ in range(4):
        out = json.dumps([gap_map(frame, gap, phase, 1.0, 0.05), worst_segments(frame, gap)])
        print(hashlib.sha256(out.encode()).hexdigest())
    """
)


def test_diagnosis_gap_map_is_the_same_for_any_polars_thread_count() -> None:
    # gap_map's per-maneuver means and the noise floor feed the diagnosis' where-section
    assert len(_run_threads(_GAP_MAP)) == 1


_STALL_SUMMARY = textwrap.dedent(
    """
    import hashlib
    import numpy as np
    import polars as pl
    from aerodelta.stall import stall_summary

    # a per-maneuver table of 400k rows in four (flap, kind) groups
    rng = np.random.default_rng(0)
    n = 400_000
    v_stall = 100.0 + rng.standard_normal(n)
    table = pl.DataFrame(
        {
            "flap_deg": rng.choice([0.0, 15.0], n),
            "kind": rng.choice(["straight", "turning"], n),
            "stall_id_by": rng.choice(["pusher", "g_break"], n),
            "stall_id_alpha_deg": 16.0 + rng.standard_normal(n),
            "v_warning_keas": v_stall + 5.0 + rng.standard_normal(n),
            "v_stall_keas": v_stall,
            "v_min_keas": v_stall - 2.0 + rng.standard_normal(n),
        }
    )
    for _ in range(4):
        print(hashlib.sha256(stall_summary(table).write_csv().encode()).hexdigest())
    """
)


def test_stall_summary_is_the_same_for_any_polars_thread_count() -> None:
    assert len(_run_threads(_STALL_SUMMARY)) == 1


_CLOSED_LOOP = textwrap.dedent(
    """
    import hashlib
    import numpy as np
    import polars as pl
    from aerodelta.closed_loop import QUANTITIES, ClosedLoopResult

    rng = np.random.default_rng(0)
    n = 400_000
    cols = {"flap_deg": rng.choice([0.0, 15.0], n), "test_condition": rng.random(n) < 0.7}
    for key, _, _ in QUANTITIES:
        d = rng.standard_normal(n) * 2.0 + 0.4
        cols[f"{key}_diff_kt"] = d
        cols[f"{key}_status"] = np.where(np.abs(d) <= 3.0, "PASS", "FAIL")
    res = ClosedLoopResult(pl.DataFrame(cols))
    for _ in range(4):
        print(hashlib.sha256(res.summary().write_csv().encode()).hexdigest())
    """
)


def test_closed_loop_summary_is_the_same_for_any_polars_thread_count() -> None:
    assert len(_run_threads(_CLOSED_LOOP)) == 1


_BIN_PROJECTION = textwrap.dedent(
    """
    import hashlib
    import numpy as np
    from aerodelta.diagnosis.withheld import _bin_projection

    rng = np.random.default_rng(0)
    n = 400_000
    alpha = rng.uniform(0.0, 3.0, n)
    flap = rng.choice([0.0, 15.0], n)
    x = rng.standard_normal(n) + 0.2
    c = 0.3 + 0.7 * x + rng.standard_normal(n)
    for _ in range(4):
        a, s = _bin_projection(alpha, flap, x, c)
        print(hashlib.sha256(a.tobytes() + s.tobytes()).hexdigest())
    """
)


def test_withheld_bin_projection_is_the_same_for_any_polars_thread_count() -> None:
    # the true contribution of an effect per row, scored against the diagnosis
    assert len(_run_threads(_BIN_PROJECTION)) == 1
