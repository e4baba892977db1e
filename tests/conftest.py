"""Shared fixtures: the real instrument files, the demo track, and runners for the CLI (in this
process, and as a separate process).

Tests that need a pseudo-terminal, tmux or real time are marked ``slow``; ``pytest -m "not slow"``
runs the rest in about a minute. CI runs them all."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
import traceback
import warnings
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
def run_station(capsys, monkeypatch):
    """Run ``station`` in this process, ``station.cli.main.main(args)``, as the command would:
    returns a CompletedProcess with the exit status and what it printed. As in a real process,
    an exception that escapes becomes exit status 1 and a traceback on stderr, and a Python
    warning is printed on stderr (so "one line on stderr" still fails on a stray warning);
    tests of the installed command itself use ``run_station_process``."""

    def run(*args: str, cwd: str | Path | None = None) -> subprocess.CompletedProcess:
        from station.cli.main import main

        argv = list(map(str, args))
        capsys.readouterr()  # what the test printed before is not the command's output
        with monkeypatch.context() as m, warnings.catch_warnings(record=True) as caught:
            # Python's default filters for a script: each warning once, no deprecations
            warnings.resetwarnings()
            warnings.simplefilter("default")
            for category in (
                DeprecationWarning,
                PendingDeprecationWarning,
                ImportWarning,
                ResourceWarning,
            ):
                warnings.simplefilter("ignore", category)
            if cwd is not None:
                m.chdir(cwd)
            try:
                code: object = main(argv)
            except SystemExit as exc:  # argparse: --help, --version, usage errors
                code = exc.code
            except Exception:
                traceback.print_exc()
                code = 1
        if code is None:
            code = 0
        elif not isinstance(code, int):  # sys.exit("message"): printed, status 1
            print(code, file=sys.stderr)
            code = 1
        out = capsys.readouterr()
        err = out.err + "".join(
            warnings.formatwarning(w.message, w.category, w.filename, w.lineno) for w in caught
        )
        return subprocess.CompletedProcess(["station", *argv], code, out.out, err)

    return run


@pytest.fixture
def run_station_process():
    """Run the installed ``station`` command as a separate process; returns the
    CompletedProcess. For what only a real process shows: the console script, exit status."""

    def run(*args: str, cwd: str | Path | None = None) -> subprocess.CompletedProcess:
        return subprocess.run(
            [*station_cmd(), *map(str, args)],
            capture_output=True,
            text=True,
            cwd=cwd,
            timeout=120,
        )

    return run


@pytest.fixture(scope="session")
def pg():
    """One real PostgreSQL server for the season store's tests on both engines (Debian's
    binaries: tests/season_helpers.PgServer); each test makes its own database on it."""
    from tests.season_helpers import PgServer

    server = PgServer()
    try:
        yield server
    finally:
        server.close()


@pytest.fixture
def replays(monkeypatch):
    """The sessions a RecordedSession replayed (its ``run``), in order: a test of the in-place
    annotate asserts none ran."""
    from station.session.recorded_session import RecordedSession

    calls: list[str] = []
    run = RecordedSession.run

    def counted(self):
        calls.append(self.path)
        return run(self)

    monkeypatch.setattr(RecordedSession, "run", counted)
    return calls
