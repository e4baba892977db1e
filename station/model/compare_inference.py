"""The uncertainty of the day's fit: the globals' distribution integrated over the posture
scatter's posterior, a mixture of Student t with Kenward-Roger's correction (:class:`Inference`)."""

from __future__ import annotations

import math

import numpy as np
from scipy.optimize import brentq
from scipy.special import stdtr, stdtrit  # Student t (no scipy.stats)

from station.model.compare_reml import LOG_GAMMA, Pieces, Solution, Step, linear_step

#: the posterior of log γ is integrated where its log density is within this of its peak
POST_DROP = 16.0
#: steps of log γ: the widest of the walk that finds where the posterior lies, and the widest
#: of the grid that integrates it (at least POST_POINTS points over where it lies)
POST_SEARCH, POST_STEP, POST_POINTS = 0.5, 0.25, 41
#: the largest posture scatter the prior allows (relative SD of CdA between descents of a
#: skier): beyond it the single fits would show another position, not a tuck's scatter; a
#: bound makes the posterior proper on days with as few descents as skiers + 1
POSTURE_MAX = 0.2


class Inference:
    """At the solution: σ̂², the posture scatter, and the distribution of the globals with the
    uncertainty of the estimated scatter in it.

    Why a posterior over γ, not γ̂ plugged in. Plugged in, the intervals are as narrow as if
    the scatter were known; on small days (2 descents an item) REML puts it at 0 on about one
    day in ten at 0.5 % scatter, Δμ̂ at γ = 0 can be far from Δμ̂ at the true γ, and on those
    days the interval held the truth two times in three (83.5 % in all with the
    Kackar-Harville term and Satterthwaite's degrees of freedom, which both vanish or mislead
    at the boundary, issue 24). Instead the globals' distribution is integrated over γ: given
    γ, with flat priors on the fixed effects and 1/σ² on σ², the globals are exactly Student
    t on n − p degrees of freedom around β̂(γ) with scale PRSS(γ)/(n − p)·S⁻¹(γ) (of the model
    linearised at the solution), and γ's posterior is its REML likelihood,
    exp(−½[(n − p)·log PRSS(γ) + q·log γ + log det M(γ)]), times a prior. The prior is flat
    in the scatter s itself (the usual choice for a scale with few groups, Gelman 2006): it
    keeps what the day cannot rule out, and where the day pins γ the posterior is narrow and
    the answer is the plug-in one. Measured, 200 simulated days a cell
    (benchmarks/compare_small_days.py, straight drift): 2 a ski at 0.5 % scatter 88.5 %
    (83.5 % plugged in), at 3 % 89 %; 3, 4 and 6 a ski at 0.5 % 91.5, 90 and 88.5 %.
    Jeffreys' prior for γ (from REML's expected information) gave 85.5 % at 2 a ski: it
    falls to 0 with γ as fast as γ itself and so keeps too much of the scatter-free answer;
    a prior flat in γ gave 90 %, but is known to over-widen where the day says little. The
    integral is a sum over a grid in log γ: a walk out from γ̂ to where the posterior ends,
    then at least 41 points over it; each point is one linear solve of the day (no new model
    solves).

    Kenward-Roger's correction. Each component's scale σ̂²(γ)·S⁻¹(γ) is that of a day whose
    scatter is known; estimated, the scatter moves the estimates (the spread of the centres
    over the posterior, Λ, Kackar-Harville's term) and the scales themselves come out low by
    about as much: for a covariance linear in its parameters (σ² and s², as here) E[φ(θ̂)] ≈
    φ(θ) − Λ, so the variance is φ + 2Λ (Kenward & Roger 1997). Without it the components'
    mean scale was 2-8 % below the variance at the true scatter on the demo run (nine
    photocells) and about as much as Λ below on four photocells (benchmarks/
    compare_se_oracle.py), and equal skis were declared different after every descent on
    10.4-11.7 % (nine photocells) and 16.8 % (four) of simulated days (issue 21). So every
    component's scale gets Λ added: the variance is then the mean scale plus 2Λ, and every
    interval widens by what the day does not know of its scatter (nothing where the day
    pins it). The degrees of freedom of a comparison count that uncertainty too
    (:meth:`satterthwaite_dof`).

    Every number about the globals comes from that one mixture of t distributions:
    intervals (its quantiles), P(a faster), P(best), the covariance (the mixture's scale:
    mean of the scales plus the spread of the centres) and the standard errors from it, and
    the estimates themselves (μ, μ1, the drift, Δμ): the mixture's mean ``centre``, not the
    solution at γ̂. At γ̂ on the boundary (the scatter estimated at 0) the solution can lie
    outside its own interval (Δμ̂ 2.0 half-widths from the interval's middle on a 2-a-ski day,
    tests/test_compare_small_days.py), and z = Δμ̂/se spread 1.13–1.16 at 2 a ski where the
    mixture's centre spreads 1.09 (issue 21, benchmarks/compare_se_oracle.py). The skiers'
    mean CdA stay at γ̂ with their plug-in intervals (:meth:`plugin_interval`)."""

    H = 0.05  # step in log γ of the curvature's differences (the posture's interval)
    scale: np.ndarray  # (K, G, G) the components' scale matrices (set by _mixture, corrected)

    def __init__(self, sol: Solution, dof: int) -> None:
        self.sol, self.dof = sol, dof
        pc, lg, h = sol.pc, sol.lg, self.H
        wu = math.exp(-lg)
        st = self.st = linear_step(pc, wu)
        prss = self.prss = float(np.sum(pc.r**2) + wu * np.sum(pc.u**2))
        sigma2 = self.sigma2 = prss / dof
        self.posture = math.sqrt(math.exp(lg) * sigma2)
        probe = {dx: linear_step(pc, math.exp(-(lg + dx))) for dx in (-h, h)}
        p_m, p_p = probe[-h].prss, probe[h].prss
        l0, l_m, l_p = st.logdet, probe[-h].logdet, probe[h].logdet
        d1p = (p_p - p_m) / (2 * h)
        d2p = (p_p - 2 * prss + p_m) / h**2
        d2l = (l_p - 2 * l0 + l_m) / h**2
        hess = np.array([[prss / sigma2, -d1p / sigma2], [-d1p / sigma2, d2p / sigma2 + d2l]])
        vcov: np.ndarray | None
        try:
            vcov = 2.0 * np.linalg.inv(hess)
            if not (np.all(np.isfinite(vcov)) and vcov[0, 0] > 0 and vcov[1, 1] > 0):
                vcov = None
        except np.linalg.LinAlgError:
            vcov = None
        self.vcov = vcov
        cs = sol.cs
        self.plugin_sd = np.sqrt(np.maximum(sigma2 * cs * cs * np.diag(st.s_inv), 0.0))
        self._mixture(pc, lg)
        mean = self.centre = self.w @ self.beta
        spread = self.beta - mean
        #: the components' own scales, before the correction below (the degrees of freedom
        #: of a contrast are counted from them: equivalent_dof)
        self.scale0 = self.scale
        lam = (spread.T * self.w) @ spread  # the spread of the centres: Kackar-Harville's Λ
        self.scale = self.scale0 + lam[None, :, :]
        self.cov = np.einsum("k,kij->ij", self.w, self.scale) + lam
        self.sd = np.sqrt(np.maximum(np.diag(self.cov), 0.0))

    def _mixture(self, pc: Pieces, lg_hat: float) -> None:
        """The posterior of log γ on a grid: weights ``w``, and at each point the globals'
        centre ``beta`` and scale matrix ``scale`` (unscaled columns)."""
        dof, n_d, cs, glob = self.dof, len(pc.u), self.sol.cs, self.sol.glob

        def at(lgs: np.ndarray) -> tuple[list[Step], np.ndarray]:
            sts = [linear_step(pc, math.exp(-x)) for x in lgs]
            ld = np.array([n_d * x + s.logdet for x, s in zip(lgs, sts, strict=True)])
            prss = np.array([max(s.prss, 1e-300) for s in sts])
            # REML likelihood, times the prior flat in s = √γ·σ (per unit log γ: √γ)
            return sts, -0.5 * (dof * np.log(prss) + ld) + 0.5 * lgs

        # γ up to the largest scatter a skier's tuck can have (POSTURE_MAX)
        lo_b = LOG_GAMMA[0]
        hi_b = min(LOG_GAMMA[1], math.log(POSTURE_MAX**2 / max(self.sigma2, 1e-300)))
        hi_b = max(hi_b, lg_hat + POST_SEARCH)
        # the search step: the posterior's SD in log γ from its curvature at γ̂ (narrow on
        # big days), at most POST_SEARCH
        _sts, lp3 = at(np.array([lg_hat - self.H, lg_hat, lg_hat + self.H]))
        curv = (lp3[0] - 2 * lp3[1] + lp3[2]) / self.H**2
        step = POST_SEARCH if not curv < -1.0 / POST_SEARCH**2 else 1.0 / math.sqrt(-curv)
        top = float(lp3[1])
        lo = hi = lg_hat
        for sign in (1.0, -1.0):  # walk out from γ̂ until the posterior is negligible
            x = lg_hat
            while lo_b < x + sign * step < hi_b:
                x += sign * step
                lp_x = float(at(np.array([x]))[1][0])
                top = max(top, lp_x)
                if lp_x < top - POST_DROP:
                    break
            lo, hi = min(lo, x), max(hi, x)
        lo, hi = max(lo - step, lo_b), min(hi + step, hi_b)
        n = max(POST_POINTS, math.ceil((hi - lo) / POST_STEP) + 1)
        grid = np.linspace(lo, hi, n)
        sts, lp = at(grid)
        w = np.exp(lp - lp.max())
        w[[0, -1]] *= 0.5  # trapezoid
        use = w > 1e-12 * w.max()
        w = w[use] / w[use].sum()
        sts = [s for s, u in zip(sts, use, strict=True) if u]
        self.w = w
        self.grid = grid[use]
        self.beta = np.array([glob + s.dg * cs for s in sts])
        self.scale = np.array(
            [max(s.prss, 0.0) / dof * (cs[:, None] * s.s_inv * cs[None, :]) for s in sts]
        )

    def parts(self, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Centres and scales of c·globals in the mixture's components."""
        m = self.beta @ c
        s = np.sqrt(np.maximum(np.einsum("i,kij,j->k", c, self.scale, c), 1e-300))
        return m, s

    def cdf(self, c: np.ndarray, x: float) -> float:
        """P(c·globals ≤ x) (within [0, 1]: the weights' rounding gave 1.0000000000000002,
        which the report showed as a P(faster) of −0.000)."""
        m, s = self.parts(c)
        return min(max(float(self.w @ stdtr(self.dof, (x - m) / s)), 0.0), 1.0)

    def quantile(self, c: np.ndarray, p: float) -> float:
        m, s = self.parts(c)
        q = float(stdtrit(self.dof, p))
        lo, hi = float(np.min(m + q * s)), float(np.max(m + q * s))
        if hi - lo <= 1e-15 * max(abs(lo), abs(hi), 1e-300):
            return lo

        def f(x: float) -> float:
            return float(self.w @ stdtr(self.dof, (x - m) / s)) - p

        return float(brentq(f, lo, hi, xtol=1e-14 * max(abs(lo), abs(hi), 1e-12), rtol=1e-12))

    def interval_of(self, c: np.ndarray) -> tuple[float, float]:
        """The 90 % interval of c·globals."""
        return self.quantile(c, 0.05), self.quantile(c, 0.95)

    def interval(self, j: int) -> tuple[float, float]:
        """The 90 % interval of global parameter ``j``."""
        c = np.zeros(len(self.sol.glob))
        c[j] = 1.0
        return self.interval_of(c)

    def plugin_interval(self, j: int) -> tuple[float, float]:
        """The 90 % interval of global parameter ``j`` at the estimated scatter: for a
        skier's mean CdA, the mean over the day's descents. Why not the mixture: the mean
        of a skier's posture distribution is what the scatter's posterior makes uncertain,
        without bound on a day of 2 descents (a skier's CdA 0.2200 [0.1807, 0.2593] on two
        identical descents); the mean of the descents the day has is pinned by their
        times whatever the scatter. The comparisons of items are not affected by the
        scatter's tail: free CdA per descent still gives each μ its interval."""
        q = float(stdtrit(self.dof, 0.95)) * float(self.plugin_sd[j])
        g = float(self.sol.glob[j])
        return g - q, g + q

    def equivalent_dof(self, c: np.ndarray, ci: tuple[float, float]) -> float:
        """The degrees of freedom of the Student t that stands for the mixture of c·globals
        beyond its 90 % interval (the sequential rule's boundaries lie there: z 1.9 to 4.4):
        the t with the scale √(c·cov·c) whose 90 % interval is as wide as the mixture's, and
        no more than Satterthwaite's count for that variance (:meth:`satterthwaite_dof`). A
        caller that rebuilds a standard error from the interval and the degrees of freedom
        (station.model.sequential) gets the interval back at 90 % and the heavier tail
        beyond."""
        se = math.sqrt(max(float(c @ self.cov @ c), 0.0))
        ratio = (ci[1] - ci[0]) / 2 / se if se > 0 else 0.0
        if not ratio > float(stdtrit(self.dof, 0.95)):
            nu = float(self.dof)
        elif ratio >= float(stdtrit(1.0, 0.95)):
            nu = 1.0
        else:
            nu = float(brentq(lambda v: float(stdtrit(v, 0.95)) - ratio, 1.0, float(self.dof)))
        return max(1.0, min(nu, self.satterthwaite_dof(c)))

    def satterthwaite_dof(self, c: np.ndarray) -> float:
        """Degrees of freedom of the variance of c·globals counted as Satterthwaite does:
        that variance is the components' mean scale E[φ] plus twice the spread of their
        centres Λ (Kenward-Roger), and each part is uncertain: φ by the timing noise's χ² (2/ν
        in log) and by how it varies over the scatter's posterior (Var log φ), Λ as one χ²
        degree of freedom (the centres move along one direction, the scatter). Where the day
        pins the scatter (nine photocells) this is the timing noise's ν; where it does not
        (four photocells, two descents an item) it is a handful, and the decision's tail is
        that heavy: with the t at the interval's own degrees of freedom, equal skis were
        declared different on 16.8 % of simulated four-photocell days (issue 21)."""
        m = self.beta @ c
        phi = np.maximum(np.einsum("i,kij,j->k", c, self.scale0, c), 1e-300)
        lam = float(self.w @ (m - self.w @ m) ** 2)
        e_phi = float(self.w @ phi)
        log_phi = np.log(phi)
        var_log = float(self.w @ (log_phi - self.w @ log_phi) ** 2)
        tot = e_phi + 2.0 * lam
        den = e_phi**2 * (var_log + 2.0 / self.dof) / 2.0 + (2.0 * lam) ** 2
        return float(tot**2 / den) if den > 0 else float(self.dof)

    def draws(self, cols: list[int], n: int, rng: np.random.Generator) -> np.ndarray:
        """``n`` draws of the globals ``cols`` from the mixture (seeded by the caller)."""
        k = rng.choice(len(self.w), size=n, p=self.w)
        out = np.empty((n, len(cols)))
        for i in np.unique(k):
            sel = np.flatnonzero(k == i)
            sub = self.scale[i][np.ix_(cols, cols)]
            z = rng.multivariate_normal(np.zeros(len(cols)), sub, size=len(sel), method="eigh")
            chi = np.sqrt(rng.chisquare(self.dof, size=len(sel)) / self.dof)
            out[sel] = self.beta[i][cols][None, :] + z / chi[:, None]
        return out

    def posture_ci(self) -> tuple[float, float] | None:
        """The posture scatter's 90 % interval, where the day says enough about it."""
        posture, vcov = self.posture, self.vcov
        if vcov is None or not posture > 0 or not self.sol.lg > LOG_GAMMA[0] + 2.0:
            return None
        se = math.sqrt(max(float(np.ones(2) @ vcov @ np.ones(2)), 0.0))
        if not se < 10.0:  # the day says next to nothing about it
            return None
        return posture * math.exp(-1.645 * se / 2), posture * math.exp(1.645 * se / 2)
