"""Consistency checks between what files say about themselves (issue 12).

* :func:`check_meta_units`: a CSV header's units and its ``# meta:`` units must agree (a
  header ``t [ms]`` under a meta that still says seconds once gave ω0 = 0.004 instead of 4).
* :func:`warn_duplicates`: the same file or run given twice shrinks the standard errors by
  √2 without adding information; say so.
* :func:`load_json`: JSON parsing that turns absurd nesting into a one-line error.
* :func:`check_allocation`, :func:`available_memory`: refuse a request whose arrays would
  not fit in memory before it is attempted (``--omega-c 1e9`` once tried 32 TiB).

Nothing here imports numpy at module level except for the array comparison; the checks are
cheap next to reading a record.
"""

from __future__ import annotations

import hashlib
import json
import math
import os
import sys
import warnings
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from driveid.errors import FileFormatError, ParameterError, RecordWarning

__all__ = [
    "MAX_CAMPAIGN_RUNS",
    "check_meta_units",
    "warn_duplicates",
    "duplicate_groups",
    "record_digest",
    "load_json",
    "available_memory",
    "check_allocation",
    "check_count",
    "check_disk",
    "format_bytes",
    "MAX_JSON_DEPTH",
]

#: Deepest nesting of JSON (manifests, ``# meta:`` lines, TOML-derived mappings) accepted.
MAX_JSON_DEPTH = 64


def _si(column: str, unit: str) -> tuple[str, float] | None:
    from driveid.io.units import UNIT_CONVERSIONS

    return UNIT_CONVERSIONS.get(column, {}).get(unit)


def check_meta_units(header_units: Mapping[str, str], meta_units: Mapping[str, Any],
                     source: str) -> None:
    """Refuse a file whose header units and ``# meta:`` units disagree.

    Two spellings of the same unit (``Nm`` and ``N·m``) agree; so does a column named in
    only one of the two.

    Parameters
    ----------
    header_units : mapping
        Record column (``t``, ``x``, ``u``, ``v``) -> unit written in the header.
    meta_units : mapping
        Record column -> unit in the file's metadata (``meta["units"]``).
    source : str
        File name for the message.

    Raises
    ------
    FileFormatError
        Naming the column and both units, and the fix.

    Examples
    --------
    >>> check_meta_units({"t": "s"}, {"t": "s", "x": "rad"}, "a.csv")
    >>> try:
    ...     check_meta_units({"t": "ms"}, {"t": "s"}, "a.csv")
    ... except FileFormatError as exc:
    ...     print(str(exc)[:48])
    a.csv: column 't' is in 'ms' by the header but i
    """
    if not isinstance(meta_units, Mapping):
        raise FileFormatError(
            f"{source}: the metadata's 'units' must be an object such as "
            f"{{\"t\": \"s\", \"x\": \"rad\"}}; got a {type(meta_units).__name__}")
    for column, head in header_units.items():
        meta = meta_units.get(column)
        if meta is None or not head or meta == head:
            continue
        if not isinstance(meta, str):
            raise FileFormatError(
                f"{source}: the metadata's unit of column {column!r} must be text; got a "
                f"{type(meta).__name__}")
        a, b = _si(column, head), _si(column, meta)
        if a is not None and a == b:
            continue
        from driveid.io.units import normalise_unit, wrong_role

        wrong = wrong_role(column, normalise_unit(head)) if a is None else None
        if wrong:  # the user picked another role's column (--position t on a driveid file)
            raise FileFormatError(f"{source}: {wrong}")
        raise FileFormatError(
            f"{source}: column {column!r} is in {head!r} by the header but in {meta!r} by "
            "the '# meta:' line; make them agree (fix or delete the meta 'units' entry)")


def record_digest(record: Any) -> str:
    """Return a SHA-256 digest of a record's columns (not its metadata).

    Parameters
    ----------
    record : Record
        The record.

    Returns
    -------
    str
        Hex digest; equal digests mean identical samples.
    """
    h = hashlib.sha256()
    for column in ("t", "x", "u", "v"):
        values = getattr(record, column, None)
        h.update(column.encode())
        if values is not None:
            arr = np.ascontiguousarray(values, dtype=float)
            h.update(str(arr.shape).encode())
            h.update(arr.tobytes())
    return h.hexdigest()


def duplicate_groups(records: Sequence[Any]) -> list[list[int]]:
    """Group records with identical samples (or the same source file).

    Parameters
    ----------
    records : sequence of Record
        The records of one analysis.

    Returns
    -------
    list of list of int
        Indices of each group of two or more duplicates, in order.
    """
    by_key: dict[str, list[int]] = {}
    spans: dict[str, list[tuple[int, float, float]]] = {}
    for i, rec in enumerate(records):
        source = (getattr(rec, "meta", {}) or {}).get("source")
        by_key.setdefault(f"data:{record_digest(rec)}", []).append(i)
        if source:
            spans.setdefault(os.path.realpath(str(source)), []).append(
                (i, float(rec.t[0]), float(rec.t[-1])))
    # one file twice counts only where the windows overlap: file@0:0.5 and file@0.5:1.5 are
    # different data (a false warning, fifth hostile campaign)
    for path, members in spans.items():
        for a, (i, lo_i, hi_i) in enumerate(members):
            overlapping = [j for j, lo_j, hi_j in members[a + 1:] if lo_j < hi_i and lo_i < hi_j]
            if overlapping:
                by_key.setdefault(f"file:{path}:{i}", []).extend([i, *overlapping])
    groups: list[list[int]] = []
    seen: set[tuple[int, ...]] = set()
    for members in by_key.values():
        unique = tuple(sorted(set(members)))
        if len(unique) > 1 and unique not in seen:
            seen.add(unique)
            groups.append(list(unique))
    return groups


def warn_duplicates(records: Sequence[Any], *, strict: bool = False) -> list[list[int]]:
    """Warn (or, with ``strict``, refuse) when the same file or run is given twice.

    Counting one measurement twice shrinks every standard error by √2 while adding no
    information.

    Parameters
    ----------
    records : sequence of Record
        The records of one analysis.
    strict : bool
        Raise instead of warning.

    Returns
    -------
    list of list of int
        The duplicate groups (empty if none).

    Raises
    ------
    RecordError
        With ``strict`` if there is a duplicate.
    """
    groups = duplicate_groups(records)
    if not groups:
        return groups
    names = []
    for group in groups:
        first = records[group[0]]
        source = (getattr(first, "meta", {}) or {}).get("source") or f"record {group[0] + 1}"
        names.append(f"{os.path.basename(str(source))} x{len(group)} "
                     f"(records {', '.join(str(i + 1) for i in group)})")
    message = (f"the same data were given more than once: {'; '.join(names)}; each copy "
               "would shrink the standard errors by a further factor without adding "
               "information; give every file or run once")
    if strict:
        from driveid.errors import RecordError

        raise RecordError(message + " (refused under --strict)")
    warnings.warn(message, RecordWarning, stacklevel=2)
    return groups


def _depth(text: str) -> int:
    deepest = depth = 0
    in_string = escaped = False
    for char in text:
        if in_string:
            if escaped:
                escaped = False
            elif char == "\\":
                escaped = True
            elif char == '"':
                in_string = False
        elif char == '"':
            in_string = True
        elif char in "[{":
            depth += 1
            deepest = max(deepest, depth)
        elif char in "]}":
            depth -= 1
    return deepest


def load_json(text: str | bytes, source: str, *, max_depth: int = MAX_JSON_DEPTH,
              constants: bool = False) -> Any:
    """Parse JSON, refusing absurd nesting and non-finite numbers with one-line errors.

    Parameters
    ----------
    text : str or bytes
        The JSON text (bytes must be UTF-8).
    source : str
        Name used in messages (the file name, "meta line of a.csv").
    max_depth : int
        Deepest nesting of objects and arrays accepted [-].
    constants : bool
        Read ``NaN`` and ``Infinity`` as floats (a result file, whose reader decides what
        a missing number means) instead of refusing them.

    Returns
    -------
    object
        The parsed value.

    Raises
    ------
    FileFormatError
        If the text is not UTF-8, not JSON, nested deeper than ``max_depth`` or holds
        ``NaN``/``Infinity``. The message gives the position, never the content.

    Examples
    --------
    >>> load_json('{"a": [1, 2]}', "m.json")
    {'a': [1, 2]}
    """
    if isinstance(text, bytes):
        try:
            text = text.decode("utf-8-sig")
        except UnicodeDecodeError as exc:
            raise FileFormatError(
                f"{source} is not UTF-8 text (bad byte at offset {exc.start}); save it as "
                "UTF-8") from None
    depth = _depth(text)
    if depth > max_depth:
        raise FileFormatError(
            f"{source}: JSON nested {depth} levels deep; at most {max_depth} are accepted "
            "(driveid's own JSON nests a few levels: a manifest or meta line 3, a result about 8)")

    def _constant(name: str) -> Any:
        raise FileFormatError(f"{source}: JSON holds {name}, which is not a number; write "
                              "null for an unknown value")

    try:
        return json.loads(text) if constants else json.loads(text, parse_constant=_constant)
    except json.JSONDecodeError as exc:
        raise FileFormatError(
            f"{source} is not valid JSON: {exc.msg} at line {exc.lineno} column {exc.colno}"
        ) from None
    except RecursionError:  # pragma: no cover - the depth check comes first
        raise FileFormatError(f"{source}: JSON nested too deeply") from None


def available_memory() -> int:
    """Return the memory this process may still use [bytes] (a generous estimate).

    Returns
    -------
    int
        ``MemAvailable`` of ``/proc/meminfo`` (Linux), else physical memory, else 4 GiB;
        capped by ``RLIMIT_AS`` when one is set.
    """
    avail = None
    try:
        with open("/proc/meminfo", encoding="ascii") as fh:
            for line in fh:
                if line.startswith("MemAvailable:"):
                    avail = int(line.split()[1]) * 1024
                    break
    except (OSError, ValueError, IndexError):
        pass
    if avail is None:
        try:
            avail = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
        except (ValueError, OSError, AttributeError):
            avail = 4 << 30
    if sys.platform != "win32":
        import resource

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY:
            avail = min(avail, soft)
    return int(avail)


def format_bytes(n: float) -> str:
    """Return a byte count in binary units for a message, e.g. ``'1.5 GiB'``.

    Parameters
    ----------
    n : float
        Bytes [B].

    Returns
    -------
    str
        Three significant digits and the unit (B, KiB … PiB).
    """
    for unit in ("B", "KiB", "MiB", "GiB", "TiB", "PiB"):
        if n < 1024 or unit == "PiB":
            return f"{n:.3g} {unit}"
        n /= 1024
    return f"{n:.3g} PiB"  # pragma: no cover


def check_allocation(n_samples: float, bytes_per_sample: float, what: str, *,
                     limit: float | None = None, override: str | None = None) -> int:
    """Refuse a request whose arrays would exceed the available memory, before allocating.

    Parameters
    ----------
    n_samples : float
        Number of samples the request implies (e.g. ``duration * fs``) [-].
    bytes_per_sample : float
        Bytes held per sample by the whole computation (all arrays, temporaries) [B].
    what : str
        What is being sized, in the user's terms (``"--duration 1e9 at --rate 1000"``).
    limit : float, optional
        Largest total allowed [B]; default :func:`available_memory`.
    override : str, optional
        How the user lowers the request or lifts the limit, appended to the message.

    Returns
    -------
    int
        The number of samples, as an int.

    Raises
    ------
    ParameterError
        If ``n_samples`` is not finite and non-negative, or the estimate exceeds ``limit``.

    Examples
    --------
    >>> check_allocation(1000, 8, "a test")
    1000
    """
    if not (isinstance(n_samples, (int, float)) and math.isfinite(n_samples)
            and n_samples >= 0):
        raise ParameterError(f"{what}: the number of samples must be finite and >= 0; got "
                             f"{n_samples!r}")
    limit = available_memory() if limit is None else float(limit)
    need = float(n_samples) * float(bytes_per_sample)
    if need > limit:
        hint = override or "shorten the request (duration, rate or grid)"
        raise ParameterError(
            f"{what} needs about {format_bytes(need)} ({n_samples:.3g} samples x "
            f"{bytes_per_sample:g} B), more than the {format_bytes(limit)} of memory available; "
            f"{hint}")
    return int(n_samples)


def check_disk(n_bytes: float, folder: str | Path, what: str, *, override: str) -> None:
    """Refuse a write that would not fit on the disk holding ``folder``, before writing.

    Parameters
    ----------
    n_bytes : float
        Bytes the request will write, an estimate [B].
    folder : str or Path
        Where it writes (need not exist yet: its nearest existing parent is measured).
    what : str
        What is written, in the user's terms.
    override : str
        How the user makes the request smaller.

    Raises
    ------
    ParameterError
        If ``n_bytes`` exceeds the free space there.

    Examples
    --------
    >>> check_disk(1000, ".", "a test", override="write less")
    """
    import shutil

    where = Path(folder).absolute()
    while not where.exists() and where != where.parent:
        where = where.parent
    free = shutil.disk_usage(where).free
    if n_bytes > free:
        raise ParameterError(
            f"{what} would write about {format_bytes(n_bytes)}, more than the "
            f"{format_bytes(free)} free on the disk of {where}; {override}")


#: Most runs a campaign plans without an explicit override (CLI ``--max-runs``): the
#: largest grid a mistyped ``--n-D`` should not start silently [-].
MAX_CAMPAIGN_RUNS = 10_000


def check_count(count: int, limit: int, what: str, *, override: str) -> int:
    """Refuse an absurd number of items (runs of a campaign, records of an analysis).

    Parameters
    ----------
    count : int
        Number requested [-].
    limit : int
        Largest number accepted without an explicit override [-].
    what : str
        What is counted, in the user's terms.
    override : str
        How to lift the limit (e.g. ``"max_runs=... (CLI: --max-runs)"``).

    Returns
    -------
    int
        ``count``.

    Raises
    ------
    ParameterError
        If ``count > limit``.
    """
    if count > limit:
        raise ParameterError(
            f"{what}: {count} is more than the limit of {limit}; reduce it, or raise the "
            f"limit with {override}")
    return count
