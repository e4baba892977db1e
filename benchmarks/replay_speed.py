"""Replay speed: parse and assemble a long capture, and a test day end to end with fits.

1. A plain ALGE capture of 11 200 descents × 9 photocells = 100 800 impulse lines (2.7 MB,
   four days of device time), replayed by ``station replay CAPTURE --no-fit`` in this process
   (reading the file, framer, parser, descent assembler; no fits), against a bare loop over
   the same file: ``for line in text.split("\r"): line.split()``. Both alternate, 5 runs
   each, CPU time of this process (the shared machine's load hits both alike); target: the
   replay at ≥ 1/20 of the bare loop's lines/s. The same lines are replayed from a session's
   raw log too (``raw.jsonl``, one record per line as a live recording writes them at the
   timer's pace: reading and checking each JSON record, framing, parsing, assembling), against
   the same bare loop, and from a raw log with each line in two reads (a USB serial adapter's
   16-byte pieces: 201 600 records). The parser alone is timed too.
2. A 50-descent capture with timing noise, double triggers and running-time lines, replayed
   end to end: parse, assemble, fit every descent, write the results CSV.

BLAS is capped at one thread while the replays run (station.runtime), as ``station``'s command
line caps it before numpy loads (``station.runtime.one_blas_thread``): the command's set-up
fits the survey's smoothing spline (one 68 × 68 eigh), which a pool of BLAS threads on the
shared 2-core machine made 50-90 ms of CPU instead of 0.5 ms. This process (and
speed_table.py) has numpy loaded before it calls the command, so without the cap it measured
a thread pool the command never has (0.5 µs a line of the capture, 1/5 of the replay's time).

Run: python benchmarks/replay_speed.py
"""

from __future__ import annotations

import contextlib
import io
import os
import statistics
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from station import runtime  # noqa: E402
from station.model.physics import Conditions, Params, StraightRun  # noqa: E402
from station.session.config import load_config  # noqa: E402
from station.session.runs import replay  # noqa: E402
from station.survey.load import load_survey  # noqa: E402
from station.survey.track import build_track  # noqa: E402
from station.timing.impulses import format_tod  # noqa: E402
from station.timing.wireformats import format_alge  # noqa: E402

CONFIG = """\
serial: {{port: loop://, protocol: alge}}
survey: {survey}
photocells: {{C0: PC1, C1: PC2, C2: PC3, C3: PC4, C4: PC5, C5: PC6, C6: PC7, C7: PC8, C8: PC9}}
skier: {{mass_kg: 88}}
air: {{density: 1.079}}
"""


def demo_station():
    """The station config of these benchmarks (written to a temporary file) and its track."""
    tmp = tempfile.mkdtemp(prefix="station-bench-")
    cfg_path = os.path.join(tmp, "station.yaml")
    with open(cfg_path, "w") as fh:
        fh.write(CONFIG.format(survey=ROOT / "surveys" / "demo_run.yaml"))
    cfg = load_config(cfg_path)
    return cfg, build_track(load_survey(cfg.survey_path))


def cpu(fn) -> float:  # type: ignore[no-untyped-def]
    """CPU seconds of this process that ``fn()`` took."""
    start = time.process_time()
    fn()
    return time.process_time() - start


def bare_loop(path: str) -> None:
    """The floor: the file read, its lines split into fields, nothing more."""
    with open(path, "rb") as fh:
        text = fh.read().decode("latin-1")
    for line in text.split("\r"):
        line.split()


def no_fit(path: str, config: str) -> None:
    """``station replay PATH --config CONFIG --no-fit`` in this process, output discarded."""
    from station.cli.main import main as station

    out = io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(out):
        status = station(["replay", path, "--config", config, "--no-fit", "--date", "2026-01-05"])
    assert status == 0, out.getvalue()[-500:]
    assert "11,200 descents" in out.getvalue() or "11200 descents" in out.getvalue()


def write_session(folder: str, lines: list[str], config: str, pieces: bool = False) -> str:
    """A session folder whose raw log holds ``lines``, one record each (a live recording's
    shape: the timer sends a line, the reader thread logs it), 0.3 s of host time apart; with
    ``pieces``, each line in two reads 16 ms apart, its first 16 bytes and the rest (as a USB
    serial adapter hands a line on, its latency timer 16 ms)."""
    import json
    import shutil

    os.makedirs(folder, exist_ok=True)
    shutil.copy(config, os.path.join(folder, "config.yaml"))
    t = 1_767_600_000.0
    with open(os.path.join(folder, "raw.jsonl"), "w", encoding="ascii") as fh:
        fh.write(json.dumps({"t": t, "event": "session", "detail": {"station": "bench"}},
                            separators=(",", ":")) + "\n")  # fmt: skip
        for k, line in enumerate(lines):
            reads = [(0.0, line[:16]), (0.016, line[16:])] if pieces else [(0.0, line)]
            for dt, part in reads:
                rec = {"t": round(t + 0.3 * k + dt, 6), "rx": part}
                fh.write(json.dumps(rec, ensure_ascii=True, separators=(",", ":")) + "\n")
    return folder


def parse_only(data: bytes) -> None:
    from station.timing.framing import LineFramer
    from station.timing.wireformats import make_parser

    framer, parser = LineFramer(), make_parser("alge")
    for k in range(0, len(data), 4096):
        for line in framer.feed(data[k : k + 4096]):
            parser.parse(line)


def measure_replay(runs: int = 5) -> dict[str, float]:
    """lines/s of ``replay --no-fit``, the parser alone and the bare loop (medians, CPU)."""
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    times = (
        StraightRun(track.profile, xs)
        .solve(Params(0.22, 0.0085, 3.4), Conditions(88, 1.079), sensitivities=False)
        .t
    )
    lines = []
    t0 = 8 * 3600 * 10**6
    n = 0
    for _ in range(11_200):
        for i, ti in enumerate(times):
            n += 1
            lines.append(format_alge(f"C{i}", (t0 + int(ti * 1e6)) % 86_400_000_000, n) + "\r")
        t0 += 25_000_000
    data = "".join(lines).encode("ascii")
    big = os.path.join(os.path.dirname(cfg.path), "four-days.txt")
    with open(big, "wb") as fh:
        fh.write(data)
    session = write_session(os.path.join(os.path.dirname(cfg.path), "session"), lines, cfg.path)
    halves = write_session(os.path.join(os.path.dirname(cfg.path), "halves"), lines, cfg.path,
                           pieces=True)  # fmt: skip
    rates: dict[str, list[float]] = {
        "replay --no-fit": [], "session --no-fit": [], "session, 2 reads a line": [],
        "parser alone": [], "bare loop": []
    }  # fmt: skip
    with runtime.blas_on_one_thread():  # as the command runs (see above)
        for _ in range(runs):
            rates["bare loop"].append(len(lines) / cpu(lambda: bare_loop(big)))
            rates["replay --no-fit"].append(len(lines) / cpu(lambda: no_fit(big, cfg.path)))
            rates["session --no-fit"].append(len(lines) / cpu(lambda: no_fit(session, cfg.path)))
            rates["session, 2 reads a line"].append(
                len(lines) / cpu(lambda: no_fit(halves, cfg.path))
            )
            rates["parser alone"].append(len(lines) / cpu(lambda: parse_only(data)))
    return {k: statistics.median(v) for k, v in rates.items()}


def main() -> int:
    cfg, track = demo_station()
    xs = np.array([pc.x for pc in track.photocells])
    run = StraightRun(track.profile, xs)

    # 1. parse + assemble: station replay --no-fit against a bare loop
    med = measure_replay()
    print(f"replay of 100,800 impulse lines (2.7 MB, 11 200 descents), median of 5, CPU time, "
          f"load {os.getloadavg()[0]:.1f}, one BLAS thread")  # fmt: skip
    for k, v in med.items():
        print(f"  {k:<23} {v:>12,.0f} lines/s   1/{med['bare loop'] / v:.1f} of the bare loop")
    for k in ("replay --no-fit", "session --no-fit", "session, 2 reads a line"):
        ratio = med[k] / med["bare loop"]
        print(f"  {k} at {ratio * 20:.2f}× the target (1/20 of the bare loop)")

    # 2. a 50-descent day end to end
    rng = np.random.default_rng(7)
    out = []
    t0 = 9 * 3600 * 10**6
    n = 0
    for _ in range(50):
        p = Params(rng.uniform(0.18, 0.3), rng.uniform(0.006, 0.03), rng.uniform(2, 6))
        t = run.solve(p, Conditions(88, 1.079), sensitivities=False).t
        t = t + np.concatenate([[0], rng.normal(0, 3e-4, len(t) - 1)])
        for s in range(0, 20, 1):  # running-time lines before the start
            out.append(format_tod(t0 - (20 - s) * 1_000_000, 1) + "\r")
        for i, ti in enumerate(t):
            n += 1
            tod = t0 + int(round(ti * 1e6))
            out.append(format_alge(f"C{i}", tod, n) + "\r")
            if rng.random() < 0.1:
                n += 1
                out.append(format_alge(f"C{i}", tod + 50_000, n) + "\r")
        t0 += 40_000_000
    tmp = os.path.dirname(cfg.path)  # the benchmark's temporary folder
    cap = os.path.join(tmp, "day.txt")
    with open(cap, "w", newline="") as fh:
        fh.write("".join(out))
    secs = []
    for _ in range(3):
        start = time.perf_counter()
        r = replay(cap, cfg)
        r.write_csv(os.path.join(tmp, "results.csv"))
        secs.append(time.perf_counter() - start)
    med = statistics.median(secs)
    statuses = {}
    for res in r.results():
        statuses[res.row.status.value] = statuses.get(res.row.status.value, 0) + 1
    print(f"end to end: 50 descents, {len(out)} lines, fits and CSV: median {med * 1e3:.0f} ms "
          f"({med / 50 * 1e3:.1f} ms per descent); statuses {statuses}")  # fmt: skip
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
