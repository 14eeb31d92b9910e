"""Units, smoother, derivative and CG-transfer bindings against independent references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.signal import savgol_filter

from aerodelta import DataError, _core
from aerodelta.units import convert, factor_offset, known_units


@pytest.mark.parametrize(
    ("a", "b", "x", "y"),
    [
        ("kt", "m/s", 1.0, 0.514444),
        ("ft", "m", 1.0, 0.3048),
        ("rad", "deg", np.pi, 180.0),
        ("psf", "Pa", 1.0, 47.880259),
        ("lbf", "N", 1.0, 4.448222),
        ("degF", "K", 32.0, 273.15),
        ("g", "ft/s2", 1.0, 32.174049),
        ("slug/ft3", "kg/m3", 1.0, 515.378818),
    ],
)
def test_known_conversions(a: str, b: str, x: float, y: float) -> None:
    assert float(convert(x, a, b)) == pytest.approx(y, rel=1e-6)


def test_round_trips_for_every_pair_of_a_dimension() -> None:
    from aerodelta.units import dimension  # noqa: PLC0415

    x = np.array([-3.5, 0.0, 12.25, 1e4])
    for a in known_units():
        for b in known_units():
            if dimension(a) == dimension(b):
                np.testing.assert_allclose(
                    convert(convert(x, a, b), b, a), x, rtol=1e-12, atol=1e-9
                )


def test_cross_dimension_and_unknown_units_refused() -> None:
    with pytest.raises(DataError, match="cannot convert 'deg'"):
        factor_offset("deg", "m/s")
    with pytest.raises(DataError, match="unknown unit 'furlong'"):
        factor_offset("furlong", "m")


def test_smoother_and_derivative_on_noisy_analytic_signal() -> None:
    rng = np.random.default_rng(0)
    dt, n = 0.02, 3000
    t = np.arange(n) * dt
    w = 2 * np.pi * 0.25
    truth = np.sin(w * t) + 0.2 * np.cos(3 * w * t)
    dtruth = w * np.cos(w * t) - 0.6 * w * np.sin(3 * w * t)
    sigma = 0.02
    x = truth + sigma * rng.standard_normal(n)
    xs, fc, noise = _core.smooth(x, dt)
    inner = slice(20, n - 20)
    # smoothed error well under the noise (bound sigma/3), noise level recovered within 20 %
    assert np.sqrt(np.mean((xs - truth)[inner] ** 2)) < sigma / 3
    assert noise == pytest.approx(sigma, rel=0.2)
    assert 0.75 < fc < 10.0  # above the 0.75 Hz harmonic, below Nyquist
    d, _ = _core.smooth_deriv(x, dt)
    # derivative error bound: 3 % of the derivative's peak (≈ 2.7 /s); raw differences ~ 0.7
    assert np.sqrt(np.mean((d - dtruth)[inner] ** 2)) < 0.03 * np.abs(dtruth).max()
    # local polynomial derivative equals scipy's Savitzky-Golay derivative in the interior
    lp = _core.local_poly_deriv(x, dt, 10, 3)
    sg = savgol_filter(x, 21, 3, deriv=1, delta=dt)
    np.testing.assert_allclose(lp[10:-10], sg[10:-10], rtol=1e-9, atol=1e-9)


def test_cg_transfer_of_a_pure_rotation() -> None:
    # the CG is at rest and the aircraft spins about it: the sensor feels only ω̇×r + ω×(ω×r),
    # and the transfer must return zero at the CG
    n = 50
    rng = np.random.default_rng(1)
    w = rng.normal(0, 0.5, (3, n))
    wd = rng.normal(0, 0.5, (3, n))
    r = np.array([1.2, -0.4, 0.7])
    a_s = np.cross(wd.T, r) + np.cross(w.T, np.cross(w.T, r))
    out = _core.accel_to_cg(list(a_s.T.copy()), list(w.copy()), list(wd.copy()), list(r))
    for c in out:
        np.testing.assert_allclose(c, 0.0, atol=1e-14)
