"""Shared fixtures: the real instrument files, the demo track, and a runner for the CLI."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
SURVEYS = ROOT / "surveys"
DEMO_SURVEY = SURVEYS / "demo_run.yaml"


def real_fixtures() -> Path:
    """``../shared/fixtures/real`` beside the checkout (or $STATION_REAL_FIXTURES).

    Outside CI a missing folder skips the tests that need it; in CI it is an error, so a
    broken checkout can never pass by skipping.
    """
    path = Path(
        os.environ.get("STATION_REAL_FIXTURES", ROOT.parent / "shared" / "fixtures" / "real")
    )
    if not path.is_dir():
        if os.environ.get("CI"):
            raise RuntimeError(f"real fixtures not found at {path}")
        pytest.skip(f"real fixtures not found at {path}")
    return path


@pytest.fixture(scope="session")
def real() -> Path:
    return real_fixtures()


@pytest.fixture(scope="session")
def demo_track():
    from station.survey.load import load_survey
    from station.survey.track import build_track

    return build_track(load_survey(str(DEMO_SURVEY)))


@pytest.fixture(scope="session")
def demo_xs(demo_track) -> np.ndarray:
    return np.array([pc.x for pc in demo_track.photocells])


def station_cmd() -> list[str]:
    exe = shutil.which("station")
    return [exe] if exe else [sys.executable, "-m", "station"]


@pytest.fixture
def run_station():
    """Run the real ``station`` command; returns the CompletedProcess."""

    def run(*args: str, cwd: str | Path | None = None) -> subprocess.CompletedProcess:
        return subprocess.run(
            [*station_cmd(), *map(str, args)],
            capture_output=True,
            text=True,
            cwd=cwd,
            timeout=120,
        )

    return run
