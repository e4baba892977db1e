"""What a fit says of one parameter, and what it says of itself: the typed answer every view
(the terminal, the results CSV, the JSON, the report, the UI) renders, so none of them looks a
parameter up by its name in a dictionary.

Pure: the standard library only (it is on the fit's start-up path).
"""

from __future__ import annotations

from dataclasses import dataclass
from enum import StrEnum


class FitStatus(StrEnum):
    """The verdict of one descent's fit, most serious first in :func:`station.model.fit.
    fit_descent`. The values are the strings earlier versions wrote (JSON, results CSV)."""

    OK = "ok"
    ILL_CONDITIONED = "ill-conditioned"  # a parameter's interval is wider than itself
    LIFT_OFF = "lift-off"  # the fitted skier leaves the snow
    STOPPED = "stopped"  # the fitted skier stops before the last photocell
    TOO_FEW_PHOTOCELLS = "too-few-photocells"
    NOT_CONVERGED = "not-converged"
    POOR_FIT = "poor-fit"  # residuals far above the timer's precision (χ² test)


@dataclass(frozen=True)
class Estimate:
    """One fitted parameter: its value, 90 % interval and standard error (None where the data
    do not give one: not fitted, no degree of freedom left, or not identifiable).

    Where the fit carried the survey's uncertainty, ``ci90`` and ``stderr`` include it and the
    timing-only ones are kept beside them with the survey's share of the variance."""

    value: float | None
    ci90: tuple[float, float] | None = None
    stderr: float | None = None
    ci90_timing: tuple[float, float] | None = None
    stderr_timing: float | None = None
    survey_share: float | None = None
    #: the 90 % interval is wider than the value itself: the data do not determine it
    not_identifiable: bool = False
    #: a signed effect (μ1) whose 90 % interval includes 0: shown, with this flag, not hidden
    consistent_with_zero: bool = False

    @property
    def lo(self) -> float | None:
        return None if self.ci90 is None else self.ci90[0]

    @property
    def hi(self) -> float | None:
        return None if self.ci90 is None else self.ci90[1]


#: a parameter the fit did not estimate
MISSING = Estimate(None)
