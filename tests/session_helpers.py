"""A recorded test day in a second, for the tests of what reads sessions (export, sessions,
report): the model's own times for each descent, written as the ALGE lines a timer sends into
a raw log with host times, a real session snapshot and its results CSV. The end-to-end tests on
the simulated timer (tests/test_record.py) cover the recording itself."""

from __future__ import annotations

import datetime as dt
import json
import os
from pathlib import Path

import numpy as np

from tests.timing_helpers import ALGE_CHANNELS, write_config

#: 2026-02-02 10:00 local time: a test day's morning
T0 = dt.datetime(2026, 2, 2, 10, 0).timestamp()


def make_session(
    tmp_path: Path,
    order: str = "ABBAABBA",
    mus: dict[str, float] | None = None,
    cda: float = 0.22,
    interval_s: float = 300.0,
    noise_ms: float = 0.3,
    seed: int = 1,
    annotate: bool = True,
    config_extra: str = "",
    drift_per_hour: float = 0.0,
) -> Path:
    """A session of ``len(order)`` descents of items A, B … (with ski annotations); μ drifts
    by ``drift_per_hour`` from the first descent on."""
    from station.model.physics import Conditions, Params, StraightRun
    from station.session import store
    from station.session.acquisition import replay
    from station.session.config import load_config
    from station.session.rawlog import RawLogWriter
    from station.session.records import Metadata, MetadataAnnotation
    from station.survey.load import load_survey
    from station.survey.track import build_track
    from station.timing.wireformats import format_alge

    mus = mus or {"A": 0.0085, "B": 0.0095}
    cfg_path = write_config(tmp_path, "/dev/ttyUSB0", extra=config_extra)
    session = tmp_path / "session"
    cfg = load_config(str(cfg_path))
    store.create(cfg, str(session))
    cfg = store.load_session_config(str(session))
    track = build_track(load_survey(cfg.survey_path))
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)
    rng = np.random.default_rng(seed)
    log = RawLogWriter(str(session / store.RAW), header={"port": "/dev/ttyUSB0"})
    channels = list(ALGE_CHANNELS)
    bib = 0
    for k, item in enumerate(order):
        t_start = T0 + k * interval_s
        sol = run.solve(
            Params(
                cda,
                mus[item] + drift_per_hour * k * interval_s / 3600.0,
                3.0 + 0.3 * rng.standard_normal(),
            ),  # fmt: skip
            Conditions(88.0, 1.079),
            sensitivities=False,
        )
        times = sol.t + np.r_[0.0, rng.normal(0, noise_ms * 1e-3, len(sol.t) - 1)]
        day_start = dt.datetime.fromtimestamp(t_start)
        tod0 = (day_start.hour * 3600 + day_start.minute * 60 + day_start.second) * 10**6
        for ch, t in zip(channels, times, strict=True):
            bib += 1
            line = format_alge(ch, tod0 + int(round(t * 1e6)), bib)
            log.write(t_start + float(t) + 0.01, (line + "\r").encode("ascii"))
    log.close()
    raw = session / store.RAW  # as if recorded that day: header time, file date
    lines = raw.read_text().splitlines()
    lines[0] = json.dumps({**json.loads(lines[0]), "t": T0 - 60.0}, separators=(",", ":"))
    raw.write_text("\n".join(lines) + "\n")
    os.utime(raw, (t_start + 60.0, t_start + 60.0))
    if annotate:
        for item in sorted(set(order)):
            numbers = [k + 1 for k, it in enumerate(order) if it == item]
            store.append_annotation(
                str(session),
                MetadataAnnotation(
                    Metadata(ski=f"pair {item}", wax="blue"), descents=tuple(numbers), t=T0
                ),
            )
    done = replay(str(session), cfg)
    done.write_csv(str(session / store.RESULTS))
    return session


def read_json_lines(path: Path) -> list[dict]:
    return [json.loads(x) for x in path.read_text().splitlines() if x.strip()]


def live_comparison_text(track, results) -> str:
    """The comparison's text as the UI's panel shows it: the live comparison, rendered."""
    from station.report.comparison_text import comparison_view
    from station.session.comparison import compare_results

    return comparison_view(compare_results(track, results, at_least=2))
