"""Shared references of the diagnosis tests: the dense design matrix and a small toy data set."""

from __future__ import annotations

import numpy as np

from aerodelta.diagnosis import cv


def dense_design(y, man, flap, alpha, aero, glob, grid, n_flaps):  # noqa: PLR0917
    """The full design matrix written out row by row (hat basis in alpha per flap, then the
    global columns): the reference the sparse per-maneuver reduction must reproduce."""
    del man  # rows are independent of their maneuver here
    k_n, r_n, g_n = grid.n, aero.shape[1], glob.shape[1]
    j, w1 = grid.locate(alpha)
    x = np.zeros((y.size, n_flaps * k_n * r_n + g_n))
    rows = np.arange(y.size)
    for r in range(r_n):
        np.add.at(x, (rows, flap * k_n * r_n + j * r_n + r), (1 - w1) * aero[:, r])
        np.add.at(x, (rows, flap * k_n * r_n + (j + 1) * r_n + r), w1 * aero[:, r])
    x[:, n_flaps * k_n * r_n :] = glob
    return x


def toy_rows(seed: int, n_man: int, per: int):
    """Two flaps (alternating maneuvers), alpha 0-10 deg, two aerodynamic regressors (the first
    acting as sin(alpha/3)) and one global (0.3), light noise; a 2.5-deg hat grid."""
    rng = np.random.default_rng(seed)
    man = np.repeat(np.arange(n_man), per)
    flap = (man % 2).astype(np.int64)
    alpha = rng.uniform(0, 10, man.size)
    aero = rng.normal(size=(man.size, 2))
    glob = rng.normal(size=(man.size, 1))
    y = np.sin(alpha / 3) * aero[:, 0] + 0.3 * glob[:, 0] + 0.05 * rng.normal(size=man.size)
    grid = cv.HatGrid.covering(alpha, 2.5)
    return y, man, flap, alpha, aero, glob, grid
