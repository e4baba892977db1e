"""A recorded session as the season store keeps it: the one place that reads session folders.

It opens the session as a :class:`station.session.recorded.RecordedSession` and replays its raw
log with its annotations (as ``station replay`` and ``station export`` do: the raw log is the
day, results.csv only a view of it), so the descents, fits,
marks and conditions are those the station gives today, and fits the day model of
:mod:`station.model.compare` once per grouping of the descents (by item, ski, wax, grind) to
keep each day's μ per item with their covariance, which the season's comparison joins.

Two steps, so a session added again costs a hash, not a replay: :func:`identify` (the raw
log's SHA-256 and a digest of everything the results depend on), then :func:`read`.
"""

from __future__ import annotations

import hashlib
import json
import os
from dataclasses import dataclass, field, replace
from typing import Any

from station import __version__
from station.errors import InputError
from station.store.schema import CONDITIONS, DESCENT_NUMBERS, GROUPINGS, ITEM_PARTS

_CHUNK = 1 << 20


@dataclass(frozen=True)
class Identity:
    """What names a session and says whether it changed."""

    id: str  # SHA-256 of raw.jsonl
    content_sha256: str  # of the session's own files (not the results CSV, fits cache, lock)


@dataclass
class SessionRecord:
    """Everything the store holds of one session: rows for its tables."""

    identity: Identity
    session: dict[str, Any]
    descents: list[dict[str, Any]] = field(default_factory=list)
    conditions: list[dict[str, Any]] = field(default_factory=list)
    annotations: list[dict[str, Any]] = field(default_factory=list)
    day_fits: list[dict[str, Any]] = field(default_factory=list)
    items: list[dict[str, Any]] = field(default_factory=list)
    covariances: list[dict[str, Any]] = field(default_factory=list)


def _sha256(path: str) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while chunk := fh.read(_CHUNK):
            h.update(chunk)
    return h.hexdigest()


def identify(session: str) -> Identity:
    """The session's identity; a folder that is no finished session is an :class:`InputError`."""
    from station.session import store as sessions

    if not os.path.exists(session):
        raise InputError("no such session folder", path=session)
    if not sessions.is_session(session):
        raise InputError("not a session folder (no raw.jsonl)", path=session)
    if sessions.recording_state(session) is sessions.Recording.NOW:
        raise InputError("being recorded now: add it when the recording has ended", path=session)
    # what is made from the others (the results CSV, the fits' cache) or says who records is
    # not part of its identity: session/store.DERIVED
    content = hashlib.sha256()
    raw_id = ""
    try:
        for root, dirs, files in os.walk(session):
            dirs.sort()
            for name in sorted(files):
                path = os.path.join(root, name)
                rel = os.path.relpath(path, session)
                if rel in sessions.DERIVED or not os.path.isfile(path):
                    continue
                digest = _sha256(path)
                if rel == sessions.RAW:
                    raw_id = digest
                content.update(f"{rel}\0{digest}\0".encode())
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path=exc.filename or session) from None
    return Identity(raw_id, content.hexdigest())


def _group_label(meta: Any, grouping: str, item: str) -> str:
    if grouping == "item":
        return item
    value = getattr(meta, grouping, None)
    return str(value).strip() if value not in (None, "") else f"(no {grouping})"


def read(session: str, identity: Identity | None = None) -> SessionRecord:
    """The session's rows for the store (a replay and the day fits: a fraction of a second)."""
    import time

    from station.files import MAX_OBSERVATIONS
    from station.session.recorded import RecordedSession, sha256_of

    ident = identity or identify(session)
    rs = RecordedSession(session)
    results = list(rs.results())
    started = rs.started()
    prov_cfg = rs.config
    now = time.time()
    rec = SessionRecord(
        ident,
        {
            "id": ident.id,
            "name": rs.name,
            "source": os.path.abspath(session),
            "started": started,
            "date": started[:10],
            "site": str(getattr(rs.track, "name", "") or ""),
            "survey_sha256": sha256_of(prov_cfg.survey_path, MAX_OBSERVATIONS, "survey file"),
            "config_sha256": sha256_of(prov_cfg.path, MAX_OBSERVATIONS, "config"),
            "station_version": __version__,
            "content_sha256": ident.content_sha256,
            "descents": sum(r.row.descent_status != "aborted" for r in results),
            "valid": sum(r.row.status == "ok" and not r.row.invalid_reason for r in results),
            "added_t": now,
            "updated_t": now,
        },
    )
    meta_of = _add_descents(rec, results)
    _add_annotations(rec, rs.annotations())
    _add_day_fits(rec, rs.track, results, meta_of)
    return rec


def _add_descents(rec: SessionRecord, results: list[Any]) -> dict[int, Any]:
    """Each descent's row and its conditions; returns the metadata of each descent."""
    from station.model.compare import item_of

    sid = rec.identity.id
    meta_of = {}
    for r in results:
        row, fit = r.row, r.fit
        meta = row.metadata
        meta_of[row.descent] = meta
        v0_ci = fit.v0.ci90 if fit is not None else None
        from_fit = {"v0_lo": v0_ci[0] if v0_ci else None, "v0_hi": v0_ci[1] if v0_ci else None}
        rec.descents.append(
            {
                "session_id": sid,
                "number": row.descent,
                "start_time": row.start_time,
                "status": str(row.status),
                "descent_status": str(row.descent_status),
                "model": str(row.model),
                "photocells_used": row.photocells_used,
                **{k: from_fit[k] if k in from_fit else getattr(row, k) for k in DESCENT_NUMBERS},
                "flags": "; ".join(row.flags),
                "invalid_reason": row.invalid_reason,
                "item": item_of(row),
                **{k: str(getattr(meta, k, None) or "") for k in ITEM_PARTS},
                "notes": meta.notes or "",
            }
        )
        cond: dict[str, Any] = {k: getattr(meta, k, None) for k in CONDITIONS}
        cond["wind_ms"] = row.wind_ms if meta.wind_ms is not None else None
        rec.conditions.append({"session_id": sid, "descent": row.descent, **cond})
    return meta_of


def _add_annotations(rec: SessionRecord, annotations: list[Any]) -> None:
    """The annotation log, in order."""
    from station.session.records import annotation_to_json

    for seq, a in enumerate(annotations, start=1):
        js = annotation_to_json(a)
        rec.annotations.append(
            {
                "session_id": rec.identity.id,
                "seq": seq,
                "t": a.t,
                "kind": str(js.get("type", "")),
                "record": json.dumps(js, ensure_ascii=False, sort_keys=True),
            }
        )


def _add_day_fits(
    rec: SessionRecord, track: Any, results: list[Any], meta_of: dict[int, Any]
) -> None:
    """The day model fitted once per grouping of the descents (by item, ski, wax, grind): its
    status, and its items' μ with their covariance (items with two descents or more)."""
    from station.model.compare import CompareError, collect, joint_fit

    data, _excluded, _windy = collect(results)
    fitted: dict[tuple[int, ...], Any] = {}
    for grouping in GROUPINGS:
        labels = [_group_label(meta_of[d.number], grouping, d.item) for d in data]
        order: dict[str, int] = {}
        key = tuple(order.setdefault(x, len(order)) for x in labels)
        base = {"session_id": rec.identity.id, "grouping": grouping}
        if len(order) < 2:
            rec.day_fits.append({**base, "status": "one-item", "message":
                                 f"one {grouping} only: nothing to compare",
                                 "posture_sd": None, "sigma_s": None})  # fmt: skip
            continue
        if key not in fitted:
            grouped = [replace(d, item=f"#{key[k]}") for k, d in enumerate(data)]
            try:
                fitted[key] = joint_fit(track, grouped, drift="auto")
            except CompareError as exc:
                fitted[key] = exc
        res = fitted[key]
        if isinstance(res, CompareError):
            rec.day_fits.append({**base, "status": "error", "message": str(res),
                                 "posture_sd": None, "sigma_s": None})  # fmt: skip
            continue
        names = {f"#{i}": name for name, i in order.items()}
        rec.day_fits.append({**base, "status": res.status, "message": res.message,
                             "posture_sd": res.posture_sd, "sigma_s": res.sigma_s})  # fmt: skip
        keep = [k for k, it in enumerate(res.items) if len(it.descents) >= 2]
        for pos, k in enumerate(keep):
            it = res.items[k]
            rec.items.append({**base, "position": pos, "item": names[it.item], "mu": it.mu,
                              "descents": len(it.descents),
                              "descent_numbers": " ".join(map(str, it.descents))})  # fmt: skip
        cov = res.item_cov
        for pa, ka in enumerate(keep):
            for pb in range(pa, len(keep)):
                rec.covariances.append({**base, "a": pa, "b": pb,
                                        "cov": float(cov[ka][keep[pb]])})  # fmt: skip
