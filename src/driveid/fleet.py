"""Fleet identification on Dask: one task per record, results into the catalogue.

``identify_many`` finds the records (paths or glob patterns), skips those whose SHA-256 is
already catalogued (resumable), and submits one task per record to a Dask cluster — a
local one by default (two single-threaded worker processes on the loopback interface), or
an existing scheduler. Each task reads its own file (paths are shipped, not arrays, so the
client's memory does not grow with the fleet) and returns a small result in the
``driveid-result/1`` schema, or the error that stopped it. The client writes each result to
the catalogue as it arrives: a bad file becomes a catalogued failure and the rest goes on;
a task lost with a killed worker is re-run by the scheduler (and ``retries`` re-runs a task
that raised), and since entries are keyed by the input's hash nothing is catalogued twice.

Machine, axis and measurement time come from the path, by a pattern matched against its
last components: the default ``{machine}/{axis}/{time}`` reads
``plant/m003/x/2026-03-01.csv`` as machine ``m003``, axis ``x``, measured 2026-03-01 (a file
name that is not ISO 8601 leaves the time to the file's modification time).
"""

from __future__ import annotations

import datetime as dt
import glob
import inspect
import itertools
import math
import os
import re
import time
import warnings
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from driveid.catalog import Catalog, file_sha256, parse_time
from driveid.errors import ConfigError

__all__ = ["DEFAULT_PATH_PATTERN", "METHODS", "FleetSummary", "identify_many", "parse_path",
           "identify_file", "identify_files"]

#: How machine, axis and time are read from a record's path (its last components).
DEFAULT_PATH_PATTERN = "{machine}/{axis}/{time}"
#: Methods a fleet run can use.
METHODS = ("logdec", "output-error", "auto")
#: How long a given scheduler address is tried before the run gives up [s]: Dask waits 30 s
#: by default, which a mistyped or stopped scheduler cost every time (issue 28); a
#: scheduler that answers at all does so within milliseconds on a LAN.
SCHEDULER_TIMEOUT = 10.0
_FIELDS = ("machine", "axis", "time", "type")


@dataclass(frozen=True)
class FleetSummary:
    """What a fleet run did.

    Attributes
    ----------
    n_found : int
        Records found.
    n_skipped : int
        Already catalogued (by hash), or the same content twice.
    n_ok, n_failed : int
        Identified and catalogued; failed and catalogued with their error.
    n_duplicates : int
        Results whose key was already in the catalogue when they arrived.
    elapsed : float
        Wall time of the identification, without cluster start-up [s].
    n_workers : int
        Workers of the cluster.
    cpu_seconds : float
        Processor time of all tasks [s]: the per-record cost, independent of machine load.
    n_tasks : int
        Dask tasks submitted (records go in batches, see ``identify_many(batch_size=)``).
    """

    n_found: int
    n_skipped: int
    n_ok: int
    n_failed: int
    n_duplicates: int
    elapsed: float
    n_workers: int
    cpu_seconds: float = 0.0
    n_tasks: int = 0

    @property
    def records_per_second(self) -> float:
        """Throughput [records/s]."""
        done = self.n_ok + self.n_failed
        return done / self.elapsed if self.elapsed > 0 else float("nan")

    @property
    def cpu_seconds_per_record(self) -> float:
        """Mean processor time of one record's task [s]."""
        done = self.n_ok + self.n_failed
        return self.cpu_seconds / done if done else float("nan")


def parse_path(path: str | Path, pattern: str = DEFAULT_PATH_PATTERN) -> dict[str, Any]:
    """Read machine, axis, time and machine type from a record's path.

    Parameters
    ----------
    path : str or Path
        The record file.
    pattern : str
        ``/``-separated components matched against the path's last components (the last
        one without its suffix); placeholders ``{machine}``, ``{axis}``, ``{time}``,
        ``{type}`` and ``{*}`` (ignored) each match text without ``/``.

    Returns
    -------
    dict
        ``machine``, ``axis``, ``machine_type`` (or None) and ``measured_at`` (naive UTC
        datetime; from ``{time}`` if ISO 8601, else the file's modification time).

    Raises
    ------
    ConfigError
        If the path does not match, or the pattern lacks ``{machine}`` or ``{axis}``.

    Examples
    --------
    >>> parse_path("plant/m003/x/2026-03-01.csv")["machine"]
    'm003'
    >>> parse_path("line2/m003/x/2026-03-01.csv", "{type}/{machine}/{axis}/{time}")["machine_type"]
    'line2'
    """
    parts = pattern.strip("/").split("/")
    if "{machine}" not in pattern or "{axis}" not in pattern:
        raise ConfigError(f"path pattern must contain {{machine}} and {{axis}}, e.g. "
                          f"{DEFAULT_PATH_PATTERN}; got {pattern!r}")
    path = Path(path)
    components = list(path.parts[:-1]) + [path.stem]
    if len(components) < len(parts):
        raise ConfigError(f"path {path} has fewer components than pattern {pattern!r}")
    found: dict[str, str] = {}
    for part, text in zip(parts, components[-len(parts):], strict=True):
        pieces = re.split(r"\{(\w+|\*)\}", part)
        regex = "^" + "".join(re.escape(x) if k % 2 == 0 else _group(x)
                              for k, x in enumerate(pieces)) + "$"
        match = re.match(regex, text)
        if match is None:
            raise ConfigError(f"path {path} does not match pattern {pattern!r} at {text!r}; "
                              "set --machine-from-path, e.g. '{machine}/{axis}/{time}'")
        found.update({k: v for k, v in match.groupdict().items() if v is not None})
    measured = None
    if "time" in found:
        try:
            measured = parse_time(found["time"])
        except ConfigError:
            measured = None
    if measured is None:
        stamp = path.stat().st_mtime if path.exists() else time.time()
        measured = dt.datetime.fromtimestamp(stamp, dt.UTC).replace(tzinfo=None, microsecond=0)
    return {"machine": found["machine"], "axis": found["axis"],
            "machine_type": found.get("type"), "measured_at": measured}


def _group(name: str) -> str:
    if name == "*":
        return "[^/]*?"
    if name not in _FIELDS:
        raise ConfigError(f"unknown placeholder {{{name}}} in path pattern; use "
                          f"{', '.join('{' + f + '}' for f in _FIELDS)} or {{*}}")
    return f"(?P<{name}>[^/]+?)"


def identify_file(path: str | Path, *, method: str = "output-error",
                  method_options: Mapping[str, Any] | None = None,
                  record_options: Mapping[str, Any] | None = None,
                  sha256: str | None = None) -> dict[str, Any]:
    """Identify one record file; never raise for a bad file (the fleet task).

    Parameters
    ----------
    path : str or Path
        The record.
    method : {"output-error", "logdec", "auto"}
        Estimator: the whole-record output-error fit (default, as ``identify logdec``), the
        peak log decrement, or ``auto`` (:func:`driveid.identify_auto`: recognise each
        record's test and run what applies; ``diagnostics["auto"]`` says what and why).
    method_options : mapping, optional
        Keywords of the estimator (e.g. ``{"mass": 1.0}``).
    record_options : mapping, optional
        Keywords of :func:`driveid.io.read_record`.
    sha256 : str, optional
        The file's SHA-256 when the caller has it already (the fleet client hashes every
        file to skip catalogued ones): the task does not read the file twice.

    Returns
    -------
    dict
        ``{"status": "ok", "result": <driveid-result/1 dict>}`` or
        ``{"status": "failed", "error": str, "inputs": [...], "method": str}``, both with
        ``cpu_seconds``, the task's processor time [s] (read, hash, fit).
    """
    import driveid
    from driveid.io import read_record

    path = Path(path)
    inputs = [{"path": str(path), "sha256": None}]
    cpu_start = time.process_time()
    try:
        inputs[0]["sha256"] = sha256 or file_sha256(path)
        estimator = _estimator(method)
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            record = read_record(path, **dict(record_options or {}))
            est = estimator(record, **dict(method_options or {}))
        inputs[0].update({"rows": record.n, "columns": list(record.columns),
                          "units": dict(record.units)})
    except Exception as exc:  # noqa: BLE001 — a fleet task isolates every failure of a file
        return {"status": "failed", "method": method, "inputs": inputs,
                "error": f"{type(exc).__name__}: {exc}",
                "cpu_seconds": time.process_time() - cpu_start}
    messages = list(est.warnings) + [str(w.message) for w in caught]
    # a given parameter has no standard error: null, as in the result schema (issue 26)
    params = {n: {"value": p.value, "stderr": None if getattr(p, "fixed", False) else p.stderr,
                  "unit": p.unit, "fixed": bool(getattr(p, "fixed", False))}
              for n, p in est.params.items()}
    cov = None
    if est.covariance is not None:
        cov = {"names": list(est.covariance["names"]),
               "matrix": [list(map(float, row)) for row in est.covariance["matrix"]]}
    from driveid._json import to_jsonable

    result = {"driveid": driveid.__version__, "schema": "driveid-result/1",
              "command": ["driveid.fleet.identify_many", method], "inputs": inputs,
              "method": est.method, "parameters": params, "covariance": cov,
              "diagnostics": dict(est.diagnostics), "warnings": messages}
    return {"status": "ok", "result": to_jsonable(result),
            "cpu_seconds": time.process_time() - cpu_start}


def identify_files(paths: Sequence[str | Path], *, method: str = "output-error",
                   method_options: Mapping[str, Any] | None = None,
                   record_options: Mapping[str, Any] | None = None,
                   sha256: Sequence[str | None] | None = None) -> list[dict[str, Any]]:
    """Identify several record files in one task (a fleet batch); never raise for a bad file.

    Parameters
    ----------
    paths : sequence of str or Path
        The records.
    method : {"output-error", "logdec", "auto"}
        Estimator.
    method_options : mapping, optional
        Keywords of the estimator (e.g. ``{"mass": 1.0}``).
    record_options : mapping, optional
        Keywords of :func:`driveid.io.read_record`.
    sha256 : sequence of str, optional
        The files' SHA-256, one per path, when known.

    Returns
    -------
    list of dict
        One :func:`identify_file` outcome per path, in order.
    """
    hashes = list(sha256) if sha256 is not None else [None] * len(paths)
    return [identify_file(path, method=method, method_options=method_options,
                          record_options=record_options, sha256=sha)
            for path, sha in zip(paths, hashes, strict=True)]


def _estimator(method: str):
    if method == "logdec":
        from driveid.identify.free_decay.logdec import estimate_log_decrement

        return estimate_log_decrement
    if method == "auto":
        from driveid.identify.auto import identify_auto

        return identify_auto
    if method == "output-error":
        try:
            from driveid.identify.free_decay.output_error import estimate_output_error
        except ImportError:
            raise ConfigError("method 'output-error' is not available in this driveid; use "
                              "--method logdec") from None
        return estimate_output_error
    raise ConfigError(f"method must be one of {METHODS}; got {method!r}")


def _expand(paths: str | Path | Iterable[str | Path]) -> list[Path]:
    if isinstance(paths, (str, Path)):
        paths = [paths]
    found: list[Path] = []
    for item in paths:
        text = str(item)
        if any(c in text for c in "*?["):
            found.extend(Path(p) for p in sorted(glob.glob(text, recursive=True))
                         if os.path.isfile(p))
        else:
            if not Path(text).is_file():
                from driveid.io.tables import refuse_non_file

                refuse_non_file(Path(text))
            found.append(Path(text))
    return list(dict.fromkeys(found))


def identify_many(paths: str | Path | Sequence[str | Path], *, method: str = "output-error",
                  method_options: Mapping[str, Any] | None = None,
                  record_options: Mapping[str, Any] | Any | None = None,
                  catalog: str | Path | Catalog | None = None, client: Any = None,
                  scheduler: str | None = None, n_workers: int = 2,
                  path_pattern: str = DEFAULT_PATH_PATTERN, machine_type: str | None = None,
                  retries: int = 2, progress: bool = True,
                  batch_size: int | None = None,
                  scheduler_timeout: float = SCHEDULER_TIMEOUT) -> FleetSummary:
    """Identify every record of a fleet on Dask and catalogue the results.

    Parameters
    ----------
    paths : str or Path or sequence
        Record files or glob patterns (``'traces/**/*.csv'``, recursive).
    method : {"output-error", "logdec", "auto"}
        Estimator: the whole-record output-error fit (default, the one ``identify logdec``
        runs; near the Cramér-Rao bound), the peak log decrement (``logdec``) or ``auto``
        (each record's test shape recognised, see :func:`driveid.identify_auto`).
    method_options : mapping, optional
        Estimator keywords, e.g. ``{"mass": 1.0}`` [kg or kg·m²]; checked before submitting.
    record_options : mapping or RecordOptions, optional
        Keywords of :func:`driveid.io.read_record` (or the CLI's ``RecordOptions``).
    catalog : str or Path or Catalog, optional
        Catalogue (file or URL); default ``./driveid-catalog.sqlite``.
    client : distributed.Client, optional
        An existing client; its cluster is used and left running.
    scheduler : str, optional
        Address of an existing scheduler, ``tcp://host:port`` (ignored with ``client``).
    n_workers : int
        Workers of the local cluster started when neither ``client`` nor ``scheduler`` is
        given (single-threaded processes on 127.0.0.1).
    path_pattern : str
        How machine, axis and time are read from a path (:func:`parse_path`).
    machine_type : str, optional
        Machine type of every record (a ``{type}`` in the pattern wins).
    retries : int
        Re-runs of a task that raised (workers lost are re-run by the scheduler).
    progress : bool
        Show a progress bar on stderr.
    batch_size : int, optional
        Records per Dask task [-]: each task costs the scheduler and the worker a few
        milliseconds whatever its size, so records travel in batches. Default: batches that
        shrink as the work runs out (each about 1/(2 x workers) of the records left, at most
        32, the last ones single records), so no worker waits long for the others at the end.
    scheduler_timeout : float
        How long to try reaching ``scheduler`` before giving up [s] (Dask's own default is
        30 s, which a mistyped address cost every time; issue 28).

    Returns
    -------
    FleetSummary
        Counts and throughput.

    Raises
    ------
    ConfigError
        No file found, an unknown method or estimator keyword, a path that does not
        match the pattern, a ``batch_size`` below 1, or a ``scheduler_timeout`` that is not
        a positive number of seconds.
    FileNotFoundError
        A named file (not a pattern) that does not exist.
    """
    files = _expand(paths)
    if not files:
        raise ConfigError(f"no record file matches {paths!r}; check the pattern (quote it "
                          "in the shell so that ** reaches driveid)")
    if batch_size is not None and not (isinstance(batch_size, int) and batch_size >= 1):
        raise ConfigError(f"batch_size must be a whole number of records >= 1 (CLI: "
                          f"--batch-size); got {batch_size!r}")
    if scheduler is not None and not (isinstance(scheduler_timeout, (int, float))
                                      and math.isfinite(scheduler_timeout)
                                      and scheduler_timeout > 0):
        # checked before the files are hashed, not when the client starts
        raise ConfigError(f"the scheduler timeout must be a positive number of seconds "
                          f"(CLI --scheduler-timeout); got {scheduler_timeout!r}")
    estimator = _estimator(method)
    options = dict(method_options or {})
    try:
        inspect.signature(estimator).bind(None, **options)
    except TypeError as exc:
        raise ConfigError(f"method {method!r} does not take {sorted(options)}: {exc}") from None
    if record_options is not None and hasattr(record_options, "read_kwargs"):
        record_options = record_options.read_kwargs()
    record_kwargs = dict(record_options or {})
    located = {f: parse_path(f, path_pattern) for f in files}
    owns_catalog = not isinstance(catalog, Catalog)
    cat = Catalog(catalog) if owns_catalog else catalog
    owned: list[Any] = []
    try:
        hashes = {f: file_sha256(f) for f in files}
        known = cat.known_hashes(hashes.values())
        todo: dict[str, Path] = {}
        for f in files:
            if hashes[f] not in known and hashes[f] not in todo:
                todo[hashes[f]] = f
        n_skipped = len(files) - len(todo)
        counts: dict[str, Any] = {"ok": 0, "failed": 0, "duplicates": 0, "cpu": 0.0,
                                  "tasks": 0}
        workers, elapsed = 0, 0.0
        if todo:
            if client is None:
                client = _start_client(scheduler, n_workers, owned, scheduler_timeout)
            workers = len(client.scheduler_info().get("workers", {}))
            client.run(_warm_worker, method)  # import (and compile) before the clock starts
            sizes = _batch_sizes(len(todo), workers, batch_size)
            start = time.perf_counter()
            counts = _run(client, todo, located, cat, method, options, record_kwargs,
                          machine_type, retries, progress, sizes)
            elapsed = time.perf_counter() - start
    finally:
        for thing in reversed(owned):
            thing.close()
        if owns_catalog:
            cat.close()
    return FleetSummary(n_found=len(files), n_skipped=n_skipped, n_ok=counts["ok"],
                        n_failed=counts["failed"], n_duplicates=counts["duplicates"],
                        elapsed=elapsed, n_workers=workers, cpu_seconds=counts["cpu"],
                        n_tasks=counts["tasks"])


def _start_client(scheduler: str | None, n_workers: int, owned: list[Any],
                  timeout: float = SCHEDULER_TIMEOUT) -> Any:
    from distributed import Client, LocalCluster

    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=f"{float(timeout)}s")
        except (OSError, TimeoutError, ValueError, MemoryError) as exc:
            # issue 28: a service that is no Dask scheduler sent bytes read as a 3 EiB frame
            # length, and the line said "out of memory"; a dead address timed out in Dask
            raise ConfigError(
                f"cannot use the Dask scheduler at {scheduler}: {type(exc).__name__}: "
                f"{str(exc)[:200]}; check the address and that a Dask scheduler (not another "
                "service) listens there (a slow network: a longer --scheduler-timeout), or "
                "leave --scheduler out for a local cluster"
            ) from None
        owned.append(client)
        return client
    if n_workers < 1:
        raise ConfigError(f"n_workers must be >= 1; got {n_workers}")
    import dask

    # the workers' statistical profiler samples the task thread's stack every 10 ms and takes
    # the GIL from the fit each time; our own cluster runs without it (issue 28)
    with dask.config.set({"distributed.worker.profile.enabled": False}):
        cluster = LocalCluster(n_workers=n_workers, threads_per_worker=1, processes=True,
                               host="127.0.0.1", dashboard_address="127.0.0.1:0")
    owned.append(cluster)
    client = Client(cluster)
    owned.append(client)
    return client


#: Automatic batches: each holds about 1/(this x workers) of the records still to go ...
_GUIDED_SHARE = 2
#: ... and at most this many records (a batch lost with its worker is re-run whole).
_MAX_AUTO_BATCH = 32


def _batch_sizes(n_records: int, n_workers: int, batch_size: int | None) -> list[int]:
    """Return the records of each task, in submission order [-].

    A given ``batch_size`` is used throughout. Otherwise the sizes shrink as the work runs
    out (guided self-scheduling): each batch takes ``1 / (2 x workers)`` of the records left,
    capped at 32, down to single records, so the first tasks amortise the few milliseconds
    each costs and the last wave is one record deep — equal batches left 16 workers idle
    for up to a batch's time at the end (issue 28).

    Examples
    --------
    >>> _batch_sizes(10, 1, 4)
    [4, 4, 2]
    >>> _batch_sizes(20, 2, None)
    [5, 3, 3, 2, 1, 1, 1, 1, 1, 1, 1]
    """
    if batch_size is not None:
        return [min(batch_size, n_records - i) for i in range(0, n_records, batch_size)]
    sizes, left = [], n_records
    while left > 0:
        size = max(1, min(_MAX_AUTO_BATCH, left // (_GUIDED_SHARE * max(n_workers, 1))))
        sizes.append(size)
        left -= size
    return sizes


def _warm_worker(method: str) -> None:
    """Import what a task needs (the estimator, the reader's pandas) before the clock starts."""
    import pandas  # noqa: F401 — the reader imports it on the first record (0.2 s)

    import driveid._json  # noqa: F401
    import driveid.io  # noqa: F401

    _estimator(method)


class _CatalogWriter:
    """Write outcomes to the catalogue from a thread, in transactions of many records.

    The client thread only queues what arrives, so collecting results never waits for a
    commit (issue 28: the writes were on the critical path of every batch).
    """

    def __init__(self, cat: Catalog, counts: dict[str, Any]) -> None:
        import queue
        import threading

        self.cat, self.counts = cat, counts
        self.queue: queue.Queue = queue.Queue()
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._loop, name="driveid-catalog-writer",
                                       daemon=True)
        self.thread.start()

    def put(self, item: dict[str, Any]) -> None:
        if self.error is not None:
            raise self.error
        self.queue.put(item)

    def _loop(self) -> None:
        import queue

        done = False
        while not done:
            batch = [self.queue.get()]
            # gather what else is waiting (up to 0.2 s): one transaction per batch
            deadline = time.monotonic() + 0.2
            while len(batch) < 200:
                try:
                    batch.append(self.queue.get(timeout=max(0.0, deadline - time.monotonic())))
                except queue.Empty:
                    break
            if batch[-1] is None:
                batch.pop()
                done = True
            try:
                if batch and self.error is None:
                    for added in self.cat.add_many(batch):
                        self.counts["duplicates"] += 0 if added.created else 1
            except BaseException as exc:  # noqa: BLE001 — re-raised in the client thread
                self.error = exc

    def close(self) -> None:
        self.queue.put(None)
        self.thread.join()
        if self.error is not None:
            raise self.error


def _run(client, todo, located, cat, method, options, record_kwargs, machine_type, retries,
         progress, sizes) -> dict[str, Any]:
    import hashlib

    from distributed import as_completed
    from tqdm import tqdm

    import driveid

    futures = {}
    items = list(todo.items())
    starts = list(itertools.accumulate(sizes, initial=0))
    for i, j in itertools.pairwise(starts):
        chunk = items[i:j]
        key = hashlib.sha256("".join(sha for sha, _ in chunk).encode()).hexdigest()[:32]
        future = client.submit(identify_files, [str(path) for _, path in chunk], method=method,
                               method_options=options, record_options=record_kwargs,
                               sha256=[sha for sha, _ in chunk],
                               key=f"driveid-identify-{key}", retries=retries, pure=False)
        futures[future] = chunk
    counts: dict[str, Any] = {"ok": 0, "failed": 0, "duplicates": 0, "cpu": 0.0,
                              "tasks": len(futures)}
    writer = _CatalogWriter(cat, counts)
    try:
        with tqdm(total=len(items), disable=not progress, unit="record") as bar:
            for future in as_completed(list(futures)):
                chunk = futures.pop(future)
                try:
                    outcomes = future.result()
                except Exception as exc:  # noqa: BLE001 — a batch lost for good (KilledWorker)
                    outcomes = [{"status": "failed", "method": method,
                                 "inputs": [{"path": str(path), "sha256": sha}],
                                 "error": f"{type(exc).__name__}: {exc}"} for sha, path in chunk]
                future.release()
                for (_, path), outcome in zip(chunk, outcomes, strict=True):
                    where = located[path]
                    place = {"machine": where["machine"], "axis": where["axis"],
                             "measured_at": where["measured_at"],
                             "machine_type": where["machine_type"] or machine_type}
                    if outcome["status"] == "ok":
                        writer.put({"result": outcome["result"], **place})
                    else:
                        writer.put({"failure": {
                            "inputs": outcome["inputs"], "method": outcome["method"],
                            "error": outcome["error"], "driveid_version": driveid.__version__,
                            "command": ["driveid.fleet.identify_many", method], **place}})
                    counts[outcome["status"]] += 1
                    counts["cpu"] += outcome.get("cpu_seconds", 0.0)
                bar.update(len(chunk))
    finally:
        writer.close()
    return counts
