"""SQLite specifics of the catalogue: file checks, connection pragmas, lock errors, names.

Kept apart from :mod:`driveid.catalog.store` (the engine-neutral catalogue); every function
here raises :class:`~driveid.errors.ConfigError` with one line naming the fix.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from driveid.errors import ConfigError

_SQLITE_HEADER = b"SQLite format 3\x00"


def check_sqlite_file(path: Path) -> None:
    """Refuse an existing file that is no driveid catalogue before any driver touches it.

    Opening with the engine would already change such a file: its connect hook switches
    the journal to WAL (a persistent change) and adds ``-wal``/``-shm`` files (issue 28).
    """
    import sqlite3

    if not path.is_file() or path.stat().st_size == 0:
        return  # a new catalogue (SQLite makes an empty file a database)
    fix = "name another file (--catalog NEW.sqlite) or move this one away"
    with path.open("rb") as fh:
        head = fh.read(len(_SQLITE_HEADER))
    if head != _SQLITE_HEADER:
        raise ConfigError(f"cannot open catalogue {path}: the file is not a SQLite database "
                          f"(it lacks the SQLite header); {fix}")
    try:
        con = sqlite3.connect(f"{path.resolve().as_uri()}?mode=ro", uri=True)
        try:
            tables = {row[0] for row in con.execute(
                "SELECT name FROM sqlite_master WHERE type = 'table'")}
        finally:
            con.close()
    except sqlite3.DatabaseError as exc:
        raise ConfigError(f"cannot open catalogue {path}: {exc}; {fix}") from None
    if tables and "schema_version" not in tables:
        raise ConfigError(f"{path} holds tables of another application but no "
                          f"schema_version table: not a driveid catalogue; {fix}")


def check_names(machine: Any, axis: Any) -> None:
    """Refuse names that 'driveid health MACHINE/AXIS' could not address afterwards."""
    # issue 28: --machine '' --axis '' was catalogued, and no MACHINE/AXIS names it
    for what, name in (("machine", machine), ("axis", axis)):
        if not isinstance(name, str) or not name.strip():
            raise ConfigError(f"the {what} name must be a non-empty text (--{what}); got "
                              f"{name!r}")
    if "/" in axis:
        raise ConfigError(f"the axis name must not contain '/' (health reads MACHINE/AXIS); "
                          f"got {axis!r}")


#: Seconds a SQLite catalogue waits for another process's write lock before giving up [s].
LOCK_WAIT = 30.0


def sqlite_locked(context: Any) -> None:
    """Turn SQLite's 'database is locked' (after the wait) into one line naming the fix."""
    import sqlite3

    exc = context.original_exception
    if isinstance(exc, sqlite3.OperationalError) and "locked" in str(exc):
        # issue 28: a catalogue held by another process ended in exit 70 after 60 s
        url = context.engine.url if context.engine is not None else "the catalogue"
        raise ConfigError(
            f"catalogue {url.database if hasattr(url, 'database') else url} stayed locked by "
            f"another process for {LOCK_WAIT:g} s ({exc}); wait for that process "
            "(a running 'driveid fleet identify'?) to finish and run this again, or name "
            "another catalogue (--catalog FILE)")


def sqlite_pragmas(dbapi_connection: Any, _record: Any) -> None:
    """Set each new SQLite connection's pragmas (foreign keys, write-ahead log)."""
    cursor = dbapi_connection.cursor()
    cursor.execute("PRAGMA foreign_keys=ON")
    # write-ahead log: readers don't block the writer, and a commit costs no full fsync
    cursor.execute("PRAGMA journal_mode=WAL")
    cursor.execute("PRAGMA synchronous=NORMAL")
    cursor.close()
