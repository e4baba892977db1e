"""What every ``station`` command shares: one-line usage errors with exit status 2, number
parsers that say which option is wrong, the air options, output paths checked before any work,
and small output helpers."""

from __future__ import annotations

import argparse
import contextlib
import datetime as dt
import json
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterable, Iterator
from typing import IO, TYPE_CHECKING, Any, NoReturn

from station.errors import InputError
from station.files import check_output, staged_output
from station.limits import PLAUSIBLE
from station.model.air import (
    DEFAULT_HUMIDITY_PCT,
    DEFAULT_PRESSURE_HPA,
    DEFAULT_TEMPERATURE_C,
    air_density,
)
from station.numbers import parse_number

if TYPE_CHECKING:  # the day's results: numpy and scipy, loaded when a command runs
    from station.session.analysis import DescentResult

EXIT_BAD_INPUT = 2


class Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and exit status 2, and an option must be spelt
    out: with abbreviations ``--masss 88`` would not be "unrecognized", and ``--mas`` would
    silently mean ``--mass`` today and something else once another ``--mas…`` option exists."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        kwargs.setdefault("allow_abbrev", False)
        super().__init__(*args, **kwargs)
        # a negative number with a decimal comma (``--temperature-c -4,5``, the cold
        # trackside's usual value) is a value, not an option, as ``-4.5`` is to argparse;
        # private: argparse has no public setting for what a negative number looks like
        self._negative_number_matcher = re.compile(r"^-(\d+([.,]\d*)?|[.,]\d+)$")

    _argv: list[str] | None = None
    #: the subcommands' action (its ``choices``: name → parser), when this parser has them
    commands: Any = None

    def add_subparsers(self, **kwargs: Any) -> Any:
        self.commands = super().add_subparsers(**kwargs)
        return self.commands

    def option_names(self) -> list[str]:
        """The ``--long`` options this parser knows."""
        # private: argparse lists a parser's option strings nowhere public
        return [o for o in self._option_string_actions if o.startswith("--")]

    def parse_known_args(self, args: Any = None, namespace: Any = None) -> Any:
        self._argv = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str) -> NoReturn:
        if message.startswith("the following arguments are required"):
            # `--masss 88`: the typo is the problem, not the --mass it left out
            unknown = self._unknown_options()
            if unknown:
                message = f"unrecognized arguments: {' '.join(unknown)}"
        if message.startswith("unrecognized arguments"):
            message += self._suggestion(message)
        typo = re.match(r"argument command: invalid choice: '([^']*)'", message)
        if typo:  # ``station raport``: the command it was meant to be, not all sixteen
            message = f"unknown command {typo.group(1)!r}" + self._command_suggestion(typo.group(1))
        bare = message == "the following arguments are required: command"  # ``station``
        if bare and self.commands is not None:
            message = f"give a command: {', '.join(self.commands.choices)}"
        self.exit(EXIT_BAD_INPUT, f"{self.prog}: error: {message} (see --help)\n")

    def _command_suggestion(self, word: str) -> str:
        import difflib

        if self.commands is None:
            return ""
        choices = list(self.commands.choices)
        close = difflib.get_close_matches(word, choices, n=1, cutoff=0.6)
        if close:
            return f" (did you mean {close[0]}?)"
        return f"; the commands: {', '.join(choices)}"

    def _unknown_options(self) -> list[str]:
        names = [a.split("=", 1)[0] for a in self._argv or [] if a.startswith("--") and a != "--"]
        known = self.option_names()
        return [n for n in names if n not in known]

    def _suggestion(self, message: str) -> str:
        import difflib  # only for a mistyped option: not on every command's start-up

        options = self.option_names()
        if self.commands is not None and self._argv:  # the command's own, its typo seen here
            command = next((a for a in self._argv if not a.startswith("-")), None)
            chosen = self.commands.choices.get(command) if command else None
            if isinstance(chosen, Parser):
                options += chosen.option_names()
        for word in message.split(":", 1)[1].split():
            if word.startswith("--"):
                close = difflib.get_close_matches(word.split("=", 1)[0], options, n=1)
                if close:
                    return f" (did you mean {close[0]}?)"
        return ""


def whole_number(text: str, kind: str, least: int, below: str) -> int:
    """An option's whole number of at least ``least``: ``kind`` names what it must be when
    it is no whole number, ``below`` what a smaller one is not."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"must be {kind}, got {text!r}") from None
    if value < least:
        raise argparse.ArgumentTypeError(f"{below}, got {text!r}")
    return value


def _positive(text: str) -> float:
    value = _number(text)
    if value <= 0:
        raise argparse.ArgumentTypeError(f"must be a number greater than 0, got {text!r}")
    return value


def _nonnegative(text: str) -> float:
    value = _number(text)
    if value < 0:
        raise argparse.ArgumentTypeError(f"must be a number ≥ 0, got {text!r}")
    return value


def _percent(text: str) -> float:
    value = _nonnegative(text)
    if value > 100:
        raise argparse.ArgumentTypeError(f"must lie between 0 and 100 %, got {text!r}")
    return value


def _celsius(text: str) -> float:
    value = _number(text)
    if not -60 <= value <= 50:
        raise argparse.ArgumentTypeError(f"{text!r} °C is not an air temperature on snow")
    return value


def plausible(key: str) -> Callable[[str], float]:
    """The option parser of a number with a plausible range (:data:`station.limits.PLAUSIBLE`):
    ``--mass 880`` is a typo, refused as the config and the UI form refuse it."""
    lo, hi, unit = PLAUSIBLE[key]

    def check(text: str) -> float:
        value = _number(text)
        if not lo <= value <= hi:
            raise argparse.ArgumentTypeError(f"{text!r} {unit} is out of range ({lo:g} .. {hi:g})")
        return value

    check.__name__ = key
    return check


def _number(text: str) -> float:
    """A finite number with a decimal point or a decimal comma (``--mass 72,5``)."""
    try:
        return parse_number(text)
    except ValueError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def _warn(message: str) -> None:
    print(f"warning: {message}", file=sys.stderr)


def _add_air(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("air (station pressure, not sea-level QNH)")
    g.add_argument("--pressure-hpa", type=plausible("pressure_hpa"), metavar="P",
                   help="station pressure, hPa")  # fmt: skip
    g.add_argument("--temperature-c", type=_celsius, metavar="T", help="air temperature, °C")
    g.add_argument("--humidity-pct", type=_percent, metavar="H", help="relative humidity, %%")
    g.add_argument("--air-density", type=plausible("air_density"), metavar="RHO",
                   help="kg/m³, instead of P, T, H")  # fmt: skip


def add_timer_option(p: argparse.ArgumentParser, default: float | None, default_says: str) -> None:
    """``--timer-ms``: the timer's precision (SD of one crossing time, ms) against which the
    residuals are judged, the one spelling on every command (:mod:`station.model.timer`);
    ``--timer-precision-ms``, the single fit's earlier spelling, still works for old scripts
    but is not shown."""
    p.add_argument("--timer-ms", dest="timer_ms", type=_positive, default=default, metavar="MS",
                   help="the timer's precision (SD of one crossing time, ms), against which "
                        f"the residuals are judged (default {default_says})")  # fmt: skip
    p.add_argument("--timer-precision-ms", dest="timer_ms", type=_positive,
                   default=argparse.SUPPRESS, help=argparse.SUPPRESS)  # fmt: skip


def _density(args: argparse.Namespace) -> float:
    given = [args.pressure_hpa, args.temperature_c, args.humidity_pct]
    if args.air_density is not None:
        if any(v is not None for v in given):
            raise InputError("give --air-density or pressure/temperature/humidity, not both")
        return args.air_density
    if all(v is None for v in given):
        rho = air_density(DEFAULT_PRESSURE_HPA, DEFAULT_TEMPERATURE_C, DEFAULT_HUMIDITY_PCT)
        _warn(
            f"no air data given; assuming {DEFAULT_PRESSURE_HPA} hPa, "
            f"{DEFAULT_TEMPERATURE_C:g} °C, {DEFAULT_HUMIDITY_PCT:g} % (ρ = {rho:.3f} kg/m³). "
            "Give --pressure-hpa at the run's "
            "altitude: ρ enters CdA one to one"
        )
        return rho
    p = args.pressure_hpa if args.pressure_hpa is not None else DEFAULT_PRESSURE_HPA
    t = args.temperature_c if args.temperature_c is not None else DEFAULT_TEMPERATURE_C
    h = args.humidity_pct if args.humidity_pct is not None else DEFAULT_HUMIDITY_PCT
    assumed = [
        f"{name} {value:g}"
        for name, given, value in (
            ("--pressure-hpa", args.pressure_hpa, p),
            ("--temperature-c", args.temperature_c, t),
            ("--humidity-pct", args.humidity_pct, h),
        )
        if given is None
    ]
    if assumed:
        _warn("assuming " + ", ".join(assumed))
    try:
        return air_density(p, t, h)
    except ValueError as exc:
        raise InputError(str(exc), field="air") from None


def _gravity_ms2(text: str) -> float:
    value = _number(text)
    if not 9.7 <= value <= 9.9:
        raise argparse.ArgumentTypeError(
            f"{text!r} m/s² is not gravity on the earth's surface (9.7 .. 9.9)"
        )
    return value


def _add_gravity(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--gravity",
        type=_gravity_ms2,
        metavar="G",
        help="m/s²; default: normal gravity at the survey's latitude_deg and height, "
        "else standard gravity 9.80665",
    )


def _load_track(path: str):
    # here, not at the top: numpy and scipy, which station --help and a usage error never need
    from station.survey.load import load_survey
    from station.survey.track import build_track

    track = build_track(load_survey(path))
    return track


def _fmt(v: float | None, spec: str) -> str:
    return "—" if v is None else format(v, spec)


def _print_json(obj: Any) -> None:
    print(json.dumps(obj, indent=2, allow_nan=False))


def _date(text: str | None):

    if text is None:
        return None
    try:
        return dt.date.fromisoformat(text)
    except ValueError:
        raise InputError(f"--date {text!r} is not YYYY-MM-DD") from None


def _numbers(text: str) -> list[int]:
    out = []
    for part in text.split(","):
        part = part.strip()
        if "-" in part:
            a, b = part.split("-", 1)
            if not (a.isdigit() and b.isdigit()):
                raise InputError(f"--descents {text!r}: {part!r} is not a range like 3-6")
            if int(b) < int(a):  # 5-3 would be no descent at all, silently
                raise InputError(f"--descents {text!r}: {part!r} runs backwards; write {b}-{a}")
            out += list(range(int(a), int(b) + 1))
        elif part.isdigit():
            out.append(int(part))
        else:
            raise InputError(f"--descents {text!r}: {part!r} is not a descent number")
    return out


def unique_prefix(text: str, choices: list[str], what: str, option: str) -> str:
    """The one choice ``text`` names: itself, or the only one it begins (case and surrounding
    blanks ignored), so "pair A" names "pair A / LF blue" when no other item begins so."""
    if text in choices:
        return text
    key = text.strip().casefold()
    exact = [c for c in choices if c.casefold() == key]
    if len(exact) == 1:
        return exact[0]
    hits = [c for c in choices if c.casefold().startswith(key)]
    if len(hits) == 1:
        return hits[0]
    if hits:
        raise InputError(f"{text!r} could be {', '.join(map(repr, hits))}: say which",
                         field=option)  # fmt: skip
    raise InputError(f"no {what} {text!r}; there are {', '.join(map(repr, choices))}",
                     field=option)  # fmt: skip


def reference_item(
    reference: str | None, results: Iterable[DescentResult], wind_limit_ms: float
) -> str | None:
    """``--reference`` as the item it names (:func:`unique_prefix`) among those a comparison
    of ``results`` would compare; None when not given. One for ``compare`` and ``report``,
    which each resolved it so: the same words name the same item in both."""
    if reference is None:
        return None
    from station.session.comparison import compared_items  # (numpy: when a command runs)

    items = compared_items(results, wind_limit_ms)
    return unique_prefix(reference, items, "item", "--reference")


# ----------------------------------------------------------------------------- output paths

STDOUT = "-"
#: options whose value is an output file; ``-`` sends it to standard output
OUTPUT_OPTIONS = ("csv", "events", "times")
#: where ``-`` writes: the real standard output, saved before the report is moved to stderr
_data_stdout: IO[str] | None = None


def output_path(arg: str | None, option: str) -> str | None:
    """Check an output file before any work is done, so a day is not replayed and fitted only
    to fail at the last step with a traceback: its folder must exist and be writable, and the
    path must not be a folder or a special file. ``-`` (standard output) and ``None`` (not
    asked for) pass as they are."""
    if arg is None or arg == STDOUT:
        return arg
    if arg == "":
        raise InputError("empty output path (use - for standard output)", field=option)
    return check_output(arg, option)


def output_dir(arg: str, option: str) -> str:
    """Check an output folder (``--out DIR``): made if missing, as long as its parent exists
    (a mistyped parent is an error, not a tree of new folders)."""
    if arg == "":
        raise InputError("empty output folder", field=option)
    if os.path.exists(arg) and not os.path.isdir(arg):
        raise InputError("is a file, not a folder", path=arg, field=option)
    parent = os.path.dirname(os.path.abspath(arg))
    if not os.path.exists(arg):
        if not os.path.isdir(parent):
            raise InputError(f"folder {parent} does not exist", path=arg, field=option)
        try:
            os.mkdir(arg)
        except OSError as exc:
            raise InputError(f"cannot make the folder: {exc.strerror}",
                             path=arg, field=option) from None  # fmt: skip
    try:
        if not os.access(arg, os.W_OK | os.X_OK):
            raise OSError(13, "permission denied")
        tempfile.TemporaryFile(dir=arg).close()
    except OSError as exc:
        raise InputError(f"folder is not writable ({exc.strerror})",
                         path=arg, field=option) from None  # fmt: skip
    return arg


@contextlib.contextmanager
def open_output(arg: str, option: str) -> Iterator[IO[str]]:
    """The checked output as a text file: ``-`` is standard output (left open); a path is
    written to a temporary file beside it and renamed over it when done (:func:`_staged`)."""
    if arg == STDOUT:
        out = _data_stdout or sys.stdout
        yield out
        out.flush()
        return
    with staged_output(arg, option) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        yield fh


def dispatch(args: argparse.Namespace) -> int:
    """Run a command; when one of its outputs is ``-``, standard output carries that data only
    and the command's report goes to stderr (so ``station export S --csv - | …`` pipes CSV)."""
    global _data_stdout
    to_stdout = [o for o in OUTPUT_OPTIONS if getattr(args, o, None) == STDOUT]
    if not to_stdout:
        return int(args.func(args) or 0)
    if len(to_stdout) > 1:
        raise InputError(
            f"{' and '.join('--' + o for o in to_stdout)} cannot both go to standard output"
        )
    if getattr(args, "json", False):
        raise InputError(f"--{to_stdout[0]} - and --json cannot both go to standard output")
    _data_stdout = sys.stdout
    try:
        with contextlib.redirect_stdout(sys.stderr):
            return int(args.func(args) or 0)
    finally:
        _data_stdout = None
