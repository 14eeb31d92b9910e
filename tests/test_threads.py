"""The thread setting of aerodelta's own pools (``aerodelta._threads``)."""

from __future__ import annotations

import pytest

from aerodelta._threads import available_cpus, engine_threads
from aerodelta.exceptions import InvalidInputError


def test_aerodelta_variable_wins_over_rayon_and_the_cap_applies(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv("AERODELTA_NUM_THREADS", "3")
    monkeypatch.setenv("RAYON_NUM_THREADS", "7")
    assert engine_threads() == 3
    assert engine_threads(cap=2) == 2
    monkeypatch.delenv("AERODELTA_NUM_THREADS")
    assert engine_threads() == 7
    assert engine_threads(cap=4) == 4


def test_unset_means_the_cpus_this_process_may_use(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AERODELTA_NUM_THREADS", raising=False)
    monkeypatch.delenv("RAYON_NUM_THREADS", raising=False)
    assert engine_threads() == available_cpus() >= 1
    assert engine_threads(cap=1) == 1


@pytest.mark.parametrize("raw", ["0", "-2", "two", "1.5"])
def test_a_value_that_is_not_a_positive_integer_is_refused_in_one_line(
    monkeypatch: pytest.MonkeyPatch, raw: str
) -> None:
    monkeypatch.setenv("AERODELTA_NUM_THREADS", raw)
    with pytest.raises(InvalidInputError, match=r"AERODELTA_NUM_THREADS=.*positive whole number"):
        engine_threads()


def test_rayon_zero_means_its_default_as_rayon_reads_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("AERODELTA_NUM_THREADS", raising=False)
    monkeypatch.setenv("RAYON_NUM_THREADS", "0")
    assert engine_threads() == available_cpus()
