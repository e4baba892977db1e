"""A session directory: everything a test day needs to be replayed later.

    SESSION/
      raw.jsonl        every byte from the timer, with host timestamps (station.session.rawlog)
      config.yaml      the station config as it was, verbatim
      <survey files>   the survey YAML and its observation file, at the same relative paths
      results.csv      one row per descent, rewritten after each descent
      annotations.jsonl  what the engineer entered: metadata, invalid marks, refits

Replaying a session (``station replay SESSION``) runs its own snapshot through the same
processor and reproduces ``results.csv`` byte for byte.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import os
import re
import shutil

from station.errors import InputError
from station.session.config import StationConfig, load_config
from station.session.records import Annotation, annotation_from_json, annotation_to_json
from station.yamlfile import load_yaml

RAW = "raw.jsonl"
CONFIG = "config.yaml"
RESULTS = "results.csv"
ANNOTATIONS = "annotations.jsonl"


def is_session(path: str) -> bool:
    return os.path.isdir(path) and os.path.exists(os.path.join(path, RAW))


def default_dir(base: str = "sessions") -> str:
    return os.path.join(base, dt.datetime.now().strftime("%Y-%m-%d_%H%M%S"))


def _inside(rel: str) -> bool:
    return not os.path.isabs(rel) and not os.path.normpath(rel).startswith("..")


def _copy(src: str, dst: str) -> None:
    os.makedirs(os.path.dirname(dst), exist_ok=True)
    shutil.copyfile(src, dst)


def snapshot(cfg: StationConfig, session: str) -> None:
    """Copy the config and the survey (with its observation file) into the session."""
    cfg_dir = os.path.dirname(os.path.abspath(cfg.path))
    text = cfg.text
    rel = os.path.relpath(cfg.survey_path, cfg_dir)
    if not _inside(rel):
        rel = os.path.join("survey", os.path.basename(cfg.survey_path))
        text = re.sub(r"(?m)^survey:.*$", f"survey: {rel}", text)
    survey_dst = os.path.join(session, rel)
    _copy(cfg.survey_path, survey_dst)
    data = load_yaml(cfg.survey_path)
    obs = data.get("observations") if isinstance(data, dict) else None
    if isinstance(obs, str):
        src = os.path.join(os.path.dirname(cfg.survey_path), obs)
        if os.path.exists(src):
            if _inside(obs):
                _copy(src, os.path.join(os.path.dirname(survey_dst), obs))
            else:
                _copy(src, os.path.join(os.path.dirname(survey_dst), os.path.basename(obs)))
                with open(survey_dst, encoding="utf-8") as fh:
                    stext = fh.read()
                stext = re.sub(
                    r"(?m)^observations:.*$", f"observations: {os.path.basename(obs)}", stext
                )
                with open(survey_dst, "w", encoding="utf-8") as fh:
                    fh.write(stext)
    with open(os.path.join(session, CONFIG), "w", encoding="utf-8") as fh:
        fh.write(text)


def create(cfg: StationConfig, session: str) -> str:
    if os.path.exists(os.path.join(session, RAW)):
        raise InputError(
            "a session is already recorded there; choose a new --session-dir", path=session
        )
    os.makedirs(session, exist_ok=True)
    snapshot(cfg, session)
    return session


def load_session_config(session: str) -> StationConfig:
    path = os.path.join(session, CONFIG)
    if not os.path.exists(path):
        raise InputError("session has no config.yaml; give --config", path=session)
    return load_config(path)


def _digest(path: str) -> str:
    with open(path, "rb") as fh:
        return hashlib.sha256(fh.read()).hexdigest()[:12]


def results_header(cfg: StationConfig, survey_name: str) -> dict[str, str]:
    """What the results were computed from, the same live and in replay."""
    air = "; ".join(f"{k} {v:g}" for k, v in cfg.air.items() if k != "density")
    return {  # `key: value` with ";" inside values: no comma, so a spreadsheet keeps each line
        "survey": f"{survey_name}; file {os.path.basename(cfg.survey_path)}; "
        f"sha256 {_digest(cfg.survey_path)}",
        "config": f"{os.path.basename(cfg.path)}; sha256 {_digest(cfg.path)}",
        "protocol": cfg.serial.protocol,
        "skier": f"mass {cfg.mass_kg:g} kg",
        "air": (f"{air}; " if air else "") + f"density {cfg.air_density:.4f} kg/m3",
        "fit": f"model {cfg.model}; 90 % intervals linearised (Wald); Student t",
    }


def append_annotation(session: str, annotation: Annotation) -> None:
    """Append one annotation (flushed and fsync'd: it is the engineer's word)."""
    path = os.path.join(session, ANNOTATIONS)
    record = annotation_to_json(annotation)
    with open(path, "a", encoding="utf-8") as fh:
        fh.write(json.dumps(record, ensure_ascii=False, sort_keys=True) + "\n")
        fh.flush()
        os.fsync(fh.fileno())


def read_annotations(session: str) -> list[Annotation]:
    """The session's annotations in order; a torn last line is passed over, a kind this
    version does not know too; a bad record is one error naming file, line and field."""
    path = os.path.join(session, ANNOTATIONS)
    if not os.path.exists(path):
        return []
    out = []
    with open(path, encoding="utf-8") as fh:
        lines = fh.read().splitlines()
    for i, line in enumerate(lines, start=1):
        if not line.strip():
            continue
        try:
            rec = json.loads(line)
        except ValueError:
            if i == len(lines):
                break
            raise InputError("not an annotation record", path=path, line=i) from None
        if not isinstance(rec, dict):
            continue
        try:
            annotation = annotation_from_json(rec)
        except InputError as exc:
            raise InputError(exc.message, path=path, line=i, field=exc.field) from None
        if annotation is not None:
            out.append(annotation)
    return out
