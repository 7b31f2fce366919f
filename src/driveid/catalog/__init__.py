"""Catalogue of identifications over time: SQLite by default, PostgreSQL by URL.

See :class:`driveid.catalog.store.Catalog` and ``docs/fleet.md``.
"""

from driveid.catalog.store import (
    DEFAULT_CATALOG,
    RESULT_SCHEMA,
    AddOutcome,
    Catalog,
    CatalogEntry,
    catalog_url,
    entry_key,
    file_sha256,
    parse_time,
)

__all__ = [
    "DEFAULT_CATALOG",
    "RESULT_SCHEMA",
    "AddOutcome",
    "Catalog",
    "CatalogEntry",
    "catalog_url",
    "entry_key",
    "file_sha256",
    "parse_time",
]
