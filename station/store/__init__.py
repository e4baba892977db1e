"""The season store: every recorded test day in one database, its descents and fits, its
items, the conditions they were skied in and what the engineer annotated, so items can be
compared across days (``station season``).

One schema (SQLAlchemy Core, :mod:`station.store.schema`) on two engines: an SQLite file by
default (``sessions/season.db``) and PostgreSQL for a team's server; Alembic migrations bring a
store made by an older station up to date on open (:mod:`station.store.db`). Sessions are read
by one adapter (:mod:`station.store.ingest`) and written one transaction each
(:mod:`station.store.writer`). Imported only by the command line, the UI and the report.
"""

from __future__ import annotations

import os


def configured(config_store: str | None = None) -> str | None:
    """The season store the environment names (``$STATION_STORE``), else ``config_store`` (a
    station config's ``store:``); None when neither names one. Here, in the package, so a
    command that only asks whether a store is configured does not load SQLAlchemy."""
    return os.environ.get("STATION_STORE") or config_store
