"""The catalogue: every identification of every axis, with its provenance, in SQL.

SQLite (a file, no set-up) by default, PostgreSQL by URL, through SQLAlchemy Core; the same
statements run on both. Each entry is keyed by a SHA-256 of its inputs' hashes and the
method, so adding the same result twice, or a fleet task that is retried after a lost
worker, never duplicates an entry. Identifications that failed are entries too
(``status="failed"`` with the error), so a fleet run's bad files are visible and are not
retried on resume.

This is the catalogue of de Marchi (1998) §6.1 ("track parameter drifts ... monitor the
general health of the machine's dynamic components"): identify the same drive again and
again, keep every result with its standard errors, and let :mod:`driveid.health` judge drift.
"""

from __future__ import annotations

import datetime as dt
import hashlib
import json
import math
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import sqlalchemy as sa

from driveid._json import to_jsonable
from driveid.catalog import _schema as S
from driveid.catalog import _sqlite
from driveid.errors import ConfigError, FileFormatError
from driveid.identify.core.estimate import Parameter, non_finite_problem
from driveid.io.reading import file_sha256

__all__ = [
    "DEFAULT_CATALOG",
    "RESULT_SCHEMA",
    "Catalog",
    "CatalogEntry",
    "AddOutcome",
    "catalog_url",
    "entry_key",
    "parse_time",
    "file_sha256",
]

#: The catalogue used when none is named: a SQLite file in the working directory.
DEFAULT_CATALOG = "driveid-catalog.sqlite"
#: Result schema this catalogue reads (written by ``driveid identify ... --json``).
RESULT_SCHEMA = "driveid-result/1"
_ENTRY_COLUMNS = ("id", "entry_key", "machine", "axis", "machine_type", "measured_at",
                  "added_at", "method", "status", "error", "driveid_version")


def catalog_url(catalog: str | Path | None = None) -> str:
    """Return the SQLAlchemy URL of a catalogue given as a file, a URL or nothing.

    Parameters
    ----------
    catalog : str or Path, optional
        A SQLite file (``plant.sqlite``), a SQLAlchemy URL (``sqlite:///plant.sqlite``,
        ``postgresql://user@host/db``) or ``None`` for :data:`DEFAULT_CATALOG` in the working
        directory.

    Returns
    -------
    str
        The URL; ``postgresql://`` is given the installed driver (``postgresql+psycopg://``).

    Raises
    ------
    ConfigError
        If the URL names a database other than SQLite or PostgreSQL.

    Examples
    --------
    >>> catalog_url("postgresql://me@db/plant")
    'postgresql+psycopg://me@db/plant'
    >>> catalog_url("/data/plant.sqlite")
    'sqlite:////data/plant.sqlite'
    """
    if catalog is None:
        catalog = DEFAULT_CATALOG
    text = str(catalog)
    if "://" not in text:
        return f"sqlite:///{Path(text).expanduser().absolute()}"
    scheme, _, rest = text.partition("://")
    if scheme in ("postgresql", "postgres"):
        return f"postgresql+psycopg://{rest}"
    if scheme.startswith("postgresql+") or scheme.startswith("sqlite"):
        return text
    raise ConfigError(
        f"catalogue URL must be a SQLite file or sqlite:///FILE or postgresql://...; got "
        f"{text!r}")


def parse_time(value: str | dt.datetime | None) -> dt.datetime:
    """Return a measurement time as a naive UTC datetime (how the catalogue stores times).

    Parameters
    ----------
    value : str or datetime or None
        ISO 8601 text (``2026-03-01``, ``2026-03-01T08:30``, ``...Z``, ``...+01:00``); a
        time without zone is taken as UTC. ``None`` is now.

    Returns
    -------
    datetime
        Naive, in UTC.

    Raises
    ------
    ConfigError
        If the text is not ISO 8601.

    Examples
    --------
    >>> parse_time("2026-03-01T09:30+01:00")
    datetime.datetime(2026, 3, 1, 8, 30)
    """
    if value is None:
        return dt.datetime.now(dt.UTC).replace(tzinfo=None, microsecond=0)
    if isinstance(value, dt.datetime):
        stamp = value
    else:
        text = str(value).strip()
        if text.endswith("Z"):
            text = text[:-1] + "+00:00"
        try:
            stamp = dt.datetime.fromisoformat(text)
        except ValueError:
            raise ConfigError(
                f"time must be ISO 8601 such as 2026-03-01 or 2026-03-01T08:30Z; got "
                f"{value!r}") from None
    if stamp.tzinfo is not None:
        stamp = stamp.astimezone(dt.UTC).replace(tzinfo=None)
    return stamp


def entry_key(input_hashes: Sequence[str], method: str, *, fallback: Any = None) -> str:
    """Return the key that makes an entry unique: its inputs' hashes and the method.

    Parameters
    ----------
    input_hashes : sequence of str
        SHA-256 of each input file (order does not matter).
    method : str
        Identification method, e.g. ``"logdec"``.
    fallback : Any, optional
        JSON-able content hashed instead when no input carries a hash.

    Returns
    -------
    str
        64 hexadecimal digits.
    """
    hashes = sorted(h for h in input_hashes if h)
    if hashes:
        payload: Any = {"inputs": hashes, "method": method}
    else:
        payload = {"content": to_jsonable(fallback), "method": method}
    text = json.dumps(payload, sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode()).hexdigest()


@dataclass(frozen=True)
class CatalogEntry:
    """One catalogued identification (or failure) of one axis.

    Attributes
    ----------
    id : int
        Database id.
    key : str
        The hash key (:func:`entry_key`).
    machine, axis : str
        Where it was measured.
    machine_type : str or None
        The type whose blueprint applies.
    measured_at : datetime
        Measurement time, naive UTC.
    method : str
        Estimator name.
    status : str
        ``"ok"`` or ``"failed"``.
    error : str or None
        Why it failed.
    driveid_version : str or None
        Version that produced it.
    parameters : mapping of str to Parameter
        Values with standard errors and units (empty for a failure).
    covariance : mapping or None
        ``{"names": [...], "matrix": list of lists}``.
    inputs : tuple of mapping
        ``path``, ``sha256``, ``rows`` and the rest of each input's provenance.
    command : list of str
        The command line that produced it.
    warnings : tuple of str
        The estimate's warnings.
    diagnostics : mapping
        The estimate's scalar diagnostics.
    """

    id: int
    key: str
    machine: str
    axis: str
    machine_type: str | None
    measured_at: dt.datetime
    method: str
    status: str
    error: str | None
    driveid_version: str | None
    parameters: Mapping[str, Parameter] = field(default_factory=dict)
    covariance: Mapping[str, Any] | None = None
    inputs: tuple[Mapping[str, Any], ...] = ()
    command: list[str] = field(default_factory=list)
    warnings: tuple[str, ...] = ()
    diagnostics: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready dict of the entry (times in ISO 8601, UTC)."""
        return to_jsonable({
            "id": self.id, "key": self.key, "machine": self.machine, "axis": self.axis,
            "machine_type": self.machine_type,
            "measured_at": self.measured_at.isoformat() + "Z", "method": self.method,
            "status": self.status, "error": self.error,
            "driveid_version": self.driveid_version,
            "parameters": {n: {"value": p.value, "stderr": p.stderr, "unit": p.unit,
                               "fixed": p.fixed} for n, p in self.parameters.items()},
            "covariance": self.covariance, "inputs": list(self.inputs),
            "command": self.command, "warnings": list(self.warnings),
            "diagnostics": dict(self.diagnostics),
        })


@dataclass(frozen=True)
class AddOutcome:
    """What :meth:`Catalog.add_result` did.

    Attributes
    ----------
    entry_id : int
        Id of the new entry, or of the existing one with the same key.
    created : bool
        False when the same inputs and method were already catalogued.
    key : str
        The entry's hash key.
    """

    entry_id: int
    created: bool
    key: str


class Catalog:
    """A catalogue of identifications in SQLite or PostgreSQL.

    Parameters
    ----------
    catalog : str or Path, optional
        File or URL (see :func:`catalog_url`); default ``./driveid-catalog.sqlite``.
    create : bool
        Create the file/schema when missing (default). With False a missing SQLite file is
        an error, so a typo does not silently start an empty catalogue.

    Raises
    ------
    ConfigError
        If the URL is not usable, the file is missing with ``create=False``, or the schema
        is newer than this driveid.

    Examples
    --------
    >>> import tempfile, pathlib
    >>> folder = pathlib.Path(tempfile.mkdtemp())
    >>> cat = Catalog(folder / "plant.sqlite")
    >>> result = {"schema": "driveid-result/1", "method": "logdec-lsq",
    ...           "inputs": [{"path": "run.csv", "sha256": "ab" * 32}],
    ...           "parameters": {"K": {"value": 16.0, "stderr": 0.1, "unit": "N·m/rad"}}}
    >>> cat.add_result(result, machine="m1", axis="x", measured_at="2026-03-01").created
    True
    >>> cat.add_result(result, machine="m1", axis="x", measured_at="2026-03-01").created
    False
    >>> [e.parameters["K"].value for e in cat.entries()]
    [16.0]
    >>> cat.close()
    """

    def __init__(self, catalog: str | Path | None = None, *, create: bool = True) -> None:
        self.url = catalog_url(catalog)
        if self.url.startswith("sqlite:///") and not create:
            path = Path(self.url[len("sqlite:///"):])
            if not path.is_file():
                raise ConfigError(
                    f"no catalogue at {path}; check the path, or add an entry first "
                    "(driveid catalog add) to create it")
        if self.url.startswith("sqlite:///"):
            _sqlite.check_sqlite_file(Path(self.url[len("sqlite:///"):]))
        kwargs: dict[str, Any] = {"future": True}
        if self.url.startswith("sqlite"):
            # several processes may write (fleet runs): wait for the lock, don't fail
            kwargs["connect_args"] = {"timeout": _sqlite.LOCK_WAIT}
        try:
            self.engine = sa.create_engine(self.url, **kwargs)
        except (sa.exc.ArgumentError, sa.exc.NoSuchModuleError, ImportError) as exc:
            raise ConfigError(f"cannot open catalogue {catalog!r}: {exc}") from None
        if self.url.startswith("sqlite"):
            sa.event.listen(self.engine, "connect", _sqlite.sqlite_pragmas)
            sa.event.listen(self.engine, "handle_error", _sqlite.sqlite_locked)
        try:
            self.schema_version = self._migrate()
        except sa.exc.OperationalError as exc:
            self.engine.dispose()
            raise ConfigError(
                f"cannot open catalogue {self.url}: {exc.orig}; check the path or URL, "
                "the server and the credentials") from None
        except sa.exc.DatabaseError as exc:  # an existing file that is no database (issue 28)
            self.engine.dispose()
            raise ConfigError(
                f"cannot open catalogue {self.url}: {exc.orig}; that file is not a driveid "
                "catalogue (a SQLite database): name another file (--catalog NEW.sqlite) "
                "or move this one away") from None

    def __enter__(self) -> Catalog:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def close(self) -> None:
        """Release the database connections."""
        self.engine.dispose()

    def __repr__(self) -> str:
        return f"Catalog({self.engine.url.render_as_string(hide_password=True)!r})"

    # -- schema -----------------------------------------------------------------------
    def _migrate(self) -> int:
        for attempt in range(5):
            try:
                return self._migrate_once()
            except (sa.exc.OperationalError, sa.exc.ProgrammingError,
                    sa.exc.IntegrityError):
                # another process is creating or migrating the same catalogue: wait, re-read
                if attempt == 4:
                    raise
                time.sleep(0.2 * (attempt + 1))
        raise AssertionError("unreachable")

    def _migrate_once(self) -> int:
        with self.engine.begin() as conn:
            inspector = sa.inspect(conn)
            if not inspector.has_table("schema_version"):
                if inspector.has_table("entries") or (
                        self.url.startswith("sqlite") and inspector.get_table_names()):
                    # another application's SQLite file: never add our tables to it
                    raise ConfigError(
                        f"{self.url} holds tables but no schema_version table: not a "
                        "driveid catalogue; name another file or database")
                S.schema_version.create(conn)
                conn.execute(S.schema_version.insert().values(version=0))
            version = conn.execute(sa.select(S.schema_version.c.version)).scalar_one()
            if version > S.SCHEMA_VERSION:
                raise ConfigError(
                    f"catalogue schema version {version} is newer than this driveid reads "
                    f"({S.SCHEMA_VERSION}); upgrade driveid")
            for step in range(version, S.SCHEMA_VERSION):
                S.MIGRATIONS[step](conn)
                conn.execute(S.schema_version.update().values(version=step + 1))
        return S.SCHEMA_VERSION

    # -- writing ----------------------------------------------------------------------
    def add_result(self, result: Mapping[str, Any], *, machine: str, axis: str,
                   measured_at: str | dt.datetime | None = None,
                   machine_type: str | None = None) -> AddOutcome:
        """Catalogue one identification result (the ``driveid-result/1`` JSON schema).

        Parameters
        ----------
        result : mapping
            ``{"driveid", "schema", "command", "inputs", "method", "parameters",
            "covariance", "diagnostics", "warnings"}``; ``parameters`` maps a name to
            ``{"value", "stderr", "unit", "fixed"}`` (null for a missing number).
        machine, axis : str
            Where the record was measured.
        measured_at : str or datetime, optional
            ISO 8601 time of the measurement (default: now, UTC).
        machine_type : str, optional
            Machine type, for the blueprint (:mod:`driveid.health`).

        Returns
        -------
        AddOutcome
            The entry id and whether it was new.

        Raises
        ------
        FileFormatError
            If ``result`` is not in the result schema, or a parameter's value or standard
            error is NaN or infinite (not null).
        """
        return self._insert(**self._result_row(result, machine=machine, axis=axis,
                                               measured_at=measured_at,
                                               machine_type=machine_type))

    def add_failure(self, *, inputs: Sequence[Mapping[str, Any]], method: str, error: str,
                    machine: str, axis: str, measured_at: str | dt.datetime | None = None,
                    machine_type: str | None = None, command: Sequence[str] = (),
                    driveid_version: str | None = None) -> AddOutcome:
        """Catalogue an identification that failed, with its error message.

        Parameters
        ----------
        inputs : sequence of mapping
            Provenance of the inputs (at least ``path`` and ``sha256``).
        method : str
            The method that was asked for.
        error : str
            The error message (what the user would have seen).
        machine, axis : str
            Where the record was measured.
        measured_at : str or datetime, optional
            ISO 8601 time of the measurement (default: now, UTC).
        machine_type : str, optional
            Machine type.
        command : sequence of str
            The command line.
        driveid_version : str, optional
            Version of driveid that tried.

        Returns
        -------
        AddOutcome
            The entry id and whether it was new.
        """
        return self._insert(**self._failure_row(
            inputs=inputs, method=method, error=error, machine=machine, axis=axis,
            measured_at=measured_at, machine_type=machine_type, command=command,
            driveid_version=driveid_version))

    def add_many(self, items: Sequence[Mapping[str, Any]]) -> list[AddOutcome]:
        """Catalogue several results and failures in one transaction (fleet runs).

        Parameters
        ----------
        items : sequence of mapping
            Each either ``{"result": <result dict>, "machine", "axis", "measured_at",
            "machine_type"}`` (as :meth:`add_result`) or ``{"failure": {...}}`` with the
            keywords of :meth:`add_failure`.

        Returns
        -------
        list of AddOutcome
            One per item, in order.
        """
        rows = []
        for item in items:
            if "failure" in item:
                rows.append(self._failure_row(**item["failure"]))
            else:
                rest = {k: v for k, v in item.items() if k != "result"}
                rows.append(self._result_row(item["result"], **rest))
        try:
            with self.engine.begin() as conn:
                return [self._write(conn, row) for row in rows]
        except sa.exc.IntegrityError:
            # a concurrent writer inserted one of the keys first: one transaction each
            outcomes = []
            for row in rows:
                try:
                    with self.engine.begin() as conn:
                        outcomes.append(self._write(conn, row))
                except sa.exc.IntegrityError:
                    outcomes.append(AddOutcome(self._id_of(row["key"]), False, row["key"]))
            return outcomes

    def _result_row(self, result, *, machine, axis, measured_at=None, machine_type=None):
        _sqlite.check_names(machine, axis)
        method, params, cov = _parse_result(result)
        inputs = [dict(i) for i in result.get("inputs") or []]
        key = entry_key([str(i.get("sha256") or "") for i in inputs], method,
                        fallback=result)
        return dict(
            key=key, machine=machine, axis=axis, machine_type=machine_type,
            measured_at=parse_time(measured_at), method=method, status="ok", error=None,
            version=result.get("driveid"), command=result.get("command") or [],
            inputs=inputs, params=params, cov=cov,
            diagnostics=result.get("diagnostics") or {},
            warnings=[str(w) for w in result.get("warnings") or []])

    def _failure_row(self, *, inputs, method, error, machine, axis, measured_at=None,
                     machine_type=None, command=(), driveid_version=None):
        _sqlite.check_names(machine, axis)
        inputs = [dict(i) for i in inputs]
        key = entry_key([str(i.get("sha256") or "") for i in inputs], method,
                        fallback={"error": error})
        return dict(
            key=key, machine=machine, axis=axis, machine_type=machine_type,
            measured_at=parse_time(measured_at), method=method, status="failed",
            error=str(error), version=driveid_version, command=list(command), inputs=inputs,
            params={}, cov=None, diagnostics={}, warnings=[])

    def _insert(self, **row: Any) -> AddOutcome:
        try:
            with self.engine.begin() as conn:
                return self._write(conn, row)
        except sa.exc.IntegrityError:
            # a concurrent writer (a retried fleet task) inserted the same key first
            existing = self._id_of(row["key"])
            if existing is None:
                raise
            return AddOutcome(existing, False, row["key"])

    @staticmethod
    def _write(conn: sa.Connection, row: Mapping[str, Any]) -> AddOutcome:
        key = row["key"]
        existing = conn.execute(sa.select(S.entries.c.id).where(S.entries.c.entry_key == key)
                                ).scalar_one_or_none()
        if existing is not None:
            return AddOutcome(int(existing), False, key)
        values = {
            "entry_key": key, "machine": str(row["machine"]), "axis": str(row["axis"]),
            "machine_type": row["machine_type"], "measured_at": row["measured_at"],
            "added_at": parse_time(None), "method": row["method"], "status": row["status"],
            "error": row["error"],
            "driveid_version": None if row["version"] is None else str(row["version"]),
            "command": json.dumps(list(row["command"])),
            "diagnostics": json.dumps(to_jsonable(dict(row["diagnostics"]))),
            "warnings": json.dumps(list(row["warnings"])),
        }
        entry_id = conn.execute(
            S.entries.insert().values(**values).returning(S.entries.c.id)).scalar_one()
        if row["inputs"]:
            conn.execute(S.inputs.insert(), [
                {"entry_id": entry_id, "position": k, "sha256": str(i.get("sha256") or ""),
                 "path": None if i.get("path") is None else str(i["path"]),
                 "rows": i.get("rows"),
                 "details": json.dumps(to_jsonable(
                     {n: v for n, v in i.items() if n not in ("sha256", "path", "rows")}))}
                for k, i in enumerate(row["inputs"])])
        if row["params"]:
            conn.execute(S.parameters.insert(), [
                {"entry_id": entry_id, "name": n, "value": _nan_to_none(p.value),
                 # a given parameter has no standard error: null, never 0 (issue 26)
                 "stderr": None if p.fixed else _nan_to_none(p.stderr), "unit": p.unit,
                 "fixed": p.fixed}
                for n, p in row["params"].items()])
        if row["cov"] is not None:
            names, matrix = row["cov"]
            conn.execute(S.covariance.insert(), [
                {"entry_id": entry_id, "row_name": a, "col_name": b,
                 "value": _nan_to_none(matrix[i][j])}
                for i, a in enumerate(names) for j, b in enumerate(names)])
        return AddOutcome(int(entry_id), True, key)

    def _id_of(self, key: str) -> int | None:
        with self.engine.connect() as conn:
            found = conn.execute(sa.select(S.entries.c.id).where(S.entries.c.entry_key == key)
                                 ).scalar_one_or_none()
        return None if found is None else int(found)

    # -- reading ----------------------------------------------------------------------
    def known_hashes(self, hashes: Iterable[str]) -> set[str]:
        """Return those of ``hashes`` that are inputs of a catalogued entry (ok or failed).

        Parameters
        ----------
        hashes : iterable of str
            SHA-256 of input files.

        Returns
        -------
        set of str
            The hashes already catalogued (a fleet run skips their files).
        """
        wanted = list(dict.fromkeys(hashes))
        found: set[str] = set()
        with self.engine.connect() as conn:
            for start in range(0, len(wanted), 500):
                chunk = wanted[start:start + 500]
                found.update(conn.execute(sa.select(S.inputs.c.sha256).where(
                    S.inputs.c.sha256.in_(chunk))).scalars())
        return found

    def entries(self, *, machine: str | None = None, axis: str | None = None,
                machine_type: str | None = None, status: str | None = None,
                since: str | dt.datetime | None = None,
                until: str | dt.datetime | None = None) -> list[CatalogEntry]:
        """Return the entries that match, ordered by machine, axis and measurement time.

        Parameters
        ----------
        machine, axis, machine_type : str, optional
            Keep only these.
        status : {"ok", "failed"}, optional
            Keep only successes or failures.
        since, until : str or datetime, optional
            Keep measurements in ``[since, until]`` (ISO 8601, UTC).

        Returns
        -------
        list of CatalogEntry
            With parameters, covariance and inputs.
        """
        e = S.entries
        query = sa.select(e).order_by(e.c.machine, e.c.axis, e.c.measured_at, e.c.id)
        for column, value in ((e.c.machine, machine), (e.c.axis, axis),
                              (e.c.machine_type, machine_type), (e.c.status, status)):
            if value is not None:
                query = query.where(column == value)
        if since is not None:
            query = query.where(e.c.measured_at >= parse_time(since))
        if until is not None:
            query = query.where(e.c.measured_at <= parse_time(until))
        with self.engine.connect() as conn:
            rows = conn.execute(query).mappings().all()
            ids = [r["id"] for r in rows]
            params: dict[int, dict[str, Parameter]] = {i: {} for i in ids}
            covs: dict[int, list[tuple[str, str, float]]] = {}
            ins: dict[int, list[dict[str, Any]]] = {i: [] for i in ids}
            for start in range(0, len(ids), 500):
                chunk = ids[start:start + 500]
                for p in conn.execute(sa.select(S.parameters).where(
                        S.parameters.c.entry_id.in_(chunk))).mappings():
                    params[p["entry_id"]][p["name"]] = Parameter(
                        _none_to_nan(p["value"]), _none_to_nan(p["stderr"]), p["unit"] or "-",
                        bool(p["fixed"]))
                for c in conn.execute(sa.select(S.covariance).where(
                        S.covariance.c.entry_id.in_(chunk))).mappings():
                    covs.setdefault(c["entry_id"], []).append(
                        (c["row_name"], c["col_name"], _none_to_nan(c["value"])))
                for i in conn.execute(sa.select(S.inputs).where(
                        S.inputs.c.entry_id.in_(chunk)).order_by(S.inputs.c.position)
                        ).mappings():
                    ins[i["entry_id"]].append({"path": i["path"], "sha256": i["sha256"],
                                               "rows": i["rows"],
                                               **json.loads(i["details"] or "{}")})
        return [CatalogEntry(
            id=r["id"], key=r["entry_key"], machine=r["machine"], axis=r["axis"],
            machine_type=r["machine_type"], measured_at=r["measured_at"], method=r["method"],
            status=r["status"], error=r["error"], driveid_version=r["driveid_version"],
            parameters=params[r["id"]], covariance=_matrix(covs.get(r["id"])),
            inputs=tuple(ins[r["id"]]), command=json.loads(r["command"] or "[]"),
            warnings=tuple(json.loads(r["warnings"] or "[]")),
            diagnostics=json.loads(r["diagnostics"] or "{}"),
        ) for r in rows]

    def count(self) -> int:
        """Return the number of entries (ok and failed)."""
        with self.engine.connect() as conn:
            return int(conn.execute(sa.select(sa.func.count()).select_from(S.entries)
                                    ).scalar_one())

    def to_frame(self, **filters: Any) -> Any:
        """Return the catalogue as a long pandas DataFrame: one row per entry and parameter.

        Parameters
        ----------
        **filters : Any
            Passed to :meth:`entries` (``machine``, ``axis``, ``machine_type``, ``status``,
            ``since``, ``until``).

        Returns
        -------
        pandas.DataFrame
            Columns ``entry_id, machine, axis, machine_type, measured_at, method, status,
            error, driveid_version, inputs, parameter, value, stderr, unit, fixed``; a
            failure has one row with an empty ``parameter``.
        """
        import pandas as pd

        rows = []
        for e in self.entries(**filters):
            base = {"entry_id": e.id, "machine": e.machine, "axis": e.axis,
                    "machine_type": e.machine_type, "measured_at": e.measured_at,
                    "method": e.method, "status": e.status, "error": e.error,
                    "driveid_version": e.driveid_version,
                    "inputs": ";".join(str(i.get("path")) for i in e.inputs)}
            if not e.parameters:
                rows.append({**base, "parameter": None, "value": math.nan,
                             "stderr": math.nan, "unit": None, "fixed": None})
            for name, p in e.parameters.items():
                rows.append({**base, "parameter": name, "value": p.value, "stderr": p.stderr,
                             "unit": p.unit, "fixed": p.fixed})
        columns = ["entry_id", "machine", "axis", "machine_type", "measured_at", "method",
                   "status", "error", "driveid_version", "inputs", "parameter", "value",
                   "stderr", "unit", "fixed"]
        return pd.DataFrame(rows, columns=columns)


def _parse_result(result: Mapping[str, Any]):
    if not isinstance(result, Mapping):
        raise FileFormatError(
            f"a result must be a JSON object in schema {RESULT_SCHEMA}; got "
            f"{type(result).__name__}")
    schema = result.get("schema", RESULT_SCHEMA)
    if schema != RESULT_SCHEMA:  # a new version means readers break (docs/result-schema.md)
        newer = str(schema).startswith("driveid-result/")
        raise FileFormatError(
            f"result schema must be {RESULT_SCHEMA}; got {schema!r}: "
            + ("a schema this driveid does not know (a newer driveid wrote it?): catalogue it "
               "with that version, or write the result again with this one's --json"
               if newer else "write the result with 'driveid identify ... --json'"))
    method = result.get("method")
    raw = result.get("parameters")
    if not method or not isinstance(raw, Mapping):
        raise FileFormatError(
            "a result needs 'method' and a 'parameters' object {name: {value, stderr, unit}};"
            f" got keys {sorted(result)}")
    params: dict[str, Parameter] = {}
    for name, p in raw.items():
        if not isinstance(p, Mapping) or "value" not in p:
            raise FileFormatError(
                f"parameter {name!r} must be {{'value', 'stderr', 'unit', 'fixed'}}; got {p!r}")
        try:
            params[str(name)] = Parameter(_none_to_nan(p.get("value")),
                                          _none_to_nan(p.get("stderr")),
                                          str(p.get("unit") or "-"), bool(p.get("fixed", False)))
        except (TypeError, ValueError):
            raise FileFormatError(f"parameter {name!r} has a non-numeric value: {p!r}") from None
        for what in ("value", "stderr"):  # issue 28: NaN and 1e999 (inf) were catalogued
            problem = p.get(what) is not None and non_finite_problem(
                what, getattr(params[str(name)], what))
            if problem:
                raise FileFormatError(f"parameter {name!r}: {problem}; correct the file or "
                                      "write it again with --json")
    cov = None
    raw_cov = result.get("covariance")
    if raw_cov:
        names = [str(n) for n in raw_cov.get("names", [])]
        matrix = raw_cov.get("matrix")
        if (matrix is None or len(matrix) != len(names)
                or any(len(row) != len(names) for row in matrix)):
            raise FileFormatError(
                f"covariance matrix must be {len(names)}×{len(names)} for names {names}")
        cov = (names, [[_none_to_nan(v) for v in row] for row in matrix])
    return str(method), params, cov


def _matrix(cells):
    if not cells:
        return None
    names = list(dict.fromkeys(r for r, _, _ in cells))
    index = {n: k for k, n in enumerate(names)}
    matrix = [[math.nan] * len(names) for _ in names]
    for r, c, v in cells:
        if c in index:
            matrix[index[r]][index[c]] = v
    return {"names": names, "matrix": matrix}


def _none_to_nan(value: Any) -> float:
    return math.nan if value is None else float(value)


def _nan_to_none(value: float) -> float | None:
    value = float(value)
    return value if math.isfinite(value) else None
