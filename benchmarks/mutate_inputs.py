"""Mutated input files through the real command line: how many runs end in a traceback or hang.

Every file a user hands the station is mutated in many ways (numbers replaced by NaN, infinity,
huge or negative values, decimal commas, text; truncation, bit flips, binary junk, invalid
UTF-8, NUL bytes; YAML nested 20 000 deep, alias bombs, recursive aliases, unsafe tags; special
files: /dev/zero, /dev/urandom, a FIFO, a folder, a symlink loop, a sparse file over the size
limit) and run through the command that reads it:

    config       station replay CAPTURE --config MUTATED       (config, survey, fits)
    survey YAML  station fit --survey MUTATED --times ...
    GSI          station fit --survey YAML-POINTING-AT-MUTATED --times ...
    times        station fit --survey ... --times MUTATED
    capture      station replay MUTATED --config ...
    import       station import MUTATED --config ... --session-dir NEW   (memory download)
    raw log      station replay SESSION        (SESSION/raw.jsonl MUTATED: also hostile
                 records, a torn tail), and station import CAPTURE --into SESSION
    annotations  station replay SESSION        (SESSION/annotations.jsonl MUTATED)

Each run is ``station.cli.main.main(argv)`` in a forked child of a process that has already
imported everything (a fresh interpreter per run would take a second or two each), with a
memory limit, killed after ``--timeout`` seconds. A run is

- a traceback: exit status other than 0 and 2, or "Traceback" on stderr (target 0);
- a hang: still running at the time-out (target 0);
- a multi-line error: exit status 2 with more than one line on stderr (target 0).

    python benchmarks/mutate_inputs.py [--seed 1] [--timeout 15] [--show 20]
"""

from __future__ import annotations

import argparse
import os
import random
import re
import resource
import shutil
import signal
import sys
import tempfile
import time
import traceback
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SURVEYS = ROOT / "surveys"
MEMORY_LIMIT = 3 * 1024**3  # a run that needs more is a failure, not a machine out of memory

BAD_NUMBERS = [
    ".nan", ".NaN", ".inf", "-.inf", "1.0e+308", "1e308", "-1", "0", "9" * 400, "9" * 5000,
    "'12,5'", "12,5", "abc", "[]", "{}", "null", "true", "0x10", "1_000", "'٣'", "'4²'",
]  # fmt: skip
BAD_TIMES = [
    "nan", "inf", "-inf", "1e400", "1e300", "-5", "", "abc", "10:41:07,2345", "4,5", "25:00:00",
    "10:61:00", "10:00:60", "²", "٣", "1,234.5", "10:41", "::", "1e-300", "0x1p3",
    '"10:41:07,2', "\x00", "\xff",
]  # fmt: skip


@dataclass(frozen=True)
class Case:
    kind: str
    name: str
    argv: list[str]


# ----------------------------------------------------------------------------- mutations


def numbers_replaced(text: str) -> Iterator[tuple[str, str]]:
    """Every number of a YAML text replaced by every bad value, one at a time."""
    pattern = re.compile(r"(?<=[:\[,{]\s)(-?[0-9][0-9.]*|null)(?=\s*(?:[,}\]#]|$))", re.M)
    for m in pattern.finditer(text):
        line = text.count("\n", 0, m.start()) + 1
        for bad in BAD_NUMBERS:
            yield f"line{line}={bad[:12]}", text[: m.start()] + bad + text[m.end() :]


def yaml_structures(text: str) -> Iterator[tuple[str, str]]:
    bomb = ['lol0: &a0 ["lol","lol","lol","lol","lol","lol","lol","lol","lol"]']
    for i in range(1, 9):
        bomb.append(f"lol{i}: &a{i} [" + ",".join([f"*a{i - 1}"] * 9) + "]")
    yield "deep-flow", text + "deep: " + "[" * 20000 + "]" * 20000 + "\n"
    yield "deep-block", text + "deep:\n" + "".join(" " * (i + 1) + f"k{i}:\n" for i in range(3000))
    yield "deep-mapping", text + "deep: " + "{a: " * 5000 + "1" + "}" * 5000 + "\n"
    yield "alias-bomb", "\n".join(bomb) + "\n" + text
    under = "\nbomb:\n  " + "\n  ".join(bomb) + "\nair:"
    yield "alias-bomb-under-key", text.replace("\nair:", under)
    yield "recursive-alias", text + "loop: &l [*l]\n"
    yield "recursive-map", text + "loop: &m {a: *m}\n"
    yield "python-tag", text + "evil: !!python/object/apply:os.system ['echo pwned']\n"
    yield "binary-tag", text + "blob: !!binary aGVsbG8=\n"
    yield "timestamp", text.replace("88", "2001-12-14t21:59:43.10-05:00", 1)
    yield "list-key", text + "? [a, b]\n: 1\n"
    yield "map-key", text + "? {a: 1}\n: 1\n"
    yield "duplicate-key", text + text.splitlines()[-1] + "\n"
    yield "merge-key", "base: &b {x: 1}\n" + text + "merged: {<<: *b}\n"
    yield "tabs", text.replace("  ", "\t")
    yield "top-list", "- " + text.replace("\n", "\n  ")
    yield "top-scalar", "just text\n"
    yield "null-doc", "~\n"
    yield "two-docs", text + "---\n" + text
    yield "long-line", text + "x: " + "a" * 1_000_000 + "\n"
    yield "long-key", text + "k" * 100_000 + ": 1\n"
    yield "unclosed-quote", text + 'x: "unclosed\n'
    yield "unclosed-flow", text + "x: [1, 2\n"


def generic(data: bytes, rng: random.Random) -> Iterator[tuple[str, bytes]]:
    n = len(data)
    for frac in (0.1, 0.25, 0.5, 0.75, 0.99):
        yield f"truncated-{frac:g}", data[: int(n * frac)]
    yield "empty", b""
    yield "only-newlines", b"\n\n\n"
    yield "junk", bytes(rng.randrange(256) for _ in range(2000))
    junk = bytes(rng.randrange(256) for _ in range(200))
    yield "junk-middle", data[: n // 2] + junk + data[n // 2 :]
    yield "latin1", data.replace(b"e", b"\xe9", 3)
    yield "invalid-utf8", data[: n // 3] + b"\xff\xfe\xc3" + data[n // 3 :]
    yield "nul", data[: n // 2] + b"\x00" * 10 + data[n // 2 :]
    yield "utf16", data.decode("latin-1").encode("utf-16")
    yield "bom", b"\xef\xbb\xbf" + data
    yield "crlf", data.replace(b"\n", b"\r\n")
    yield "cr", data.replace(b"\n", b"\r")
    yield "no-newlines", data.replace(b"\n", b" ")
    for k in range(12):
        flipped = bytearray(data)
        for _ in range(1 + k % 3):
            i = rng.randrange(n)
            flipped[i] ^= 1 << rng.randrange(8)
        yield f"bitflip-{k}", bytes(flipped)


def gsi_mutations(data: bytes, rng: random.Random) -> Iterator[tuple[str, bytes]]:
    lines = data.split(b"\n")

    def at(i: int, new: bytes) -> bytes:
        out = list(lines)
        out[i] = new
        return b"\n".join(out)

    for k in range(30):
        i = rng.randrange(1, len(lines) - 1)
        line = lines[i]
        words = line.split(b" ")
        w = rng.randrange(len(words))
        choice = k % 10
        if choice == 0:
            words[w] = words[w][:7] + b"+" + b"9" * max(1, len(words[w]) - 8)
        elif choice == 1:
            words[w] = words[w][:7] + b"+nan" + b"0" * 12
        elif choice == 2:
            words[w] = words[w][:5] + b"9" + words[w][6:]  # unit code
        elif choice == 3:
            words[w] = words[w][: len(words[w]) // 2]
        elif choice == 4:
            words[w] = words[w].replace(b"0", b",", 1)
        elif choice == 5:
            del words[w]
        elif choice == 6:
            words[w] = words[w][:7] + b"-" + words[w][8:]
        elif choice == 7:
            words[w] = words[w][:7] + b"+inf"
        elif choice == 8:
            words[w] = b"*" + words[w] if not words[w].startswith(b"*") else words[w][1:]
        else:
            words[w] = words[w][:1] + b"\xb2" + words[w][2:]
        yield f"word-{k}", at(i, b" ".join(words))
    yield "duplicate-line", at(5, lines[4])
    yield "no-setup", b"\n".join(ln for ln in lines if b"ST" not in ln[:30])
    yield "gsi8-mixed", at(3, lines[3].lstrip(b"*"))


def times_mutations(text: str) -> Iterator[tuple[str, str]]:
    lines = text.splitlines()
    header_at = next(i for i, ln in enumerate(lines) if ln.startswith("photocell"))
    body = lines[header_at + 1 :]
    for row in (0, 4):
        pc = body[row].split(",")[0]
        for bad in BAD_TIMES:
            new = list(lines)
            new[header_at + 1 + row] = f"{pc},{bad}"
            yield f"row{row}={bad[:10]!r}", "\n".join(new) + "\n"
    semi = [ln.replace(",", ";").replace(".", ",") for ln in lines]
    yield "semicolon-decimal-comma", "\n".join(semi) + "\n"
    yield "comma-decimal-comma", "\n".join(ln.replace(".", ",") for ln in lines) + "\n"
    yield "tab", "\n".join(ln.replace(",", "\t") for ln in lines) + "\n"
    yield "no-header", "\n".join(body) + "\n"
    yield "header-only", lines[header_at] + "\n"
    yield "swapped", "\n".join(",".join(ln.split(",")[::-1]) for ln in lines[header_at:]) + "\n"
    yield "extra-column", "\n".join(ln + ",x" for ln in lines[header_at:]) + "\n"
    yield "duplicate-pc", "\n".join([*lines, body[0]]) + "\n"
    yield "unknown-pc", "\n".join([*lines, "PC42,10:41:30.0"]) + "\n"
    yield "one-row", "\n".join(lines[: header_at + 2]) + "\n"
    yield "same-times", "\n".join([lines[header_at]] + [f"PC{i},10:41:07.0" for i in (1, 2, 3)])
    yield "reversed", "\n".join([lines[header_at], *body[::-1]]) + "\n"
    yield "unbalanced-quote", "\n".join([*lines, 'PC9,"10:41'])
    yield "mixed-forms", "\n".join([lines[header_at], "PC1,0", "PC2,10:41:10.0"]) + "\n"
    yield "midnight", "\n".join([lines[header_at], "PC1,23:59:59.0", "PC2,00:00:03.5"]) + "\n"
    yield "many-columns", "photocell,time" + ",x" * 100_000 + "\nPC1,1\n"


def rawlog_mutations(data: bytes) -> Iterator[tuple[str, bytes]]:
    """Records a raw log should never hold, each among the good ones (issue 18)."""
    lines = data.split(b"\n")
    hostile = {
        "rx-beyond-latin1": b'{"t": 1770000000, "rx": "\\u20ac\\r"}',
        "rx-number": b'{"t": 1770000000, "rx": 42}',
        "rx-null": b'{"t": 1770000000, "rx": null}',
        "t-nan": b'{"t": NaN, "rx": "a"}',
        "t-1e400": b'{"t": 1e400, "rx": "a"}',
        "t-huge": b'{"t": 1e300, "rx": "a"}',
        "t-text": b'{"t": "1", "rx": "a"}',
        "t-missing": b'{"rx": "a"}',
        "event-number": b'{"t": 1770000000, "event": 5}',
        "detail-list": b'{"t": 1770000000, "event": "x", "detail": [1, 2]}',
        "detail-deep": b'{"t": 1770000000, "event": "x", "detail": '
        + b'{"a": ' * 500
        + b"1"
        + b"}" * 501,
        "nested-200000": b"[" * 200_000 + b"]" * 200_000,
        "not-object": b"[1, 2, 3]",
        "record-32MB": b'{"t": 1770000000, "rx": "' + b"x" * (32 * 1024 * 1024) + b'"}',
    }
    for name, rec in hostile.items():
        yield name, b"\n".join([*lines[:2], rec, *lines[2:]])
    yield "torn-tail", data.rstrip(b"\n")[:-7]
    yield "torn-middle", b"\n".join([*lines[:2], lines[2][:9], *lines[2:]])


def annotation_mutations() -> Iterator[tuple[str, bytes]]:
    for key in ("mass_kg", "pressure_hpa", "humidity_pct", "wind_ms", "air_temperature_c"):
        for bad in ("1e308", "-1e308", "NaN", "Infinity", '"abc"', "[]", "true"):
            rec = f'{{"type": "metadata", "values": {{"{key}": {bad}}}, "descents": [1]}}\n'
            yield f"{key}={bad}", rec.encode()
    yield "descent-huge", b'{"type": "invalid", "descent": 1e300}\n'
    yield "descent-text", b'{"type": "model", "descent": "x", "model": "quadratic"}\n'
    yield "deep", b'{"type": "metadata", "values": ' + b'{"a": ' * 100_000 + b"1" + b"}" * 100_001
    yield "torn", b'{"type": "metadata", "values": {"ski": "A"}, "descents": [1]}\n{"type'


def _flip(data: bytes, rng: random.Random, n: int) -> bytes:
    out = bytearray(data)
    for _ in range(n):
        i = rng.randrange(len(out))
        out[i] ^= 1 << rng.randrange(8)
    return bytes(out)


# ----------------------------------------------------------------------------- the cases


def build_cases(work: Path, seed: int) -> list[Case]:
    rng = random.Random(seed)
    base = work / "base"
    shutil.copytree(SURVEYS, base)
    survey = base / "demo_run.yaml"
    times = base / "demo_descent.csv"
    cfg_text = (base / "demo_station.yaml").read_text()
    capture = base / "capture.txt"
    capture.write_bytes(_capture_of(times))
    cases: list[Case] = []
    n = [0]

    def new_dir() -> Path:
        n[0] += 1
        d = work / f"c{n[0]:04d}"
        d.mkdir()
        return d

    def fit_argv(survey_path, times_path) -> list[str]:
        return ["fit", "--survey", str(survey_path), "--times", str(times_path), "--mass", "88",
                "--air-density", "1.0"]  # fmt: skip

    demo_cfg = str(base / "demo_station.yaml")

    def replay_argv(source: str, config: str) -> list[str]:
        return ["replay", source, "--config", config, "--date", "2026-01-02"]

    def config_case(name: str, data: bytes) -> None:
        d = new_dir()
        for f in ("demo_run.yaml", "demo_run.gsi"):
            os.symlink(base / f, d / f)
        (d / "station.yaml").write_bytes(data)
        cfg_path = str(d / "station.yaml")
        cases.append(Case("config", name, replay_argv(str(capture), cfg_path)))

    def survey_case(name: str, data: bytes) -> None:
        d = new_dir()
        os.symlink(base / "demo_run.gsi", d / "demo_run.gsi")
        (d / "survey.yaml").write_bytes(data)
        cases.append(Case("survey", name, fit_argv(d / "survey.yaml", times)))

    def gsi_case(name: str, data: bytes) -> None:
        d = new_dir()
        os.symlink(survey, d / "demo_run.yaml")
        (d / "demo_run.gsi").write_bytes(data)
        cases.append(Case("gsi", name, fit_argv(d / "demo_run.yaml", times)))

    def times_case(name: str, data: bytes) -> None:
        d = new_dir()
        (d / "times.csv").write_bytes(data)
        cases.append(Case("times", name, fit_argv(survey, d / "times.csv")))

    def capture_case(name: str, data: bytes) -> None:
        d = new_dir()
        (d / "capture.txt").write_bytes(data)
        cases.append(Case("capture", name, replay_argv(str(d / "capture.txt"), demo_cfg)))

    for name, text in numbers_replaced(cfg_text):
        config_case(name, text.encode())
    for name, text in yaml_structures(cfg_text):
        config_case(name, text.encode())
    for name, data in generic(cfg_text.encode(), rng):
        config_case(name, data)
    config_case("survey-dev-zero", cfg_text.replace("demo_run.yaml", "/dev/zero").encode())
    config_case("survey-folder", cfg_text.replace("demo_run.yaml", "/tmp").encode())
    config_case("same-photocell", cfg_text.replace("C1: PC2", "C1: PC1").encode())
    config_case("huge-mass", cfg_text.replace("mass_kg: 88", "mass_kg: 1.0e+308").encode())

    survey_text = survey.read_text()
    for name, text in numbers_replaced(survey_text):
        survey_case(name, text.encode())
    for name, text in yaml_structures(survey_text):
        survey_case(name, text.encode())
    for name, data in generic(survey_text.encode(), rng):
        survey_case(name, data)
    survey_case("observations-dev-zero", survey_text.replace("demo_run.gsi", "/dev/zero").encode())
    survey_case("observations-folder", survey_text.replace("demo_run.gsi", "/tmp").encode())
    survey_case("observations-self", survey_text.replace("demo_run.gsi", "survey.yaml").encode())

    gsi = (base / "demo_run.gsi").read_bytes()
    for name, data in gsi_mutations(gsi, rng):
        gsi_case(name, data)
    for name, data in generic(gsi, rng):
        gsi_case(name, data)

    times_text = times.read_text()
    for name, text in times_mutations(times_text):
        times_case(name, text.encode("utf-8", "surrogateescape").replace(b"\xc3\xbf", b"\xff"))
    for name, data in generic(times_text.encode(), rng):
        times_case(name, data)

    def import_case(name: str, path: str) -> None:
        d = new_dir()
        argv = ["import", path, "--config", demo_cfg, "--session-dir", str(d / "session")]
        cases.append(Case("import", name, argv))

    cap = capture.read_bytes()
    for name, data in generic(cap, rng):
        capture_case(name, data)
        import_case(name, cases[-1].argv[1])
    for k in range(10):
        capture_case(f"many-flips-{k}", _flip(cap, rng, 20))

    # a session of the demo descent, its raw log and annotations mutated
    from station.session.config import load_config
    from station.session.memory_import import import_new

    session = work / "session"
    import_new(str(capture), load_config(demo_cfg), str(session))
    # one chunk per timer line, as a recording writes them
    from station.session.rawlog import RawLogWriter, read_rawlog

    chunks = list(read_rawlog(str(session / "raw.jsonl")))
    (session / "raw.jsonl").unlink()
    log = RawLogWriter(str(session / "raw.jsonl"))
    for c in chunks:
        if c.event:
            log.event(c.t, c.event, c.detail)
        else:
            for line in c.data.split(b"\r"):
                if line:
                    log.write(c.t, line + b"\r")
    log.close()
    raw = (session / "raw.jsonl").read_bytes()

    def session_case(kind: str, name: str, raw_data: bytes, annotations: bytes | None) -> Path:
        d = new_dir()
        shutil.copytree(session, d / "s")
        (d / "s" / "raw.jsonl").write_bytes(raw_data)
        if annotations is not None:
            (d / "s" / "annotations.jsonl").write_bytes(annotations)
        cases.append(Case(kind, name, ["replay", str(d / "s")]))
        return d / "s"

    for name, data in [*generic(raw, rng), *rawlog_mutations(raw)]:
        s_path = session_case("raw log", name, data, None)
        argv = ["import", str(capture), "--config", demo_cfg, "--into", str(s_path)]
        cases.append(Case("raw log", f"import-into-{name}", argv))
    for name, data in annotation_mutations():
        session_case("annotations", name, raw, data)

    # special files, for every kind
    specials = _special_files(work)
    for name, path in specials.items():
        cases.append(Case("config", f"special-{name}", replay_argv(str(capture), path)))
        cases.append(Case("survey", f"special-{name}", fit_argv(path, times)))
        cases.append(Case("times", f"special-{name}", fit_argv(survey, path)))
        cases.append(Case("capture", f"special-{name}", replay_argv(path, demo_cfg)))
        import_case(f"special-{name}", path)
        if path and "\0" not in path:  # a survey's observation file is always a real name
            d = new_dir()
            (d / "s.yaml").write_text(survey_text.replace("demo_run.gsi", path))
            cases.append(Case("gsi", f"special-{name}", fit_argv(d / "s.yaml", times)))
    return cases


def _special_files(work: Path) -> dict[str, str]:
    sp = work / "special"
    sp.mkdir()
    fifo = sp / "fifo"
    os.mkfifo(fifo)
    os.symlink(sp / "loop-b", sp / "loop-a")
    os.symlink(sp / "loop-a", sp / "loop-b")
    sparse = sp / "sparse"
    with open(sparse, "wb") as fh:
        fh.truncate(3 * 1024**3)  # 3 GB of nothing: over every limit
    unreadable = sp / "unreadable"
    unreadable.write_text("a: 1\n")
    unreadable.chmod(0)
    return {
        "dev-zero": "/dev/zero",
        "dev-urandom": "/dev/urandom",
        "dev-null": "/dev/null",
        "fifo": str(fifo),
        "folder": str(sp),
        "missing": str(sp / "missing"),
        "symlink-loop": str(sp / "loop-a"),
        "sparse-3GB": str(sparse),
        "unreadable": str(unreadable),
        "empty-name": "",
        "nul-in-name": "a\x00b",
    }


def _capture_of(times: Path) -> bytes:
    """The demo descent as an ALGE timer sends it (channels C0..C8)."""
    from station.timing.timesfile import read_times
    from station.timing.wireformats import format_alge

    ids = [f"PC{i}" for i in range(1, 10)]
    d = read_times(str(times), ids)
    out = b""
    for k, (pc, t) in enumerate(zip(d.photocells, d.times, strict=True)):
        ch = f"C{int(pc[2:]) - 1}"
        out += format_alge(ch, round(t * 1e6), k + 1).encode() + b"\r"
    return out


# ----------------------------------------------------------------------------- running


@dataclass(frozen=True)
class Outcome:
    case: Case
    rc: int | None  # None: hung
    stderr: str
    seconds: float


def run_case(case: Case, work: Path, timeout: float, main: Callable[[list[str]], int]) -> Outcome:
    err_path = work / "stderr.txt"
    sys.stdout.flush()
    sys.stderr.flush()
    t0 = time.monotonic()
    pid = os.fork()
    if pid == 0:  # the child: run the command, exit with its status
        rc = 99
        try:
            out = os.open(os.devnull, os.O_WRONLY)
            err = os.open(err_path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
            os.dup2(out, 1)
            os.dup2(err, 2)
            resource.setrlimit(resource.RLIMIT_AS, (MEMORY_LIMIT, MEMORY_LIMIT))
            try:
                rc = int(main(case.argv) or 0)
            except SystemExit as exc:
                rc = exc.code if isinstance(exc.code, int) else 2
            except BaseException:
                traceback.print_exc()
                rc = 99
            sys.stdout.flush()
            sys.stderr.flush()
        finally:
            os._exit(rc)
    deadline = t0 + timeout
    status = None
    while time.monotonic() < deadline:
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        time.sleep(0.005)
    else:
        os.kill(pid, signal.SIGKILL)
        os.waitpid(pid, 0)
        return Outcome(case, None, "", time.monotonic() - t0)
    rc = os.waitstatus_to_exitcode(status)
    text = err_path.read_text(errors="replace") if err_path.exists() else ""
    return Outcome(case, rc, text, time.monotonic() - t0)


def is_traceback(o: Outcome) -> bool:
    return o.rc is not None and (o.rc not in (0, 2) or "Traceback" in o.stderr)


def is_multiline_error(o: Outcome) -> bool:
    if o.rc != 2 or is_traceback(o):
        return False
    errors = [ln for ln in o.stderr.splitlines() if ln.strip() and not ln.startswith("warning:")]
    return len(errors) != 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--timeout", type=float, default=15.0, help="seconds before a run is a hang")
    ap.add_argument("--show", type=int, default=20, help="list this many failures")
    args = ap.parse_args(argv)

    sys.path.insert(0, str(ROOT))
    from station.cli.main import main as station_main

    work = Path(tempfile.mkdtemp(prefix="mutate-inputs-"))
    try:
        cases = build_cases(work, args.seed)
        # warm up in the parent, so every forked child starts with everything imported
        run_case(Case("warm-up", "demo", cases[0].argv), work, 60, station_main)
        import station.model.fit  # noqa: F401
        import station.session.acquisition  # noqa: F401
        import station.survey.load  # noqa: F401

        t0 = time.monotonic()
        outcomes = [run_case(c, work, args.timeout, station_main) for c in cases]
        wall = time.monotonic() - t0
    finally:
        with_perm = work / "special" / "unreadable"
        if with_perm.exists():
            with_perm.chmod(0o600)
        shutil.rmtree(work, ignore_errors=True)

    kinds = sorted({o.case.kind for o in outcomes})
    print(f"{'kind':<11} {'runs':>5} {'exit 0':>7} {'exit 2':>7} {'traceback':>10} {'hang':>5} "
          f"{'multi-line':>11}")  # fmt: skip
    total: Counter[str] = Counter()
    for kind in [*kinds, "all"]:
        rows = [o for o in outcomes if kind in ("all", o.case.kind)]
        c = Counter(
            runs=len(rows),
            ok=sum(o.rc == 0 and not is_traceback(o) for o in rows),
            bad=sum(o.rc == 2 and not is_traceback(o) for o in rows),
            tb=sum(is_traceback(o) for o in rows),
            hang=sum(o.rc is None for o in rows),
            multi=sum(is_multiline_error(o) for o in rows),
        )
        if kind == "all":
            total = c
        print(f"{kind:<11} {c['runs']:>5} {c['ok']:>7} {c['bad']:>7} {c['tb']:>10} "
              f"{c['hang']:>5} {c['multi']:>11}")  # fmt: skip
    slowest = max(outcomes, key=lambda o: o.seconds)
    print(f"{len(outcomes)} runs in {wall:.1f} s; slowest {slowest.seconds:.2f} s "
          f"({slowest.case.kind} {slowest.case.name})")  # fmt: skip
    failures = [o for o in outcomes if is_traceback(o) or o.rc is None or is_multiline_error(o)]
    for o in failures[: args.show]:
        what = "hang" if o.rc is None else ("traceback" if is_traceback(o) else "multi-line")
        last = [ln for ln in o.stderr.splitlines() if ln.strip()][-1:] or [""]
        print(f"  {what}: {o.case.kind} {o.case.name} (rc {o.rc}): {last[0][:150]}")
    return 1 if total["tb"] or total["hang"] else 0


if __name__ == "__main__":
    raise SystemExit(main())
