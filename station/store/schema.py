"""The season store's tables, written once with SQLAlchemy Core for both engines (an SQLite file
at the track, PostgreSQL on a team's server).

A session is identified by its raw log's SHA-256: the raw log is the day, every other file of a
session can be made again from it. Everything else a session brings is replaced as a whole
when it is added again (one transaction): its descents with their fits, the conditions each
descent was skied in, the annotation log (the history of what the engineer entered, in order),
and the day's comparison of its items (each grouping's μ per item and their covariance, from
the day model of :mod:`station.model.compare`), which ``station season compare`` joins across
days without replaying anything.

Numbers are ``Double`` (IEEE double on both engines): the same numbers come back from SQLite and
PostgreSQL. Times are UNIX seconds; dates and local times as text (``YYYY-MM-DD HH:MM``).

The schema here is the head revision; the migrations in :mod:`station.store.migrations` build it
step by step, and a test checks that both give the same tables.
"""

from __future__ import annotations

import sqlalchemy as sa

metadata = sa.MetaData()

#: the conditions a descent is skied in: the numeric ones (``--at`` and ``--where`` take them)
NUMERIC_CONDITIONS = (
    "air_temperature_c",
    "snow_temperature_c",
    "humidity_pct",
    "pressure_hpa",
    "wind_ms",
    "grain_size_mm",
)
#: … and those given as classes
TEXT_CONDITIONS = ("snow_type", "wetness", "hardness")
CONDITIONS = NUMERIC_CONDITIONS + TEXT_CONDITIONS
#: what a descent's item is made of (``--by``)
ITEM_PARTS = ("skier", "ski", "wax", "grind", "base")
#: a descent's numbers, a column each: the results row's own, but v0's interval (``v0_lo``,
#: ``v0_hi``: the fit's). One list for the table and the ingest that fills it, so that a number
#: added to one cannot be missed by the other
DESCENT_NUMBERS = (
    "mu",
    "mu_lo",
    "mu_hi",
    "mu1",
    "cda",
    "cda_lo",
    "cda_hi",
    "v0",
    "v0_lo",
    "v0_hi",
    "rms_residual_ms",
    "mass_kg",
    "air_density",
    "gravity",
)
#: the groupings a day's items are compared by (``season compare --by``)
GROUPINGS = ("item", "ski", "wax", "grind")

sessions = sa.Table(
    "sessions",
    metadata,
    sa.Column("id", sa.String(64), primary_key=True),  # SHA-256 of raw.jsonl, hex
    sa.Column("name", sa.Text, nullable=False),  # the session folder's name
    sa.Column("source", sa.Text, nullable=False),  # where it was added from
    sa.Column("started", sa.Text, nullable=False),  # local date and time of the first record
    sa.Column("date", sa.Text, nullable=False),  # local date, YYYY-MM-DD ("" unknown)
    sa.Column("site", sa.Text, nullable=False),  # the survey's name
    sa.Column("survey_sha256", sa.Text, nullable=False),
    sa.Column("config_sha256", sa.Text, nullable=False),
    sa.Column("station_version", sa.Text, nullable=False),  # the station that added it
    sa.Column("content_sha256", sa.Text, nullable=False),  # raw log + annotations + config
    sa.Column("descents", sa.Integer, nullable=False),
    sa.Column("valid", sa.Integer, nullable=False),  # fitted ok, not marked invalid
    sa.Column("added_t", sa.Double, nullable=False),
    sa.Column("updated_t", sa.Double, nullable=False),
)


def _session_key() -> sa.Column:
    """The first key column of each table a session brings: the session it belongs to, whose
    rows go with it (``ON DELETE CASCADE``). A function, not a column shared: a column belongs
    to one table; one definition for the six tables that each wrote it out."""
    return sa.Column(
        "session_id",
        sa.String(64),
        sa.ForeignKey("sessions.id", ondelete="CASCADE"),
        primary_key=True,
    )


descents = sa.Table(
    "descents",
    metadata,
    _session_key(),
    sa.Column("number", sa.Integer, primary_key=True),
    sa.Column("start_time", sa.Text, nullable=False),
    sa.Column("status", sa.Text, nullable=False),  # the fit's verdict (records.Status)
    sa.Column("descent_status", sa.Text, nullable=False),
    sa.Column("model", sa.Text, nullable=False),
    sa.Column("photocells_used", sa.Integer, nullable=False),
    *(sa.Column(name, sa.Double) for name in DESCENT_NUMBERS),
    sa.Column("flags", sa.Text, nullable=False),
    sa.Column("invalid_reason", sa.Text, nullable=False),
    sa.Column("item", sa.Text, nullable=False),  # ski / wax, as the day comparison names it
    *(sa.Column(name, sa.Text, nullable=False) for name in ITEM_PARTS),
    sa.Column("notes", sa.Text, nullable=False),
)

annotation_log = sa.Table(
    "annotations",
    metadata,
    _session_key(),
    sa.Column("seq", sa.Integer, primary_key=True),  # its place in annotations.jsonl
    sa.Column("t", sa.Double),  # when it was entered
    sa.Column("kind", sa.Text, nullable=False),  # metadata | invalid | valid | model
    sa.Column("record", sa.Text, nullable=False),  # the JSON record as the session holds it
)

conditions = sa.Table(
    "conditions",
    metadata,
    _session_key(),
    sa.Column("descent", sa.Integer, primary_key=True),
    *(sa.Column(name, sa.Double) for name in NUMERIC_CONDITIONS),
    *(sa.Column(name, sa.Text) for name in TEXT_CONDITIONS),
)

#: each grouping's fit of the day: its verdict (only an "ok" day enters the season's comparison)
day_fits = sa.Table(
    "day_fits",
    metadata,
    _session_key(),
    sa.Column("grouping", sa.Text, primary_key=True),
    sa.Column("status", sa.Text, nullable=False),
    sa.Column("message", sa.Text, nullable=False),
    sa.Column("posture_sd", sa.Double),
    sa.Column("sigma_s", sa.Double),
)

#: the day's μ per item of a grouping (only items with two descents or more: one descent's
#: glide cannot be told from its posture)
items = sa.Table(
    "items",
    metadata,
    _session_key(),
    sa.Column("grouping", sa.Text, primary_key=True),
    sa.Column("position", sa.Integer, primary_key=True),
    sa.Column("item", sa.Text, nullable=False),
    sa.Column("mu", sa.Double, nullable=False),
    sa.Column("descents", sa.Integer, nullable=False),
    sa.Column("descent_numbers", sa.Text, nullable=False),  # "1 4 5 8"
)

#: the covariance of the day's item μ (the upper triangle, a ≤ b, by position)
item_covariance = sa.Table(
    "item_covariance",
    metadata,
    _session_key(),
    sa.Column("grouping", sa.Text, primary_key=True),
    sa.Column("a", sa.Integer, primary_key=True),
    sa.Column("b", sa.Integer, primary_key=True),
    sa.Column("cov", sa.Double, nullable=False),
)

#: what a session replaces when it is added again, children first
CHILDREN = (item_covariance, items, day_fits, conditions, annotation_log, descents)
