"""One stall-like pull through the Kirchhoff break, shared by the longitudinal tests."""

from __future__ import annotations

import numpy as np

#: Sample rate of the pulls, Hz.
HZ = 50.0


def stall_pull(
    rng: np.random.Generator, n: int = 1200
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``(t s, alpha deg, alphadot deg/s)`` of a pull from 6 deg to 21-25 deg and back over
    ``n`` samples at :data:`HZ`, with an oscillation of 0.5-2 deg at 1-2.5 rad/s; draws three
    uniforms from ``rng`` (top, frequency, amplitude), in that order."""
    t = np.arange(n) / HZ
    top, f1, amp = rng.uniform(21.0, 25.0), rng.uniform(1.0, 2.5), rng.uniform(0.5, 2.0)
    s = np.sin(np.pi * t / t[-1])
    a_deg = 6.0 + (top - 6.0) * s**2 + amp * np.sin(f1 * t)
    return t, a_deg, np.gradient(a_deg, t)
