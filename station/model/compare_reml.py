"""The solver of the day model: penalised Gauss-Newton steps with each descent's own block
eliminated (Schur complement), and the posture scatter γ found by REML at every linearisation
(the estimator is described in :mod:`station.model.compare`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize_scalar

from station.model.compare_layout import DayModel

#: search range of log γ, γ = s²/σ² (s posture scatter, relative; σ timing noise, s)
LOG_GAMMA = (-14.0, 22.0)


@dataclass
class Pieces:
    """Normal-equation pieces of the linearised day at one point (global columns scaled)."""

    bb: np.ndarray  # (D, 3, 3)
    ab: np.ndarray  # (D, G, 3)
    aa: np.ndarray  # (G, G)
    br: np.ndarray  # (D, 3)
    ar: np.ndarray  # (G,)
    a: np.ndarray  # (D, n, G)
    b: np.ndarray  # (D, n, 3)
    r: np.ndarray  # (D, n)
    u: np.ndarray  # (D,)


@dataclass
class Step:
    dg: np.ndarray  # scaled global step
    dl: np.ndarray  # (D, 3) local step
    prss: float
    logdet: float
    s_inv: np.ndarray  # (G, G) scaled


def linear_step(pc: Pieces, wu: float, lam: float = 0.0) -> Step:
    """Penalised Gauss-Newton step with the local blocks eliminated (Schur complement)."""
    hll = pc.bb.copy()
    hll[:, 0, 0] += wu
    gl = pc.br.copy()
    gl[:, 0] += wu * pc.u
    aa = pc.aa
    if lam > 0:
        idx = np.arange(3)
        hll[:, idx, idx] *= 1.0 + lam
        aa = aa + lam * np.diag(np.diag(aa))
    hinv = np.linalg.inv(hll)
    k = np.einsum("dgi,dij->dgj", pc.ab, hinv)
    s = aa - np.einsum("dgi,dhi->gh", k, pc.ab)
    rhs = pc.ar - np.einsum("dgi,di->g", k, gl)
    if s.size:
        s_inv = np.linalg.inv(s)
        dg = -s_inv @ rhs
        logdet_s = float(np.linalg.slogdet(s)[1])
    else:
        s_inv, dg, logdet_s = np.zeros((0, 0)), np.zeros(0), 0.0
    dl = -np.einsum("dij,dj->di", hinv, gl + np.einsum("dgi,g->di", pc.ab, dg))
    lin = pc.r + np.einsum("dng,g->dn", pc.a, dg) + np.einsum("dni,di->dn", pc.b, dl)
    prss = float(np.sum(lin * lin) + wu * np.sum((pc.u + dl[:, 0]) ** 2))
    logdet = float(np.sum(np.linalg.slogdet(hll)[1])) + logdet_s
    return Step(dg, dl, prss, logdet, s_inv)


@dataclass
class Solution:
    """Where the REML / Gauss-Newton iteration ended."""

    glob: np.ndarray
    loc: np.ndarray
    pc: Pieces  # the normal-equation pieces there
    cs: np.ndarray  # column scales of the globals
    lg: float  # log γ
    stopped: np.ndarray
    converged: bool  # every model solve converged
    converged_outer: bool  # the iteration itself


def solve(day: DayModel) -> Solution:
    """γ and the parameters updated together: each outer iteration linearises the model once,
    finds γ by a one-dimensional search of the REML criterion of that linearisation, and takes
    the (damped where needed) Gauss-Newton step at that γ."""
    dof, n_d = day.lay.dof, day.n_d
    glob, loc, lower = day.start()
    r, a, b, stopped, converged = day.evaluate(glob, loc)
    cs = 1.0 / np.maximum(np.sqrt(np.sum(a * a, axis=(0, 1))), 1e-300)  # column scales

    def pieces(r, a, b, loc) -> Pieces:
        a_s = a * cs
        return Pieces(
            bb=np.einsum("dni,dnj->dij", b, b),
            ab=np.einsum("dng,dni->dgi", a_s, b),
            aa=np.einsum("dng,dnh->gh", a_s, a_s),
            br=np.einsum("dni,dn->di", b, r),
            ar=np.einsum("dng,dn->g", a_s, r),
            a=a_s,
            b=b,
            r=r,
            u=loc[:, 0].copy(),
        )

    def reml(lg: float, pc: Pieces) -> tuple[float, Step]:
        st = linear_step(pc, math.exp(-lg))
        return (dof * math.log(max(st.prss, 1e-300)) + n_d * lg + st.logdet), st

    pc = pieces(r, a, b, loc)
    lg = 2.0 * math.log(0.01 / 5e-4)
    converged_outer = False
    for _ in range(60):
        lg_prev = lg
        opt = minimize_scalar(
            lambda x, pc=pc: reml(x, pc)[0],
            bounds=LOG_GAMMA,
            method="bounded",
            options={"xatol": 1e-3},
        )
        lg = float(opt.x)
        wu = math.exp(-lg)
        st = linear_step(pc, wu)
        cost = float(np.sum(pc.r**2) + wu * np.sum(pc.u**2))
        if cost - st.prss <= 1e-9 * cost + 1e-24 and abs(lg - lg_prev) < 1e-2:
            converged_outer = True
            break
        lam = 0.0
        for _ in range(12):
            g_new = np.maximum(glob + st.dg * cs, lower)
            l_new = loc + st.dl
            l_new[:, 1] = np.maximum(l_new[:, 1], 0.0)
            r2, a2, b2, stopped2, conv2 = day.evaluate(g_new, l_new)
            cost2 = float(np.sum(r2**2) + wu * np.sum(l_new[:, 0] ** 2))
            if np.isfinite(cost2) and cost2 <= cost:
                glob, loc, r, a, b, stopped, converged = g_new, l_new, r2, a2, b2, stopped2, conv2
                break
            lam = 1e-3 if lam == 0 else lam * 10
            st = linear_step(pc, wu, lam)
        else:
            break
        pc = pieces(r, a, b, loc)
    return Solution(glob, loc, pc, cs, lg, stopped, converged, converged_outer)
