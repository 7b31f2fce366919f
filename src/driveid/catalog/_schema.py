"""Tables of the catalogue and the ordered schema migrations that create them.

The schema is versioned by a one-row table ``schema_version``; :data:`MIGRATIONS` lists
the steps in order, each a function of an open transaction. A plain list was chosen over
Alembic: four tables, additive changes, and no second tool for users to run; the runner is
twenty lines and tested (``tests/catalog/test_catalog.py::test_migrates_a_version_1_file``).
"""

from __future__ import annotations

from collections.abc import Callable

import sqlalchemy as sa

__all__ = ["METADATA", "entries", "inputs", "parameters", "covariance", "schema_version",
           "MIGRATIONS", "SCHEMA_VERSION"]


def _define_tables(md: sa.MetaData, *, version: int) -> tuple[sa.Table, ...]:
    extra = [sa.Column("machine_type", sa.String(200))] if version >= 2 else []
    entries_table = sa.Table(
        "entries", md,
        sa.Column("id", sa.Integer, primary_key=True, autoincrement=True),
        sa.Column("entry_key", sa.String(64), nullable=False, unique=True),
        sa.Column("machine", sa.String(200), nullable=False),
        sa.Column("axis", sa.String(200), nullable=False),
        sa.Column("measured_at", sa.DateTime, nullable=False),
        sa.Column("added_at", sa.DateTime, nullable=False),
        sa.Column("method", sa.String(100), nullable=False),
        sa.Column("status", sa.String(10), nullable=False),
        sa.Column("error", sa.Text),
        sa.Column("driveid_version", sa.String(40)),
        sa.Column("command", sa.Text),
        sa.Column("diagnostics", sa.Text),
        sa.Column("warnings", sa.Text),
        *extra,
    )
    inputs_table = sa.Table(
        "inputs", md,
        sa.Column("entry_id", sa.Integer, sa.ForeignKey("entries.id", ondelete="CASCADE"),
                  primary_key=True),
        sa.Column("position", sa.Integer, primary_key=True),
        sa.Column("sha256", sa.String(64), nullable=False, index=True),
        sa.Column("path", sa.Text),
        sa.Column("rows", sa.Integer),
        sa.Column("details", sa.Text),
    )
    parameters_table = sa.Table(
        "parameters", md,
        sa.Column("entry_id", sa.Integer, sa.ForeignKey("entries.id", ondelete="CASCADE"),
                  primary_key=True),
        sa.Column("name", sa.String(60), primary_key=True),
        sa.Column("value", sa.Float),
        sa.Column("stderr", sa.Float),
        sa.Column("unit", sa.String(40)),
        sa.Column("fixed", sa.Boolean, nullable=False),
    )
    covariance_table = sa.Table(
        "covariance", md,
        sa.Column("entry_id", sa.Integer, sa.ForeignKey("entries.id", ondelete="CASCADE"),
                  primary_key=True),
        sa.Column("row_name", sa.String(60), primary_key=True),
        sa.Column("col_name", sa.String(60), primary_key=True),
        sa.Column("value", sa.Float),
    )
    return entries_table, inputs_table, parameters_table, covariance_table


METADATA = sa.MetaData()
schema_version = sa.Table("schema_version", METADATA,
                          sa.Column("version", sa.Integer, nullable=False))
entries, inputs, parameters, covariance = _define_tables(METADATA, version=2)


def _migration_1(conn: sa.Connection) -> None:
    """Version 1: entries, inputs, parameters, covariance (no ``machine_type`` yet)."""
    md = sa.MetaData()
    _define_tables(md, version=1)
    md.create_all(conn)


def _migration_2(conn: sa.Connection) -> None:
    """Version 2: the machine type of an entry, and an index for axis histories."""
    conn.execute(sa.text("ALTER TABLE entries ADD COLUMN machine_type VARCHAR(200)"))
    conn.execute(sa.text(
        "CREATE INDEX ix_entries_axis ON entries (machine, axis, measured_at)"))


#: Ordered migrations: ``MIGRATIONS[i]`` takes the schema from version i to i + 1.
MIGRATIONS: list[Callable[[sa.Connection], None]] = [_migration_1, _migration_2]
#: The schema version this code reads and writes.
SCHEMA_VERSION = len(MIGRATIONS)
