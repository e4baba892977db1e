"""The first store: sessions, their descents with the fits, and the annotation log.

Revision ID: r0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0001"
down_revision = None
branch_labels = None
depends_on = None

_FIT = ("mu", "mu_lo", "mu_hi", "mu1", "cda", "cda_lo", "cda_hi", "v0", "v0_lo", "v0_hi",
        "rms_residual_ms", "mass_kg", "air_density", "gravity")  # fmt: skip
_ITEM = ("skier", "ski", "wax", "grind", "base")


def _session_key() -> sa.Column:
    return sa.Column(
        "session_id",
        sa.String(64),
        sa.ForeignKey("sessions.id", ondelete="CASCADE"),
        primary_key=True,
    )


def upgrade() -> None:
    op.create_table(
        "sessions",
        sa.Column("id", sa.String(64), primary_key=True),
        *(
            sa.Column(n, sa.Text, nullable=False)
            for n in (
                "name",
                "source",
                "started",
                "date",
                "site",
                "survey_sha256",
                "config_sha256",
                "station_version",
                "content_sha256",
            )
        ),  # fmt: skip
        sa.Column("descents", sa.Integer, nullable=False),
        sa.Column("valid", sa.Integer, nullable=False),
        sa.Column("added_t", sa.Double, nullable=False),
        sa.Column("updated_t", sa.Double, nullable=False),
    )
    op.create_table(
        "descents",
        _session_key(),
        sa.Column("number", sa.Integer, primary_key=True),
        *(
            sa.Column(n, sa.Text, nullable=False)
            for n in ("start_time", "status", "descent_status", "model")
        ),  # fmt: skip
        sa.Column("photocells_used", sa.Integer, nullable=False),
        *(sa.Column(n, sa.Double) for n in _FIT),
        sa.Column("flags", sa.Text, nullable=False),
        sa.Column("invalid_reason", sa.Text, nullable=False),
        sa.Column("item", sa.Text, nullable=False),
        *(sa.Column(n, sa.Text, nullable=False) for n in _ITEM),
        sa.Column("notes", sa.Text, nullable=False),
    )
    op.create_table(
        "annotations",
        _session_key(),
        sa.Column("seq", sa.Integer, primary_key=True),
        sa.Column("t", sa.Double),
        sa.Column("kind", sa.Text, nullable=False),
        sa.Column("record", sa.Text, nullable=False),
    )


def downgrade() -> None:
    for name in ("annotations", "descents", "sessions"):
        op.drop_table(name)
