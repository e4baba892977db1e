"""``station annotate`` and ``compare``: what the engineer says about descents after the fact,
and which ski or wax glides better, by how much, and how sure."""

from __future__ import annotations

import argparse
import sys
from typing import Any

from station import __version__
from station.cli.common import (
    _celsius,
    _nonnegative,
    _number,
    _numbers,
    _percent,
    _positive,
    _print_json,
    _warn,
)
from station.errors import InputError


def cmd_annotate(args: argparse.Namespace) -> int:
    """Enter metadata, invalid marks or a model for a session's descents, as the UI would."""
    import time as _time

    from station.session import store as sessions
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

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    values = Metadata.from_values({f.key: getattr(args, f.key) for f in METADATA_FIELDS})
    if (args.descents is None) == (args.from_descent is None):
        raise InputError("give --descents N[,M,A-B] or --from N")
    records: list[Annotation] = []
    t = _time.time()
    targets = _numbers(args.descents) if args.descents is not None else []
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
    for rec in records:
        sessions.append_annotation(args.session, rec)
    print(f"{len(records)} annotation(s) added to {args.session}", file=sys.stderr)
    return 0


def cmd_compare(args: argparse.Namespace) -> int:
    from station.cli.recording import _replay_run
    from station.model.compare import CompareError, collect, format_comparison, joint_fit
    from station.session import store as sessions

    if not sessions.is_session(args.session):
        raise InputError("not a session directory (no raw.jsonl)", path=args.session)
    args.source, args.config, args.fast, args.date = args.session, None, True, None
    acq = _replay_run(args, quiet=True)
    data, excluded, windy = collect(acq.results(), args.wind_limit)
    try:
        res = joint_fit(
            acq.day.track, data, cda_fixed=args.cda, model=args.model, drift=args.drift,
            reference=args.reference,
        )  # fmt: skip
    except CompareError as exc:
        raise InputError(str(exc), path=args.session) from None
    res.excluded, res.wind_flagged = excluded, windy
    if windy:
        res.warnings.append(
            f"descents {', '.join(map(str, windy))} had more than {args.wind_limit:g} m/s of "
            "along-track wind: check them, or mark them invalid"
        )
    if args.csv:
        _write_compare_csv(res, args.csv, acq)
    if args.json:
        _print_json(res.to_dict())
        return 0
    print(format_comparison(res, len(data)))
    for w in res.warnings:
        _warn(w)
    return 0


def _write_compare_csv(res, path: str, run) -> None:
    import csv as _csv

    with open(path, "w", newline="", encoding="utf-8") as fh:
        fh.write(f"# station {__version__} comparison; reference {res.reference}; "
                 f"drift {'on' if res.drift_per_hour else 'off'}\n")  # fmt: skip
        w = _csv.writer(fh, quoting=_csv.QUOTE_NONNUMERIC, lineterminator="\n")
        w.writerow(["rank", "item", "descents", "mu", "mu_lo", "mu_hi", "delta_mu_vs_reference",
                    "delta_lo", "delta_hi", "p_faster_than_reference", "delta_t_s"])  # fmt: skip
        for k, name in enumerate(res.ranking, start=1):
            it = next(i for i in res.items if i.item == name)
            c = next((c for c in res.comparisons if c.b == name and c.a == res.reference), None)
            if c is None:
                row = [None] * 5
            else:  # item minus reference: the comparison stores reference minus item
                row = [-c.delta_mu, -c.ci90[1], -c.ci90[0], 1 - c.p_a_faster, -c.delta_t_s]
            w.writerow([k, it.item, len(it.descents), it.mu, it.ci90[0], it.ci90[1], *row])


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
    p.add_argument("session", metavar="SESSION")
    who = p.add_mutually_exclusive_group()
    who.add_argument("--descents", metavar="LIST", help="e.g. 1,4,5-8")
    who.add_argument("--from", dest="from_descent", type=int, metavar="N",
                     help="this and all later descents")  # fmt: skip
    from station.session.records import METADATA_FIELDS

    for f in METADATA_FIELDS:  # the one table of metadata keys
        text = (f.help or f.title).replace("%", "%%")  # argparse formats help with %
        p.add_argument(f.option, dest=f.key, type=_CHECKS[f.check], help=text)
    p.add_argument("--invalid", metavar="REASON", help="mark the descents invalid")
    p.add_argument("--valid", action="store_true", help="mark them valid again")
    p.add_argument("--model", choices=["constant", "velocity"], help="refit with this model")
    p.set_defaults(func=cmd_annotate)

    p = sub.add_parser("compare", help="which ski or wax glides better, by how much, how sure")
    p.add_argument("session", metavar="SESSION")
    p.add_argument("--reference", metavar="ITEM", help="compare every item with this one")
    p.add_argument("--cda", type=_positive, metavar="M2", help="fix CdA instead of fitting it")
    p.add_argument("--model", choices=["constant", "velocity"], default="constant")
    p.add_argument("--drift", choices=["auto", "on", "off"], default="auto")
    p.add_argument("--wind-limit", type=_positive, default=1.0, metavar="MS",
                   help="flag descents with more along-track wind (m/s)")  # fmt: skip
    p.add_argument("--csv", metavar="OUT")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compare)
