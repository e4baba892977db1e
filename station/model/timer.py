"""The timer's precision: the standard deviation of one recorded crossing time, and how
improbable residuals must be under it before a fit is called poor.

One fact, read by the single fit's goodness-of-fit test (:mod:`station.model.track_error`) and
by the day model's (:mod:`station.model.compare`): a descent and the day it belongs to are
judged against the same timer. Where it comes from, first found wins: ``--timer-ms`` on the
command line, ``timer: {precision_ms: …}`` in the station config, the resolution the timer
states in its impulses (:func:`precision_from_resolution`), else :data:`TIMER_PRECISION_S`.

Pure data and arithmetic, on the fit's start-up path: the standard library only.
"""

from __future__ import annotations

import math

#: precision (s) of one crossing time when nothing else is known: a 1 ms timer resolution
#: (rounding, sd 1 ms/√12 = 0.29 ms) combined with ~0.4 ms of photocell trigger jitter (which
#: part of the body breaks a beam some 1 cm wide, at 20–25 m/s); √(0.29² + 0.4²) ≈ 0.5 ms. A
#: finer timer (ALGE 1/10 000 s) is not credited with less: the jitter dominates.
TIMER_PRECISION_S = 0.5e-3
#: the photocell's trigger jitter (s) that a coarse timer's rounding adds to
PHOTOCELL_JITTER_S = 0.4e-3
#: a fit (one descent or the day) whose residuals are this improbable under the timer's
#: precision (χ² test) is a poor fit: status ``poor-fit``
POOR_FIT_P = 1e-3


def precision_from_resolution(resolution_us: int | None) -> float:
    """The precision (s) of a timer that states its resolution (µs; ``Impulse.resolution_us``):
    the rounding's sd (resolution/√12) combined with the photocell's jitter, never below
    :data:`TIMER_PRECISION_S`. Only a coarse timer moves it: a keypad's 1/100 s gives 2.9 ms;
    1 ms and finer give 0.5 ms. None or 0 (not stated): :data:`TIMER_PRECISION_S`."""
    if not resolution_us or resolution_us <= 0:
        return TIMER_PRECISION_S
    rounding = resolution_us * 1e-6 / math.sqrt(12.0)
    return max(TIMER_PRECISION_S, math.hypot(rounding, PHOTOCELL_JITTER_S))
