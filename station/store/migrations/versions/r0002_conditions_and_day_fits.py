"""The conditions of each descent (air and snow as testers record them) and each day's
comparison of its items (μ per item and their covariance, per grouping), which the season's
comparison joins across days. A store of r0001 gains them empty: ``station season add`` of its
sessions again fills them (their content is unchanged, so they are marked for it here).

Revision ID: r0002
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "r0002"
down_revision = "r0001"
branch_labels = None
depends_on = None


def _session_key() -> sa.Column:
    return sa.Column(
        "session_id",
        sa.String(64),
        sa.ForeignKey("sessions.id", ondelete="CASCADE"),
        primary_key=True,
    )


def upgrade() -> None:
    op.create_table(
        "conditions",
        _session_key(),
        sa.Column("descent", sa.Integer, primary_key=True),
        *(
            sa.Column(n, sa.Double)
            for n in (
                "air_temperature_c",
                "snow_temperature_c",
                "humidity_pct",
                "pressure_hpa",
                "wind_ms",
                "grain_size_mm",
            )
        ),  # fmt: skip
        *(sa.Column(n, sa.Text) for n in ("snow_type", "wetness", "hardness")),
    )
    op.create_table(
        "day_fits",
        _session_key(),
        sa.Column("grouping", sa.Text, primary_key=True),
        sa.Column("status", sa.Text, nullable=False),
        sa.Column("message", sa.Text, nullable=False),
        sa.Column("posture_sd", sa.Double),
        sa.Column("sigma_s", sa.Double),
    )
    op.create_table(
        "items",
        _session_key(),
        sa.Column("grouping", sa.Text, primary_key=True),
        sa.Column("position", sa.Integer, primary_key=True),
        sa.Column("item", sa.Text, nullable=False),
        sa.Column("mu", sa.Double, nullable=False),
        sa.Column("descents", sa.Integer, nullable=False),
        sa.Column("descent_numbers", sa.Text, nullable=False),
    )
    op.create_table(
        "item_covariance",
        _session_key(),
        sa.Column("grouping", sa.Text, primary_key=True),
        sa.Column("a", sa.Integer, primary_key=True),
        sa.Column("b", sa.Integer, primary_key=True),
        sa.Column("cov", sa.Double, nullable=False),
    )
    # the sessions already stored have no conditions or day fits yet: the next add fills them
    op.execute(sa.text("UPDATE sessions SET content_sha256 = ''"))


def downgrade() -> None:
    for name in ("item_covariance", "items", "day_fits", "conditions"):
        op.drop_table(name)
