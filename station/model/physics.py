"""Straight running: a particle on y = h(x), solved in arc length with exact sensitivities.

The model of Kaps, Nachbauer & Mössner (1996, eq. 3, 4, 19-21): gravity, friction (μ + μ1·v)·N
and drag ½ρ·CdA·|v − w|(v − w) on the air-relative speed (w: along-track wind, + = tailwind),
with the normal force N = m(g·cos α + κ·v²) — the paper's Lagrange multiplier, N = −λ/cos α.

Instead of integrating the DAE in time and root-finding each photocell, the energy per unit
mass E = v²/2 is integrated in the arc length s:

    dE/ds = F(s, E) = −g·sin α − (μ + μ1·v)(g·cos α + 2κE) − (ρ·CdA / 2m)(v − w)|v − w|

For constant μ and no wind F is linear in E, dE/ds = a(s) − b(s)·E, solved by the integrating
factor as a few cumulative sums (numerics.md). Otherwise F is linearised about the previous
iterate (quasi-linearisation, quadratic convergence) and the same linear solver repeats. The
sensitivities ∂E/∂p obey the variational equations d(∂E/∂p)/ds = F_E·∂E/∂p + F_p, linear
again, solved by the same routine. Times follow from t = ∫ ds/v, exact for E linear between grid
nodes. Everything runs on a fixed grid whose nodes include the photocells, so the computed times
are smooth functions of the parameters; two grids (h and h/2) combined by Richardson
extrapolation give the times to ~1e-7 s. An independent Cartesian DAE formulation lives in
:mod:`station.dae` for the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from station.survey.track import Profile, Track

Array = np.ndarray

G_STANDARD = 9.80665

#: GRS80 normal gravity (Moritz 1980, the international gravity formula 1980 in Somigliana's
#: closed form): equatorial gravity, Somigliana's constant k and the first eccentricity²
GRS80_GAMMA_E = 9.7803267715
GRS80_K = 0.001931851353
GRS80_E2 = 0.00669438002290
#: free-air gradient of normal gravity near the surface, (m/s²) per metre of height
FREE_AIR_GRADIENT = 3.086e-6


def local_gravity(latitude_deg: float, height_m: float = 0.0) -> float:
    """Normal gravity (m/s²) at a geodetic latitude and a height above the ellipsoid (or sea
    level: the difference is ~1e-4 m/s² per 30 m of geoid height).

    Somigliana's formula with the GRS80 constants, minus the free-air term 3.086e-6·h. Why it
    matters: g enters μ one to one through g·cos α; standard gravity 9.80665 at an alpine site
    (g ≈ 9.803) biases μ by +1.6e-4, and over the range of real sites by ±0.0013. Terrain and
    local anomalies (≲ 1e-4 relative) are left out.
    """
    if not math.isfinite(latitude_deg) or not -90.0 <= latitude_deg <= 90.0:
        raise ValueError(f"latitude {latitude_deg!r}° is not between -90 and 90")
    if not math.isfinite(height_m) or not -500.0 <= height_m <= 9000.0:
        raise ValueError(f"height {height_m!r} m is not on the earth's surface")
    s2 = math.sin(math.radians(latitude_deg)) ** 2
    gamma = GRS80_GAMMA_E * (1.0 + GRS80_K * s2) / math.sqrt(1.0 - GRS80_E2 * s2)
    return gamma - FREE_AIR_GRADIENT * height_m


#: floor on the speed (m/s) where the skier would stand still: keeps times finite, and is
#: small enough that a standing start (v0 = 0) costs < 1e-6 s
V_FLOOR = 1e-6
E_FLOOR = 0.5 * V_FLOOR**2

PARAM_NAMES = ("cda", "mu", "v0", "mu1")


@dataclass(frozen=True)
class Gravity:
    """The g a fit uses and where it came from, so every output can say so."""

    value: float
    source: str

    def describe(self) -> str:
        return f"g {self.value:.5f} m/s² ({self.source})"


def gravity_for(track: Track | None, override: float | None = None) -> Gravity:
    """g for a run: an explicit override, else normal gravity at the survey's latitude and the
    timed section's height, else standard gravity (and the source says what is missing)."""
    if override is not None:
        return Gravity(override, "given")
    if track is not None and track.latitude_deg is not None:
        h = track.mean_height_m
        g = local_gravity(track.latitude_deg, min(max(h, -500.0), 9000.0))
        where = "altitude_m" if track.altitude_m is not None else "survey heights"
        return Gravity(
            g, f"GRS80 normal gravity at {track.latitude_deg:.3f}° and {h:.0f} m ({where})"
        )
    return Gravity(
        G_STANDARD,
        "standard gravity: no latitude_deg in the survey; at 47° N, 1700 m g is 0.03 % lower",
    )


@dataclass(frozen=True)
class Params:
    """The unknowns of a descent: drag area (m²), friction coefficients, speed at cell 1 (m/s)."""

    cda: float
    mu: float
    v0: float
    mu1: float = 0.0


@dataclass(frozen=True)
class Conditions:
    """What is known about a descent: skier mass, air density, along-track wind, gravity."""

    mass_kg: float
    air_density: float
    wind_ms: float = 0.0  # + tailwind (blowing down the run), − headwind
    g: float = G_STANDARD


@dataclass
class Grid:
    """Track quantities on a fixed grid in x whose nodes include every photocell."""

    x: Array
    s: Array
    ds: Array
    sin_a: Array
    cos_a: Array
    kappa: Array
    cell_index: Array  # grid index of each photocell


def make_grid(profile: Profile, xs: Array, step: float, refine: int = 1) -> Grid:
    """A grid from the first to the last photocell, uniform between neighbours, spacing ≤ step,
    each interval then split ``refine`` times more (so a refined grid contains the coarse one).

    Arc length per interval by Simpson's rule with the midpoint (O(h⁵) per interval), so the
    distances the skier travels are exact to far below a millimetre.
    """
    x, idx = grid_nodes(xs, step, refine)
    xm = 0.5 * (x[1:] + x[:-1])
    return grid_on_nodes(x, idx, profile.dh(x), profile.d2h(x), profile.dh(xm))


def grid_nodes(xs: Array, step: float, refine: int = 1) -> tuple[Array, Array]:
    """The nodes of :func:`make_grid` and the node index of each photocell: they depend on the
    photocells only, so perturbed profiles on the same photocells share them."""
    xs = np.asarray(xs, dtype=float)
    if np.any(np.diff(xs) <= 0):
        raise ValueError("photocell positions must increase down the run")
    pieces = []
    idx = [0]
    for i, (a, b) in enumerate(zip(xs[:-1], xs[1:], strict=True)):
        n = max(1, int(math.ceil((b - a) / step))) * refine
        if i == 0:
            # graded as x = a + L·ξ²: the time integral ∫ds/v stays smooth in ξ even when the
            # skier crosses the first photocell slowly, so Richardson extrapolation keeps its
            # order (uniform nodes lose it: 3e-6 s error at v0 = 0.5 m/s instead of 1e-9)
            n *= 2
            pieces.append(a + (b - a) * np.linspace(0.0, 1.0, n + 1)[:-1] ** 2)
        else:
            pieces.append(np.linspace(a, b, n + 1)[:-1])
        idx.append(idx[-1] + n)
    return np.concatenate([*pieces, xs[-1:]]), np.array(idx)


def grid_on_nodes(x: Array, cell_index: Array, d1: Array, d2: Array, d1_mid: Array) -> Grid:
    """The grid on nodes ``x`` from the profile's h′ and h″ there and h′ at the midpoints.

    The slopes may carry a leading axis, one row per profile (shape (R, n), (R, n), (R, n − 1)):
    then the grid holds R tracks on the same nodes and :func:`solve_grid` solves them at once,
    each row exactly as it would be solved alone (the survey's finite differences need that).
    """
    root = np.sqrt(1.0 + d1 * d1)
    fm = np.sqrt(1.0 + d1_mid**2)
    ds = np.diff(x) / 6.0 * (root[..., :-1] + 4.0 * fm + root[..., 1:])
    s = np.concatenate([np.zeros(ds.shape[:-1] + (1,)), np.cumsum(ds, axis=-1)], axis=-1)
    return Grid(
        x=x,
        s=s,
        ds=ds,
        sin_a=d1 / root,
        cos_a=1.0 / root,
        kappa=d2 / root**3,
        cell_index=cell_index,
    )


def _solve_linear(ds: Array, a: Array, b: Array, y0: Array) -> Array:
    """y′ = a − b·y on the grid, by integrating factor and trapezoid sums (rows solved at once).

    a: (R, n), b: (n,) or (R, n), y0: (R,).
    """
    zero = np.zeros(b.shape[:-1] + (1,))
    big_b = np.concatenate(
        [zero, np.cumsum(0.5 * (b[..., 1:] + b[..., :-1]) * ds, axis=-1)], axis=-1
    )
    ebb = np.exp(big_b)
    f = a * ebb
    zero_a = np.zeros(f.shape[:-1] + (1,))
    integral = np.concatenate(
        [zero_a, np.cumsum(0.5 * (f[..., 1:] + f[..., :-1]) * ds, axis=-1)], axis=-1
    )
    return (y0[..., None] + integral) / ebb


@dataclass
class GridSolution:
    """Energy, speed and times on one grid, and their sensitivities to the parameters."""

    energy: Array
    speed: Array
    time: Array  # at every node
    dtime: Array | None  # (P, n) ∂t/∂p at every node
    normal_per_mass: Array
    converged: bool


def solve_grid(
    grid: Grid, p: Params, c: Conditions, n_params: int = 3, sensitivities: bool = True
) -> GridSolution:
    """Integrate one descent on one grid; sensitivities for the first ``n_params`` of
    (cda, mu, v0, mu1).

    A grid of R tracks (:func:`grid_on_nodes`) gives energy, speed and time as (R, n) arrays,
    without sensitivities; ``converged`` then says whether every track converged.
    """
    g = c.g
    k = c.air_density / c.mass_kg
    w = c.wind_ms
    e0 = 0.5 * p.v0 * p.v0
    linear = p.mu1 == 0.0 and w == 0.0

    def parts(energy: Array) -> tuple[Array, Array, Array, Array]:
        ec = np.maximum(energy, E_FLOOR)
        v = np.sqrt(2.0 * ec)
        nm = g * grid.cos_a + 2.0 * grid.kappa * ec
        vr = v - w
        f = -g * grid.sin_a - (p.mu + p.mu1 * v) * nm - 0.5 * k * p.cda * vr * np.abs(vr)
        f_e = -(p.mu1 / v * nm + (p.mu + p.mu1 * v) * 2.0 * grid.kappa) - k * p.cda * np.abs(vr) / v
        return f, f_e, v, nm

    # first pass: the linear part (exact when μ1 = 0 and no wind)
    a0 = -g * (grid.sin_a + p.mu * grid.cos_a)
    b0 = 2.0 * p.mu * grid.kappa + k * p.cda
    energy = _solve_linear(grid.ds, a0[None, :], b0, np.array([e0]))[0]
    converged = True
    if not linear:
        # each track iterates until it has converged, and no further (so a row of a batch is
        # the very number it would be alone)
        active = np.ones(energy.shape[:-1], dtype=bool)
        for _ in range(30):
            f, f_e, _, _ = parts(energy)
            new = _solve_linear(grid.ds, (f - f_e * energy)[None, :], -f_e, np.array([e0]))[0]
            delta = np.max(np.abs(new - energy), axis=-1)
            energy = np.where(active[..., None], new, energy)
            active &= ~(delta <= 1e-12 * np.maximum(1.0, np.max(np.abs(new), axis=-1)))
            if not active.any():
                break
        converged = not active.any()

    if sensitivities:
        _, f_e, v, nm = parts(energy)
    else:  # the speed only (as parts() computes it): the times need no derivatives
        v = np.sqrt(2.0 * np.maximum(energy, E_FLOOR))
    dt_nodes = 2.0 * grid.ds / (v[..., 1:] + v[..., :-1])
    time = np.concatenate([np.zeros(v.shape[:-1] + (1,)), np.cumsum(dt_nodes, axis=-1)], axis=-1)
    dtime = None
    if sensitivities:
        if v.ndim != 1:
            raise ValueError("sensitivities are for one track at a time")
        vr = v - w
        rows = [
            -0.5 * k * vr * np.abs(vr),  # ∂F/∂CdA
            -nm,  # ∂F/∂μ
            np.zeros_like(v),  # ∂F/∂v0 (enters through E0)
            -v * nm,  # ∂F/∂μ1
        ][:n_params]
        y0 = np.array([0.0, 0.0, p.v0, 0.0][:n_params])
        de = _solve_linear(grid.ds, np.array(rows), -f_e, y0)
        dv = de / v
        dt_seg = -2.0 * grid.ds * (dv[:, 1:] + dv[:, :-1]) / (v[1:] + v[:-1]) ** 2
        dtime = np.concatenate([np.zeros((n_params, 1)), np.cumsum(dt_seg, axis=1)], axis=1)
    return GridSolution(
        energy=energy,
        speed=v,
        time=time,
        dtime=dtime,
        normal_per_mass=g * grid.cos_a + 2.0 * grid.kappa * energy,
        converged=converged,
    )


@dataclass
class Trajectory:
    """The computed descent: times and speeds at the photocells and what happened on the way."""

    t: Array  # time at each photocell, t[0] = 0
    v: Array  # speed at each photocell
    dt_dp: Array | None  # (cells, P)
    x: Array  # grid nodes (the coarse grid, ≤ step apart)
    speed: Array  # speed at the grid nodes
    normal_force_n: Array  # normal force at the grid nodes, N
    min_normal_force_n: float
    liftoff_x: float | None
    stopped_x: float | None
    converged: bool = True
    notes: list[str] = field(default_factory=list)


def _first_crossing(x: Array, f: Array) -> float | None:
    """x where f first falls to 0 or below, interpolated between grid nodes; None if never."""
    below = np.flatnonzero(f <= 0.0)
    if not below.size:
        return None
    i = int(below[0])
    if i == 0:
        return float(x[0])
    return float(x[i - 1] + (x[i] - x[i - 1]) * f[i - 1] / (f[i - 1] - f[i]))


class StraightRun:
    """The forward model on one track and one set of photocells, grids built once.

    ``step`` is the coarse grid spacing in metres; the fine grid has half of it, and the two
    are combined by Richardson extrapolation.
    """

    def __init__(self, profile: Profile, xs: Array, step: float = 0.5):
        self.profile = profile
        self.xs = np.asarray(xs, dtype=float)
        if len(self.xs) < 2:
            raise ValueError("at least two photocells are needed")
        self.coarse = make_grid(profile, self.xs, step)
        self.fine = make_grid(profile, self.xs, step, refine=2)

    def solve(
        self, p: Params, c: Conditions, n_params: int = 3, sensitivities: bool = True
    ) -> Trajectory:
        sc = solve_grid(self.coarse, p, c, n_params, sensitivities)
        sf = solve_grid(self.fine, p, c, n_params, sensitivities)
        ic, jf = self.coarse.cell_index, self.fine.cell_index
        t = (4.0 * sf.time[jf] - sc.time[ic]) / 3.0
        dt = None
        if sensitivities:
            assert sf.dtime is not None and sc.dtime is not None
            dt = ((4.0 * sf.dtime[:, jf] - sc.dtime[:, ic]) / 3.0).T
        # energy extrapolated at the coarse nodes (every second fine node)
        energy = (4.0 * sf.energy[::2] - sc.energy) / 3.0
        x = self.coarse.x
        speed = np.sqrt(2.0 * np.maximum(energy, 0.0))
        normal = c.g * self.coarse.cos_a + 2.0 * self.coarse.kappa * energy
        return Trajectory(
            t=t,
            v=speed[ic],
            dt_dp=dt,
            x=x,
            speed=speed,
            normal_force_n=c.mass_kg * normal,
            min_normal_force_n=float(c.mass_kg * normal.min()),
            liftoff_x=_first_crossing(x, normal),
            stopped_x=_first_crossing(x, energy),
            converged=sc.converged and sf.converged,
        )
