"""``station annotate`` and ``compare``: what the engineer says about descents after the fact,
and which ski or wax glides better, by how much, and how sure."""

from __future__ import annotations

import argparse
import sys
import time
from typing import Any

from station.cli.common import (
    _celsius,
    _nonnegative,
    _number,
    _numbers,
    _percent,
    _positive,
    _print_json,
    _warn,
    add_timer_option,
    open_output,
    output_path,
    plausible,
    reference_item,
    whole_number,
)
from station.errors import InputError
from station.limits import PLAUSIBLE
from station.session.records import (
    METADATA_FIELDS,
    Annotation,
    FitModel,
    InvalidMark,
    Metadata,
    MetadataAnnotation,
    ModelChange,
    ValidMark,
)
from station.store import configured


def cmd_annotate(args: argparse.Namespace) -> int:
    """Enter metadata, invalid marks or a model for a session's descents, as the UI would."""
    # here, not at the top: the session's replay loads numpy and scipy (see recording.py);
    # an annotation that changes no fit needs neither (the session's results CSV is changed
    # in place: station.session.resultsstate), so station.cli.console is not imported either
    from station.session.recorded_session import RecordedSession

    session = RecordedSession(args.session)
    _check_annotate_options(args)
    targets = _numbers(args.descents) if args.descents is not None else []
    records = _annotations(args, targets, time.time())
    session.check_descents(targets)  # --from N may name descents still to come
    try:
        print(session.annotate(records), file=sys.stderr)
    finally:
        while session.warnings:  # what the replay passed over (a torn last record)
            _warn(session.warnings.pop(0))
    try:
        store = session.config.store
    except InputError:
        store = None
    if configured(store):  # console.add_after's test, without its imports
        from station.cli.console import add_after

        add_after(session.path, store)  # the season store's rows follow the annotation
    return 0


def _check_annotate_options(args: argparse.Namespace) -> None:
    """The options of ``annotate`` that contradict each other or lack their partner."""
    if (args.descents is None) == (args.from_descent is None):
        raise InputError("give --descents N[,M,A-B] or --from N")
    if args.invalid and args.valid:
        raise InputError("--invalid and --valid contradict each other: give one")
    if args.wind_from_deg is not None and not 0.0 <= args.wind_from_deg <= 360.0:
        raise InputError(
            f"--wind-from-deg {args.wind_from_deg:g}: a direction is 0 to 360 degrees from north"
        )
    if args.wind_ms and args.wind_from_deg is None:
        raise InputError("--wind-ms needs --wind-from-deg (the direction the wind comes from)")


def _annotations(args: argparse.Namespace, targets: list[int], t: float) -> list[Annotation]:
    """The records ``annotate`` appends: the metadata, then each descent's marks and model."""
    values = Metadata.from_values({f.key: getattr(args, f.key) for f in METADATA_FIELDS})
    records: list[Annotation] = []
    if values.values():
        if args.descents is not None:
            records.append(MetadataAnnotation(values, descents=tuple(targets), t=t))
        else:
            records.append(MetadataAnnotation(values, from_descent=args.from_descent, t=t))
    if (args.invalid or args.valid or args.model) and not targets:
        raise InputError("--invalid, --valid and --model need --descents")
    for n in targets:
        if args.invalid:
            records.append(InvalidMark(n, args.invalid, t))
        if args.valid:
            records.append(ValidMark(n, t))
        if args.model:
            records.append(ModelChange(n, FitModel(args.model), t))
    if not records:
        raise InputError("nothing to annotate: give metadata, --invalid, --valid or --model")
    return records


def cmd_compare(args: argparse.Namespace) -> int:
    from station.cli.console import replayed  # here: see cmd_annotate
    from station.report.comparison_text import compare_text, comparison_json, write_ranking_csv
    from station.session.recorded_session import RecordedSession

    session = RecordedSession(args.session)
    output_path(args.csv, "--csv")
    if args.upto is not None:  # a look after a descent the day does not have is no look
        session.check_descents([args.upto], field="--upto")
    results = replayed(session).results_upto(args.upto)  # the day as after descent K
    reference = reference_item(args.reference, results, args.wind_limit)
    day = session.analysis(
        upto=args.upto, wind_limit_ms=args.wind_limit, reference=reference, cda_fixed=args.cda,
        model=args.model, drift=args.drift,
        timer_sd_s=None if args.timer_ms is None else args.timer_ms / 1000.0,
        horizon=args.horizon, margin=args.margin,
    ).comparison  # fmt: skip
    if day.result is None:
        raise InputError(day.error, path=args.session)
    if args.csv:
        with open_output(args.csv, "--csv") as fh:
            write_ranking_csv(day, fh)
    if args.json:
        _print_json(comparison_json(day))
        return 0
    print(compare_text(day))
    for w in day.result.warnings:
        _warn(w)
    return 0


#: the number parser of each kind of metadata value (records.MetadataField.check)
_CHECKS = {
    "text": str,
    "number": _number,
    "positive": _positive,
    "nonnegative": _nonnegative,
    "percent": _percent,
    "celsius": _celsius,
}


def add_parsers(sub: Any) -> None:
    p = sub.add_parser("annotate", help="enter metadata, invalid marks or a model for descents")
    p.add_argument("session", metavar="SESSION", help="session folder")
    who = p.add_mutually_exclusive_group()
    who.add_argument("--descents", metavar="LIST", help="e.g. 1,4,5-8")
    who.add_argument("--from", dest="from_descent", type=int, metavar="N",
                     help="this and all later descents")  # fmt: skip
    for f in METADATA_FIELDS:  # the one table of metadata keys
        text = (f.help or f.title).replace("%", "%%")  # argparse formats help with %
        # the wind's direction keeps its own check, after parsing: it says which way is which
        ranged = f.key in PLAUSIBLE and f.key != "wind_from_deg"
        check = plausible(f.key) if ranged else _CHECKS[f.check]
        p.add_argument(f.option, dest=f.key, type=check, help=text)
    p.add_argument("--invalid", metavar="REASON", help="mark the descents invalid")
    p.add_argument("--valid", action="store_true", help="mark them valid again")
    p.add_argument(
        "--model", choices=["constant", "velocity"], help="refit: μ constant, or μ + μ1·v"
    )
    p.set_defaults(func=cmd_annotate)

    p = sub.add_parser("compare", help="which ski or wax glides better, by how much, how sure")
    p.add_argument("session", metavar="SESSION", help="session folder")
    p.add_argument(
        "--reference",
        metavar="ITEM",
        help="compare every item with this one (ski / wax as listed; its beginning is enough "
        "when no other item begins so)",
    )
    p.add_argument("--cda", type=_positive, metavar="M2", help="fix CdA (m²) instead of fitting it")
    p.add_argument("--model", choices=["constant", "velocity"], default="constant",
                   help="friction μ per item constant, or μ + μ1·v (μ1 in s/m)")  # fmt: skip
    p.add_argument(
        "--drift",
        choices=["auto", "on", "off"],
        default="auto",
        help="fit a linear drift of μ per hour of the day (auto: when an item recurs)",
    )
    add_timer_option(p, None, "the session's: its config's timer.precision_ms, else from the "
                              "resolution the timer states, 0.5 for 1 ms and finer")  # fmt: skip
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.add_argument("--upto", type=_descent_number, metavar="K",
                   help="answer as after descent K (the descents after it left out)")  # fmt: skip
    p.add_argument("--margin", type=_positive, metavar="DMU",
                   help="a difference of μ that does not matter: 'equivalent' when the "
                        "interval lies within ±DMU")  # fmt: skip
    p.add_argument("--horizon", type=_horizon, default=10, metavar="N",
                   help="descents per item over which the decision's error rate is spent "
                        "(the plan's number; default 10)")  # fmt: skip
    p.add_argument("--csv", metavar="OUT", help="write the ranking as CSV; - = stdout")
    p.add_argument("--json", action="store_true", help="machine-readable output")
    p.set_defaults(func=cmd_compare)


def _descent_number(text: str) -> int:
    return whole_number(text, "a descent number", 1, "descents are numbered from 1")


def _horizon(text: str) -> int:
    value = _descent_number(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"at least 2 descents per item, got {text!r}")
    return value
