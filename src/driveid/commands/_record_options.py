"""The record options shared by every command that reads a trace (defined once).

``@record_options`` adds ``--time --position --velocity --force`` (column name, 0-based index
or ``VAR:INDEX``), ``--fs``, ``--t-start``, ``--t-end``, ``--max-jitter``, ``--scale COL=F``,
``--unit COL=UNIT``, ``--counts-per-rev``, ``--counts-per-metre`` and ``--sign-magnitude
COL:BITS`` to a click command and passes one :class:`RecordOptions` to the callback as
``record_opts``. ``record_opts.read(spec)`` reads one file (``file.csv@12.5:40`` keeps its
own window) with the same keywords as :func:`driveid.io.read_record`, and prints the reading's
notes (a column chosen by convention, a unit assumed) as ``note: ...`` lines on stderr.
:meth:`RecordOptions.from_reading` rebuilds the options stored in a result's ``inputs``
(``validate`` and ``report`` reuse them).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import click

from driveid.commands._checks import PositiveFloat
from driveid.commands._output import cli_text
from driveid.io.reading_options import reading_as_cli

__all__ = ["RecordOptions", "record_options", "split_window_spec", "show_notes",
           "reading_as_cli"]


@dataclass(frozen=True)
class RecordOptions:
    """How to read a trace: columns, sample rate, window, jitter, scales and units.

    Attributes
    ----------
    columns : dict
        Record column (``t``, ``x``, ``v``, ``u``) -> name, index or ``VAR:INDEX`` in the file.
    fs : float or None
        Sample rate [Hz] for files without a time column.
    window : tuple of (float or None, float or None)
        Start and end time [s] kept from every file (a file's own ``@t0:t1`` wins).
    max_jitter : float or None
        Largest relative deviation of a sampling interval [-]; ``None`` accepts any
        increasing timeline.
    scale : dict
        Record column -> factor (a number, an expression such as ``0.02/60``, or a scalar
        variable of the file).
    units : dict
        Record column -> unit string stating or overriding the file's unit.
    counts_per_rev, counts_per_metre : float or None
        Encoder resolution for positions given in counts [counts/rev, counts/m].
    sign_magnitude : dict
        Record column -> register width [bits] of a sign-magnitude integer column.
    """

    columns: dict[str, str] = field(default_factory=dict)
    fs: float | None = None
    window: tuple[float | None, float | None] = (None, None)
    max_jitter: float | None = 0.01
    scale: dict[str, Any] = field(default_factory=dict)
    units: dict[str, str] = field(default_factory=dict)
    counts_per_rev: float | None = None
    counts_per_metre: float | None = None
    sign_magnitude: dict[str, int] = field(default_factory=dict)

    def read(self, spec: str | Path, *, position: bool = True, notes: bool = True) -> Any:
        """Read one file, ``PATH`` or ``PATH@T0:T1`` (either bound may be empty) [s].

        Parameters
        ----------
        spec : str or Path
            The file, optionally with its own window; a file's window wins over
            ``--t-start``/``--t-end``.
        position : bool
            False accepts a speed-only file, for a command that uses no position.
        notes : bool
            Print the reading's notes as ``note: FILE: ...`` lines on stderr.

        Returns
        -------
        Record
            The record in SI units with provenance in ``meta``.
        """
        from driveid.io import read_record

        path, window = split_window_spec(spec)
        if window == (None, None):
            window = self.window
        record = read_record(path, position=position, **self.read_kwargs(window))
        _check_magnitudes(record, path)
        if notes:
            show_notes(path, record.meta.get("notes", ()))
        return record

    @classmethod
    def from_reading(cls, reading: Mapping[str, Any]) -> RecordOptions:
        """Rebuild the options stored as ``inputs[k]["reading"]`` of a result.

        Parameters
        ----------
        reading : mapping
            ``columns``, ``fs`` [Hz], ``max_jitter`` [-], ``scale``, ``units``,
            ``counts_per_rev`` [1/rev], ``counts_per_metre`` [1/m], ``sign_magnitude``
            [bits], each optional.

        Returns
        -------
        RecordOptions
            The options (no window: a result's window is not reused).
        """
        known = {"columns", "fs", "max_jitter", "scale", "units", "counts_per_rev",
                 "counts_per_metre", "sign_magnitude"}
        kwargs = {k: (dict(v) if isinstance(v, Mapping) else v)
                  for k, v in reading.items() if k in known}
        return cls(**kwargs)

    def is_default(self) -> bool:
        """Return True when no reading option was given (every field at its default).

        Returns
        -------
        bool
            True for ``RecordOptions()``.
        """
        return self == RecordOptions()

    def read_all(self, specs: Sequence[str | Path]) -> list[Any]:
        """Read several files, each with its own window.

        Parameters
        ----------
        specs : sequence of str or Path
            ``PATH`` or ``PATH@T0:T1`` each.

        Returns
        -------
        list of Record
            One per file, in order.

        Warns
        -----
        RecordWarning
            When the same data are given twice (their standard errors would shrink by
            √2 with nothing new measured).
        """
        from driveid.io.consistency import warn_duplicates

        records = [self.read(spec) for spec in specs]
        _one_kind_of_motion(records)
        warn_duplicates(records)
        return records

    def read_kwargs(self, window: tuple[float | None, float | None] | None = None
                    ) -> dict[str, Any]:
        """Return the keywords of :func:`driveid.io.read_record` for these options.

        Parameters
        ----------
        window : tuple of (float or None, float or None), optional
            Window [s] to use instead of the options' own.

        Returns
        -------
        dict
            ``max_jitter`` always; the other keywords where given.
        """
        kwargs: dict[str, Any] = {"max_jitter": self.max_jitter}
        if self.columns:
            kwargs["columns"] = dict(self.columns)
        if self.scale:
            kwargs["scale"] = dict(self.scale)
        if self.units:
            kwargs["units"] = dict(self.units)
        if self.fs is not None:
            kwargs["fs"] = self.fs
        window = self.window if window is None else window
        if window != (None, None):
            kwargs["window"] = window
        if self.counts_per_rev is not None:
            kwargs["counts_per_rev"] = self.counts_per_rev
        if self.counts_per_metre is not None:
            kwargs["counts_per_metre"] = self.counts_per_metre
        if self.sign_magnitude:
            kwargs["sign_magnitude"] = dict(self.sign_magnitude)
        return kwargs


#: Magnitudes outside [1e-100, 1e100] (as for numeric options) make squares and products of
#: samples overflow or underflow in the estimators: ×1e300 and ×1e-310 once ended in exit 70.
_MAGNITUDE_LIMIT = 1e100
_COLUMN_WORDS = {"t": "time", "x": "position", "v": "velocity", "u": "force"}


def _one_kind_of_motion(records: Sequence[Any]) -> None:
    """Refuse records of one fit that mix rotation (rad) and translation (m).

    A rad file fitted with an mm file was accepted, the result's units set by whichever
    came first (fifth hostile campaign).
    """
    from driveid.errors import FileFormatError

    units = {r.units.get("x") for r in records}
    if len(units) > 1:
        listed = ", ".join(f"{Path(str(r.meta.get('source') or i + 1)).name} in "
                           f"{r.units.get('x')}" for i, r in enumerate(records))
        raise FileFormatError(
            f"the records of one fit mix rotation and translation ({listed}); fit each axis "
            "on its own, or state the unit that is wrong with --unit x=UNIT")


def _check_magnitudes(record: Any, path: Path) -> None:
    """Refuse a column whose largest magnitude is out of the range the estimators compute in."""
    import numpy as np

    from driveid.errors import RecordError

    for col, word in _COLUMN_WORDS.items():
        values = getattr(record, col, None)
        if values is None:
            continue
        peak = float(np.max(np.abs(values), initial=0.0))
        if peak == 0.0 or (1.0 / _MAGNITUDE_LIMIT <= peak <= _MAGNITUDE_LIMIT):
            continue
        size = "above" if peak > _MAGNITUDE_LIMIT else "below"
        bound = _MAGNITUDE_LIMIT if peak > _MAGNITUDE_LIMIT else 1.0 / _MAGNITUDE_LIMIT
        exponent = min(max(-math.floor(math.log10(peak)), -300), 300)  # a finite factor
        raise RecordError(
            f"{path.name}: the {word} column reaches {peak:.3g} (SI units), {size} the "
            f"{bound:.0e} that driveid computes with (squares of samples would "
            f"{'overflow' if size == 'above' else 'underflow'}); check the column's unit "
            f"(--unit {col}=UNIT) or rescale it (--scale {col}=F), e.g. "
            f"--scale {col}=1e{exponent}")


def show_notes(path: str | Path, notes: Sequence[str]) -> None:
    """Print the notes of a reading as ``note: FILE: ...`` on stderr.

    Parameters
    ----------
    path : str or Path
        The file read.
    notes : sequence of str
        ``record.meta["notes"]``.
    """
    for note in dict.fromkeys(notes):
        click.echo(f"note: {Path(path).name}: {note}", err=True)


def split_window_spec(spec: str | Path) -> tuple[Path, tuple[float | None, float | None]]:
    """Split ``PATH@T0:T1`` into the path and its window [s]; a plain path has none.

    Parameters
    ----------
    spec : str or Path
        ``run.csv``, ``run.csv@12.5:40``, ``run.csv@12.5:`` or ``run.csv@:40``.

    Returns
    -------
    tuple
        ``(Path, (t0 or None, t1 or None))``.

    Examples
    --------
    >>> split_window_spec("a.csv@1.5:")
    (PosixPath('a.csv'), (1.5, None))
    """
    text = str(spec)
    if "@" not in text or Path(text).exists():
        return Path(text), (None, None)
    path, _, window = text.rpartition("@")
    start, sep, end = window.partition(":")
    if not sep:
        raise click.BadParameter(
            f"window {window!r} must be T0:T1 in seconds, e.g. {path}@12.5:40; got {text!r}")
    return Path(path), (_time(start, text), _time(end, text))


def _time(text: str, spec: str) -> float | None:
    if not text.strip():
        return None
    try:
        value = float(text)
    except ValueError:
        raise click.BadParameter(f"window bound {text!r} in {spec!r} is not a number [s]"
                                 ) from None
    if not math.isfinite(value):
        raise click.BadParameter(f"window bound in {spec!r} must be finite [s]; got {text!r}")
    return value


def _pairs(values: Sequence[str], option: str) -> dict[str, str]:
    out: dict[str, str] = {}
    for item in values:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise click.BadParameter(f"{option} takes COL=VALUE, e.g. {option} u=200; got {item!r}")
        column = _column(key.strip(), option)
        if column in out and out[column] != value.strip():  # the last one won in silence
            raise click.BadParameter(
                f"{option} gives column {column} twice ({out[column]!r} and {value.strip()!r})"
                "; give it once" + ("" if option != "--scale" else
                                    f" (a product is one expression, e.g. --scale {column}=2*3)"))
        out[column] = value.strip()
    return out


_COLUMN_NAMES = {"t": "t", "time": "t", "x": "x", "position": "x", "v": "v", "velocity": "v",
                 "u": "u", "force": "u", "torque": "u"}


def _column(name: str, option: str) -> str:
    try:
        return _COLUMN_NAMES[name.lower()]
    except KeyError:
        raise click.BadParameter(
            f"{option} names record column {name!r}; use t, x, v or u (time, position, "
            "velocity, force)") from None


def record_options(func: Callable[..., Any]) -> Callable[..., Any]:
    """Add the shared record options to a click command; pass ``record_opts`` to it."""
    options = [
        click.option("--time", "opt_time", default=None,
                     help="Time column: name, 0-based index or VAR:INDEX (default: found "
                          "by name, e.g. t, time, Zeit)."),
        click.option("--position", "opt_position", default=None,
                     help="Position column: name, 0-based index or VAR:INDEX."),
        click.option("--velocity", "opt_velocity", default=None,
                     help="Velocity column: name, 0-based index or VAR:INDEX; 'none' "
                          "ignores a velocity column."),
        click.option("--force", "opt_force", default=None,
                     help="Force/torque column: name, 0-based index or VAR:INDEX; 'none' "
                          "ignores a force column."),
        click.option("--fs", "opt_fs", type=float, default=None,
                     help="Sample rate [Hz] for files without a time column."),
        click.option("--t-start", "opt_t_start", type=float, default=None,
                     help="Keep samples from this time on [s] (per file: FILE@T0:T1)."),
        click.option("--t-end", "opt_t_end", type=float, default=None,
                     help="Keep samples up to this time [s]."),
        click.option("--max-jitter", "opt_max_jitter", default="0.01", show_default=True,
                     help="Largest relative deviation of a sampling interval; 'none' "
                          "accepts any increasing timeline."),
        click.option("--scale", "opt_scale", multiple=True, metavar="COL=F",
                     help="Multiply a column by F after reading, e.g. u=200 (N per V) or "
                          "v=0.02/60; repeatable."),
        click.option("--unit", "opt_unit", multiple=True, metavar="COL=UNIT",
                     help="State or override a column's unit, e.g. x=mm; repeatable."),
        click.option("--counts-per-rev", "opt_counts_per_rev", type=PositiveFloat(min=1.0),
                     default=None,
                     help="Encoder counts per revolution, for positions in counts."),
        click.option("--counts-per-metre", "opt_counts_per_metre",
                     type=PositiveFloat(min=1.0), default=None,
                     help="Encoder counts per metre, for positions in counts."),
        click.option("--sign-magnitude", "opt_sign_magnitude", multiple=True,
                     metavar="COL:BITS",
                     help="Decode a column stored as sign-magnitude integers (top bit the "
                          "sign), e.g. x:16; repeatable."),
    ]

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            kwargs["record_opts"] = _build(kwargs)
        except click.BadParameter as exc:
            click.echo(f"error: {cli_text(exc.format_message())}", err=True)
            raise SystemExit(2) from None
        return func(*args, **kwargs)

    for option in reversed(options):
        wrapper = option(wrapper)
    return wrapper


def _build(kwargs: dict[str, Any]) -> RecordOptions:
    columns = {}
    for col, key in (("t", "opt_time"), ("x", "opt_position"), ("v", "opt_velocity"),
                     ("u", "opt_force")):
        value = kwargs.pop(key)
        if value is not None:
            columns[col] = value
    jitter_text = str(kwargs.pop("opt_max_jitter")).strip().lower()
    if jitter_text == "none":
        max_jitter = None
    else:
        try:
            max_jitter = float(jitter_text)
        except ValueError:
            raise click.BadParameter(
                f"--max-jitter takes a fraction such as 0.05 or 'none'; got {jitter_text!r}"
            ) from None
        if not (math.isfinite(max_jitter) and max_jitter > 0):
            raise click.BadParameter(
                f"--max-jitter must be a positive fraction or 'none'; got {jitter_text!r}")
    fs = kwargs.pop("opt_fs")
    if fs is not None and not (math.isfinite(fs) and fs > 0):
        raise click.BadParameter(f"--fs must be a positive sample rate [Hz]; got {fs}")
    return RecordOptions(
        columns=columns,
        fs=fs,
        window=(kwargs.pop("opt_t_start"), kwargs.pop("opt_t_end")),
        max_jitter=max_jitter,
        scale=_pairs(kwargs.pop("opt_scale"), "--scale"),
        units=_pairs(kwargs.pop("opt_unit"), "--unit"),
        counts_per_rev=kwargs.pop("opt_counts_per_rev"),
        counts_per_metre=kwargs.pop("opt_counts_per_metre"),
        sign_magnitude=_bits(kwargs.pop("opt_sign_magnitude")),
    )


def _bits(values: Sequence[str]) -> dict[str, int]:
    out: dict[str, int] = {}
    for item in values:
        key, sep, value = item.replace("=", ":").partition(":")
        try:
            bits = int(value)
        except ValueError:
            bits = 0
        if not sep or not key.strip() or not 2 <= bits <= 64:
            raise click.BadParameter(
                f"--sign-magnitude takes COL:BITS with 2 to 64 bits, e.g. --sign-magnitude "
                f"x:16; got {item!r}")
        out[_column(key.strip(), "--sign-magnitude")] = bits
    return out
