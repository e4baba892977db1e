"""Fits of finished descents: the station's track, skier and air applied to each timed descent,
and the row of the results it gives. Pure: no I/O, no threads.

A fit that raises (a singular matrix in the interval step, a bug) never ends the day: the
descent gets ``status: error`` with the reason in its flags, and the next descent is fitted
as if nothing happened.
"""

from __future__ import annotations

import contextlib
import datetime as dt
import math
from collections.abc import Hashable
from dataclasses import dataclass, replace
from typing import Any, Protocol

import numpy as np

from station.model.estimate import MISSING, FitStatus
from station.model.fit import FitResult, fit_descent
from station.model.physics import G_STANDARD, Conditions, Params, StraightRun, gravity_for
from station.model.timer import TIMER_PRECISION_S
from station.model.track_error import survey_error
from station.session.config import StationConfig, site_track
from station.session.records import (
    DescentStatus,
    DescentTimes,
    FitModel,
    Metadata,
    ResultRow,
    ResultStatus,
    fit_status,
)
from station.survey.track import Track
from station.timing.impulses import DAY_US


@dataclass(frozen=True)
class FitJob:
    """Everything one fit needs, taken from the day under its lock; the fit itself then runs
    without it, so the reader is never held up by a fit."""

    descent: DescentTimes
    start_time: str
    metadata: Metadata  # in force for this descent
    model: FitModel
    mass_kg: float
    air_density: float
    wind_ms: float = 0.0
    gravity: float | None = None  # m/s²; None: the analyser's (the survey's site, else standard)
    timer_precision_s: float = TIMER_PRECISION_S  # SD of one crossing time (station.model.timer)
    problem: str = ""  # what makes the fit impossible (e.g. wind without a direction)


@dataclass(frozen=True, slots=True)
class DescentResult:
    """A descent with its fit and its row of the results: immutable, so it can be handed to the
    UI thread as it is (the speed arrays are read-only).

    The fit is :attr:`fit`. A recording keeps it in the session's fit store rather than in
    memory (``kept_fit`` None; ``stored`` the store, ``handle`` where in it): 4 kB a descent,
    two thirds of what a 2000-descent day kept (issue 18's target is 2 kB a descent);
    :attr:`fit` reads it back (0.5 ms) for the view that asks (the UI's selected descent)."""

    descent: DescentTimes
    kept_fit: FitResult | None
    row: ResultRow
    speed_x: np.ndarray | None = None  # the fitted skier's speed along the run, for plots
    speed_v: np.ndarray | None = None
    #: the session's store that keeps the fit (None: not stored, or no fit), and where in it
    stored: StoredFit | None = None
    handle: Hashable | None = None

    @property
    def fit(self) -> FitResult | None:
        """The fit (None: not fitted): the one in memory, else read back from the store."""
        if self.kept_fit is not None or self.stored is None:
            return self.kept_fit
        return self.stored.load(self, self.handle)

    @property
    def has_fit(self) -> bool:
        """Fitted (a fit in memory or in the store): no read of the store."""
        return self.kept_fit is not None or self.stored is not None

    @property
    def fit_timer_precision_s(self) -> float | None:
        """The SD of one crossing time the fit was judged against (the fit's
        ``timer_precision_s``), without a read of the store: what the day's comparison takes
        of each fit, with the row's values (a read of 2000 stored fits costs a second)."""
        if self.kept_fit is not None:
            return self.kept_fit.timer_precision_s
        return self.stored.timer_precision_s if self.stored is not None else None

    def lean(self) -> DescentResult:
        """The same result without what it need not keep: its speed curve, and its fit where
        the store has it (what a recording keeps of each descent)."""
        curve = self.speed_x is not None or self.speed_v is not None
        if not curve and (self.kept_fit is None or self.stored is None):
            return self
        fit = None if self.stored is not None else self.kept_fit
        return replace(self, kept_fit=fit, speed_x=None, speed_v=None)

    @property
    def number(self) -> int:
        return self.descent.number

    @property
    def start_time(self) -> str:
        return self.row.start_time

    def marked(self, invalid_reason: str) -> DescentResult:
        """The same result with the engineer's invalid mark (or none) on it."""
        if invalid_reason == self.row.invalid_reason:
            return self
        return replace(self, row=replace(self.row, invalid_reason=invalid_reason))


def start_time(d: DescentTimes, host_t: float | None, date: dt.date | None) -> str:
    """The device's time of day of the start, dated. Live, the date is the one that puts the
    start nearest the host's clock: a descent started at 23:59:58 and finished after midnight
    keeps its day, so start times never go backwards at midnight. In replay, the replay's
    date plus the days the device clock counted. A timer that dates its impulses (TAG: days
    since 2000-01-01) is believed over both. With a date, ISO 8601 with the local UTC offset of
    that date, so a reader elsewhere (or after the clocks changed) knows the instant: timers
    send local time of day."""
    if d.day is not None:
        tod_of_day = dt.timedelta(microseconds=d.start_us % DAY_US)
        start = dt.datetime(2000, 1, 1) + dt.timedelta(days=d.day) + tod_of_day
        return start.astimezone().isoformat()
    days, tod = divmod(d.start_us, DAY_US)
    t = (dt.datetime.min + dt.timedelta(microseconds=tod)).time()
    if host_t is not None and math.isfinite(host_t):  # (NaN: no host time to go by)
        host = dt.datetime.fromtimestamp(host_t)
        near = [dt.datetime.combine(host.date() + dt.timedelta(days=k), t) for k in (-1, 0, 1)]
        return min(near, key=lambda c: abs(c - host)).astimezone().isoformat()
    if date is None:
        return t.isoformat()
    return dt.datetime.combine(date + dt.timedelta(days=days), t).astimezone().isoformat()


@dataclass(frozen=True, slots=True)
class StoredFit:
    """Fits kept in the session's store, not in memory: the analyser that reads one back (by
    the handle its result keeps, :meth:`FitCache.handle`) or computes it again if the store no
    longer has it (another process compacted it, the file went), from the result's own inputs
    (descent, row) and the timer's precision. One for all the fits of an analyser and a
    precision, shared: a result keeps a reference and its handle."""

    analyser: Analyser
    timer_precision_s: float

    def load(self, res: DescentResult, handle: Hashable) -> FitResult | None:
        fits = self.analyser.fits
        fit = fits.get(handle) if fits is not None else None
        if fit is not None:
            return fit
        row = res.row
        job = FitJob(
            descent=res.descent, start_time=row.start_time, metadata=row.metadata,
            model=row.model, mass_kg=row.mass_kg, air_density=row.air_density,
            wind_ms=row.wind_ms, gravity=row.gravity, timer_precision_s=self.timer_precision_s,
        )  # fmt: skip
        return self.analyser.run(job).kept_fit


class FitCache(Protocol):
    """Fits stored with the session (:class:`station.session.fitstore.FitStore`): the analyser
    asks for a fit by the key of what it is computed from before it computes it."""

    def key(self, parts: dict[str, Any], survey_cov: np.ndarray | None) -> str: ...

    def get(self, key: Hashable) -> FitResult | None: ...

    def put(self, key: str, fit: FitResult) -> None: ...

    def handle(self, key: str) -> Hashable | None: ...


class Analyser:
    """Fits finished descents with the station's track, skier and air; grids built once per
    set of photocells."""

    def __init__(self, config: StationConfig, track: Track) -> None:
        self.config = config
        self.track = track
        self._runs: dict[tuple[str, ...], StraightRun] = {}
        # the g `station fit` uses too: normal gravity at the survey's latitude_deg, else the
        # station config's, else 9.80665; a config that contradicts the survey is said once
        site, self.site_warning = site_track(track, config)
        self.gravity = gravity_for(site)
        # the survey's covariance of the crossing times, per set of photocells: computed once
        # (~60 model solves, 15 ms; a fit with it given takes 2 ms) and reused, so the
        # intervals of every descent carry the track. It is linearised at the *reference fit*
        # of the first descent on them (in the order the descents end) whose reference fit is
        # good: its times fitted with the station config's model, mass and air, no wind —
        # nothing an annotation changes. Linearised at the first good fit as annotated, a
        # model or mass given to descent 1 after later descents took its covariance gave a
        # live day that a replay (annotations first) did not reproduce (6th digit). The speed
        # along the run the covariance depends on is what the times say, whichever model and
        # mass fit them. A descent that ended before its photocells had one computes its own,
        # at its own fit, now and whenever it is fitted again, as a replay computes it.
        self._survey_cov: dict[tuple[str, ...], np.ndarray] = {}
        #: the descent whose reference fit gave each set of photocells its covariance
        self.survey_source: dict[tuple[str, ...], int] = {}
        #: (descent, its photocells) fitted before those photocells had one (an edit at the
        #: timer may change a descent's photocells: each set is judged by itself)
        self._own_survey: set[tuple[int, tuple[str, ...]]] = set()
        #: fits stored with the session, when it has them: a fit found there is not computed
        self.fits: FitCache | None = None
        self._stored: dict[float, StoredFit] = {}  # what a result keeps of it, by precision
        #: the fitted speed along the run of every descent (one model solve each), for the
        #: views that draw it (the UI, the report); off for those that only list results
        self.speed_curves = True

    def run(self, job: FitJob) -> DescentResult:
        """Fit one descent; an exception of the fit is the descent's ``error`` status."""
        if job.gravity is None:  # the site's g, which the row then reports
            job = replace(job, gravity=self.gravity.value)
        if job.problem:
            # the covariance a later descent takes cannot hang on this one's annotations
            if job.descent.status != DescentStatus.ABORTED:
                with contextlib.suppress(Exception):
                    self._survey_for(job, self._run_of(job.descent.photocells))
            return error_result(job, job.problem)
        try:
            return self._fit(job)
        except Exception as exc:  # noqa: BLE001 - one failed fit must not end the day
            return error_result(job, f"fit failed: {type(exc).__name__}: {exc}")

    def hand_on(self, ids: tuple[str, ...], source: int, cov: np.ndarray) -> None:
        """The survey covariance of the photocells ``ids``, as descent ``source``'s reference
        fit gave it (the in-place annotate has it from the replay's descents file)."""
        self._survey_cov[ids] = cov
        self.survey_source[ids] = source

    def survey_sources(self) -> list[tuple[tuple[str, ...], int, np.ndarray]]:
        """Each set of photocells with a survey covariance, the descent whose reference fit
        gave it, and the covariance (the descents file of the in-place annotate keeps them)."""
        return [(ids, n, self._survey_cov[ids]) for ids, n in self.survey_source.items()]

    def own_survey(self, number: int, ids: tuple[str, ...]) -> None:
        """Descent ``number`` on the photocells ``ids`` was first fitted before they had a
        survey covariance: its fit computes its own (the in-place annotate has it from the
        replay's descents file)."""
        self._own_survey.add((number, ids))

    def computes_own(self, number: int, ids: tuple[str, ...]) -> bool:
        """Whether descent ``number``'s fit on ``ids`` computes its own survey covariance."""
        return (number, ids) in self._own_survey

    def _run_of(self, ids: tuple[str, ...]) -> tuple[StraightRun, np.ndarray]:
        run = self._runs.get(ids)
        xs = np.array([self.track.photocell(p).x for p in ids])
        if run is None:
            run = self._runs[ids] = StraightRun(self.track.profile, xs)
        return run, xs

    def _reference(self, job: FitJob) -> FitJob:
        """The job of a descent's reference fit: the station config's model, mass and air, no
        wind (none of them annotated), the day's g and timer precision."""
        config: StationConfig | None = self.config
        if config is None:  # an analyser without a config (tests): the job itself
            return job
        return replace(
            job, metadata=Metadata(), model=FitModel(config.model),
            mass_kg=float(config.mass_kg), air_density=config.air_density,
            wind_ms=0.0, gravity=self.gravity.value, problem="",
        )  # fmt: skip

    def _survey_for(
        self, job: FitJob, run: tuple[StraightRun, np.ndarray]
    ) -> tuple[np.ndarray | None, tuple[FitResult, str | None] | None]:
        """The survey covariance descent ``job.descent``'s fit takes (None: it computes its
        own), and its reference fit (with its key in the fit store) when that is the
        descent's own fit too."""
        d = job.descent
        ids = d.photocells
        if d.status == DescentStatus.ABORTED or (d.number, ids) in self._own_survey:
            return None, None
        cov = self._survey_cov.get(ids)
        if cov is not None:
            return cov, None
        ref_job = self._reference(job)
        alike = _parts(ref_job) == _parts(job)
        try:
            computed: tuple[FitResult, str | None] | None = self._computed(ref_job, run, None)
        except Exception:
            self._own_survey.add((d.number, ids))
            if alike:
                raise  # the descent's own fit failed: its error
            computed = None  # no reference: the descent computes its own
        same = computed if alike else None
        ref = computed[0] if computed is not None else None
        if ref is not None and ref.status == FitStatus.OK and ref.survey_time_cov is not None:
            self.hand_on(ids, d.number, ref.survey_time_cov)
            return ref.survey_time_cov, same
        self._own_survey.add((d.number, ids))
        return None, same

    def _computed(
        self, job: FitJob, run: tuple[StraightRun, np.ndarray], cov: np.ndarray | None
    ) -> tuple[FitResult, str | None]:
        """The fit of ``job`` with the survey covariance ``cov`` (None: its own), from the
        session's fit store when it has it; and its key there."""
        assert job.gravity is not None  # set by run()
        d = job.descent
        ids = d.photocells
        straight, xs = run
        cond = Conditions(job.mass_kg, job.air_density, job.wind_ms, g=job.gravity)
        t = (np.array(d.times_us) - d.times_us[0]) / 1e6
        key: str | None = None
        fit: FitResult | None = None
        if self.fits is not None:  # everything the fit below depends on but the session's files
            key = self.fits.key(_parts(job), cov)
            fit = self.fits.get(key)
        if fit is None:
            fit = fit_descent(
                self.track.profile, xs, t, cond, list(ids), model=job.model.value, run=straight,
                survey=survey_error(self.track, list(ids)) if cov is None else None,
                survey_time_cov=cov, timer_precision_s=job.timer_precision_s,
            )  # fmt: skip
            if self.fits is not None and key is not None:
                self.fits.put(key, fit)
        return fit, key

    def _fit(self, job: FitJob) -> DescentResult:
        d = job.descent
        assert job.gravity is not None  # set by run()
        cond = Conditions(job.mass_kg, job.air_density, job.wind_ms, g=job.gravity)
        if d.status == DescentStatus.ABORTED:
            return DescentResult(d, None, result_row(job, None))
        run = self._run_of(d.photocells)
        cov, same = self._survey_for(job, run)
        # the reference fit is this descent's own when its job is the reference's: the same
        # numbers as a fit given the covariance (which enters after the search), not fitted twice
        fit, key = same if same is not None else self._computed(job, run, cov)
        row = result_row(job, fit)
        curve = _speed_curve(run[0], fit, cond) if self.speed_curves else None
        speed_x, speed_v = curve if curve is not None else (None, None)
        stored = None
        handle = self.fits.handle(key) if key is not None and self.fits is not None else None
        if handle is not None:
            stored = self._stored.get(job.timer_precision_s)
            if stored is None:
                stored = self._stored[job.timer_precision_s] = StoredFit(
                    self, job.timer_precision_s
                )
        return DescentResult(d, fit, row, speed_x, speed_v, stored, handle)

    def speed_curve(self, res: DescentResult) -> tuple[np.ndarray, np.ndarray] | None:
        """The fitted skier's speed along the run of a result kept without it (a recording
        keeps a descent's ~12 kB curve only where it is shown: the UI asks for the one it
        shows). The same solve as the fit's own; None where there is no fit to draw."""
        fit = res.fit
        if fit is None:
            return None
        ids = res.descent.photocells
        run = self._runs.get(ids)
        if run is None:
            xs = np.array([self.track.photocell(p).x for p in ids])
            run = self._runs[ids] = StraightRun(self.track.profile, xs)
        row = res.row
        cond = Conditions(row.mass_kg, row.air_density, row.wind_ms, g=row.gravity)
        return _speed_curve(run, fit, cond)


def _parts(job: FitJob) -> dict[str, Any]:
    """What a descent's fit is computed from, but the session's files (the fit store's key)."""
    d = job.descent
    return {
        "times_us": list(d.times_us), "photocells": list(d.photocells), "model": job.model.value,
        "mass_kg": job.mass_kg, "air_density": job.air_density, "wind_ms": job.wind_ms,
        "g": job.gravity, "timer_precision_s": job.timer_precision_s,
    }  # fmt: skip


def _speed_curve(
    run: StraightRun, fit: FitResult, cond: Conditions
) -> tuple[np.ndarray, np.ndarray] | None:
    cda, mu, v0 = fit.cda.value, fit.mu.value, fit.v0.value
    if cda is None or mu is None or v0 is None:
        return None
    mu1 = fit.mu1.value if fit.mu1 is not None else None
    sol = run.solve(Params(cda, mu, v0, mu1 or 0.0), cond, sensitivities=False)
    return _frozen(sol.x), _frozen(sol.speed)


def _frozen(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def result_row(job: FitJob, fit: FitResult | None) -> ResultRow:
    """The row of the results for a descent and its fit (None: not fitted)."""
    d = job.descent
    cda = fit.cda if fit else MISSING
    mu = fit.mu if fit else MISSING
    v0 = fit.v0 if fit else MISSING
    mu1 = fit.mu1 if fit and fit.mu1 is not None and job.model == FitModel.VELOCITY else MISSING
    rms = None
    if fit is not None and fit.residuals_s:
        # every photocell: each time is data (the fit's free offset takes the first one's noise)
        r = np.array(list(fit.residuals_s.values()))
        rms = float(np.sqrt(np.mean(r**2)) * 1000) if r.size else None
    flags = d.flags
    if fit is None:
        status = ResultStatus.ABORTED
    else:
        status, why = fit_status(fit.status)
        flags = (*flags, why) if why else flags
    return ResultRow(
        descent=d.number,
        start_time=job.start_time,
        photocells_used=len(d.photocells),
        missing=d.missing,
        v0=v0.value,
        cda=cda.value,
        cda_lo=cda.lo,
        cda_hi=cda.hi,
        mu=mu.value,
        mu_lo=mu.lo,
        mu_hi=mu.hi,
        mu1=mu1.value,
        sigma_s2=fit.sigma_s2 if fit else None,
        rms_residual_ms=rms,
        status=status,
        descent_status=d.status,
        flags=flags,
        model=job.model,
        mass_kg=job.mass_kg,
        air_density=job.air_density,
        gravity=job.gravity if job.gravity is not None else G_STANDARD,
        wind_ms=job.wind_ms,
        metadata=job.metadata,
    )


def error_result(job: FitJob, reason: str) -> DescentResult:
    """A descent whose fit failed: ``status: error``, the reason last among its flags."""
    row = result_row(job, None)
    row = replace(row, status=ResultStatus.ERROR, flags=(*row.flags, reason))
    return DescentResult(job.descent, None, row)
