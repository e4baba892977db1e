"""Many descents on the same photocells solved at once: the joint fit of a day in numpy.

The same model and numerics as :class:`station.model.physics.StraightRun` (energy in the arc
length, integrating factor, quasi-linearisation when μ1 ≠ 0 or with wind, variational equations
for the sensitivities, Richardson extrapolation of two grids), but every array carries one row
per descent, so a day of 2000 descents is a few array operations per grid instead of 2000 Python
calls. Rows are processed in chunks so memory stays bounded whatever the number of descents.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from station.model.physics import E_FLOOR, Grid, StraightRun, _solve_linear

#: rows solved together: bounds the memory (each row holds some 40 arrays of the grid size)
CHUNK = 32


@dataclass
class Rows:
    """Per-row parameters and conditions, arrays of shape (R,)."""

    cda: np.ndarray
    mu: np.ndarray
    v0: np.ndarray
    mu1: np.ndarray
    k: np.ndarray  # air density / mass
    wind: np.ndarray
    #: gravity (m/s²): one for all rows, or one per row (a day's descents each carry the g
    #: their single fit used, so the day model and the single fits agree)
    g: float | np.ndarray


@dataclass
class BatchSolution:
    t: np.ndarray  # (R, cells), t[:, 0] = 0
    dt_dp: np.ndarray  # (R, cells, P) for (cda, mu, v0[, mu1])
    stopped: np.ndarray  # (R,) the skier stops before the last photocell
    converged: np.ndarray  # (R,)


def _grid_rows(grid: Grid, p: Rows, n_params: int):
    g = p.g if np.ndim(p.g) == 0 else np.asarray(p.g)[:, None]
    sin, cos, kap, ds = grid.sin_a, grid.cos_a, grid.kappa, grid.ds
    mu, mu1, cda, k = p.mu[:, None], p.mu1[:, None], p.cda[:, None], p.k[:, None]
    w = p.wind[:, None]
    e0 = 0.5 * p.v0 * p.v0
    linear = not (np.any(p.mu1 != 0.0) or np.any(p.wind != 0.0))

    def parts(energy):
        ec = np.maximum(energy, E_FLOOR)
        v = np.sqrt(2.0 * ec)
        nm = g * cos + 2.0 * kap * ec
        vr = v - w
        mut = mu + mu1 * v
        f = -g * sin - mut * nm - 0.5 * k * cda * vr * np.abs(vr)
        f_e = -(mu1 / v * nm + mut * 2.0 * kap) - k * cda * np.abs(vr) / v
        return f, f_e, v, nm

    a0 = -g * (sin + mu * cos)
    b0 = 2.0 * mu * kap + k * cda
    energy = _solve_linear(ds, a0, b0, e0)
    converged = np.ones(len(e0), dtype=bool)
    if not linear:
        converged[:] = False
        for _ in range(30):
            f, f_e, _, _ = parts(energy)
            new = _solve_linear(ds, f - f_e * energy, -f_e, e0)
            delta = np.max(np.abs(new - energy), axis=1)
            energy = new
            converged = delta <= 1e-12 * np.maximum(1.0, np.max(np.abs(energy), axis=1))
            if converged.all():
                break
    f, f_e, v, nm = parts(energy)
    time = np.concatenate(
        [np.zeros((len(e0), 1)), np.cumsum(2.0 * ds / (v[:, 1:] + v[:, :-1]), axis=1)], axis=1
    )
    vr = v - w
    rows = [-0.5 * k * vr * np.abs(vr), -nm, np.zeros_like(v), -v * nm][:n_params]
    y0 = np.stack([np.zeros_like(e0), np.zeros_like(e0), p.v0, np.zeros_like(e0)][:n_params])
    de = _solve_linear(ds, np.stack(rows), -f_e, y0)  # (P, R, n)
    dv = de / v
    dt_seg = -2.0 * ds * (dv[..., 1:] + dv[..., :-1]) / (v[:, 1:] + v[:, :-1]) ** 2
    dtime = np.concatenate([np.zeros(dt_seg.shape[:-1] + (1,)), np.cumsum(dt_seg, axis=-1)], -1)
    return energy, time, dtime, converged


def solve_rows(run: StraightRun, p: Rows, n_params: int = 3) -> BatchSolution:
    """Times at the photocells and their sensitivities for every row of ``p``."""
    n = len(p.cda)
    cells = len(run.xs)
    t = np.empty((n, cells))
    dt = np.empty((n, cells, n_params))
    stopped = np.zeros(n, dtype=bool)
    converged = np.ones(n, dtype=bool)
    ic, jf = run.coarse.cell_index, run.fine.cell_index
    for lo in range(0, n, CHUNK):
        sl = slice(lo, min(n, lo + CHUNK))
        g = p.g if np.ndim(p.g) == 0 else np.asarray(p.g)[sl]
        part = Rows(p.cda[sl], p.mu[sl], p.v0[sl], p.mu1[sl], p.k[sl], p.wind[sl], g)
        ec, tc, dc, cc = _grid_rows(run.coarse, part, n_params)
        ef, tf, df, cf = _grid_rows(run.fine, part, n_params)
        t[sl] = (4.0 * tf[:, jf] - tc[:, ic]) / 3.0
        dt[sl] = np.moveaxis((4.0 * df[:, :, jf] - dc[:, :, ic]) / 3.0, 0, -1)
        energy = (4.0 * ef[:, ::2] - ec) / 3.0
        stopped[sl] = np.any(energy <= 0.0, axis=1)
        converged[sl] = cc & cf
    return BatchSolution(t, dt, stopped, converged)
