"""TOML description of a lumped drive for :func:`~driveid.sim.drive.simulate_drive`.

A file either names a preset of :mod:`driveid.sim.presets` (its ``[feedback]`` table may
then override single feedback fields) or lists the bodies and links::

    # bodies, links and feedback.body count from 1, like the x1, x2 ... record columns
    [[body]]            # motor
    J = 0.0115355       # inertia [kg·m²] (mass [kg] for a translational drive)
    c_mean = 0.0007457  # viscous friction [N·m·s/rad]
    fk_mean = 0.109456  # kinetic friction [N·m]

    [[body]]
    J = 0.0035271

    [[link]]            # joins body 1 and body 2
    type = "backlash"   # "shaft", "backlash" or "none"
    gap_plus = 0.02     # [rad]
    gap_minus = 0.02    # [rad]
    k = 100.0           # contact stiffness [N·m/rad]
    # contact = "restitution"   # optional Newton impact instead of Kelvin-Voigt:
    # restitution = 0.5         # coefficient e [-]; rest_velocity [rad/s] optional

    [feedback]
    P = 5.0             # [N·m/rad]
    D = 0.1             # [N·m·s/rad]
    delay = 0.01377     # [s]

    [run]
    duration = 5.0      # [s]
    fs = 1000.0         # output rate [Hz]
    x0 = [1.0, 1.0]     # initial positions [rad], one per body (or one number for all)

Keys and units are those of :class:`~driveid.sim.drive.BodyParams`,
:class:`~driveid.sim.drive.ShaftLink`, :class:`~driveid.sim.drive.BacklashLink` and
:class:`~driveid.sim.drive.PDFeedback`. Every error is a :class:`~driveid.errors.ConfigError`
that names the file and the key path, e.g. ``body[2].J: ...``.
"""

from __future__ import annotations

import dataclasses
import math
import re
import tomllib
from collections.abc import Mapping
from pathlib import Path

from driveid.errors import ConfigError, ParameterError
from driveid.sim.drive import (
    DEFAULT_MAX_STEPS,
    BacklashLink,
    BodyParams,
    DriveParams,
    DriveResult,
    PDFeedback,
    ShaftLink,
    simulate_drive,
)
from driveid.sim.presets import PRESETS, preset, preset_units

__all__ = ["RunOptions", "load_drive_config", "parse_drive_config", "read_toml", "simulate_config"]

_TOP_KEYS = ("preset", "body", "link", "feedback", "run")
_BODY_KEYS = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "fs_mean", "fs_delta",
              "locked", "ripple_amplitude", "ripple_period", "ripple_phase", "stribeck", "v_s",
              "v_s_delta", "stribeck_exponent", "dwell_gamma", "dwell_kappa", "memory")
_LINK_KEYS = {"shaft": ("type", "k", "c"),
              "backlash": ("type", "gap_plus", "gap_minus", "k", "c", "allow_tension",
                           "contact", "restitution", "rest_velocity"),
              "none": ("type",)}
_FEEDBACK_KEYS = ("P", "D", "delay", "body", "reference", "saturation", "abort_limit")
_RUN_KEYS = ("duration", "fs", "x0", "v0", "torque", "method", "units")
_BOOL_KEYS = ("locked", "allow_tension")
_FIELD = re.compile(r"^(?:BodyParams|ShaftLink|BacklashLink|PDFeedback)\.(\w+)")


@dataclasses.dataclass(frozen=True, kw_only=True)
class RunOptions:
    """How to run a configured drive (the ``[run]`` table).

    Attributes
    ----------
    duration : float
        Simulated time [s]; > 0 (default 5).
    fs : float
        Output sampling rate [Hz]; > 0 (default 1000).
    x0, v0 : tuple of float or None
        Initial positions [rad or m] and velocities [rad/s or m/s], one per body.
    torque : tuple of float or None
        Constant external torque [N·m] (force [N]) on each body.
    method : {"auto", "rk4", "exact"}
        Integration method of :func:`~driveid.sim.drive.simulate_drive`.
    units : {"rad", "m"}
        Rotational or translational drive (labels of the written record).
    """

    duration: float = 5.0
    fs: float = 1000.0
    x0: tuple | None = None
    v0: tuple | None = None
    torque: tuple | None = None
    method: str = "auto"
    units: str = "rad"

    def __post_init__(self) -> None:
        for name in ("duration", "fs"):
            value = getattr(self, name)
            if (isinstance(value, bool) or not isinstance(value, (int, float))
                    or not 0 < value < math.inf):
                raise ParameterError(f"RunOptions.{name} must be positive and finite; "
                                     f"got {value!r}")
        if self.method not in ("auto", "rk4", "exact"):
            raise ParameterError('RunOptions.method must be "auto", "rk4" or "exact"; '
                                 f"got {self.method!r}")
        if self.units not in ("rad", "m"):
            raise ParameterError(f'RunOptions.units must be "rad" or "m"; got {self.units!r}')


def _fail(where: str, message: str) -> ConfigError:
    return ConfigError(f"{where}: {message}")


def _check_keys(table, allowed, where: str) -> dict:
    if not isinstance(table, Mapping):
        raise _fail(where, f"must be a table; got {table!r}")
    unknown = sorted(set(table) - set(allowed))
    if unknown:
        raise _fail(where, f"unknown key(s) {unknown}; allowed keys are {list(allowed)}; "
                           f"got {sorted(table)}")
    return dict(table)


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise _fail(where, f"must be a number; got {value!r}")
    try:
        return float(value)
    except OverflowError:  # a TOML integer of hundreds of digits
        raise _fail(where, f"is an integer of about {int(value.bit_length() * 0.30103) + 1} "
                           "digits, beyond any "
                           "float (about 1.8e308); write the value in SI units with an "
                           "exponent, e.g. 1e3") from None


def _values(table: dict, where: str) -> dict:
    out = {}
    for key, value in table.items():
        if key in _BOOL_KEYS:
            if not isinstance(value, bool):
                raise _fail(f"{where}.{key}", f"must be true or false; got {value!r}")
            out[key] = value
        elif key in ("type", "contact"):
            out[key] = value
        elif key == "stribeck":  # "none" (TOML has no null) or a map name
            out[key] = None if value == "none" else value
        elif key == "body":
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise _fail(f"{where}.{key}", f"must be a body number >= 1 (counted from 1); "
                                              f"got {value!r}")
            out[key] = value - 1
        else:
            out[key] = _number(value, f"{where}.{key}")
    return out


def _build(cls, kwargs: dict, where: str):
    try:
        return cls(**kwargs)
    except ParameterError as exc:
        match = _FIELD.match(str(exc))
        key = f"{where}.{match.group(1)}" if match else where
        raise _fail(key, str(exc)) from None


def _require(table: dict, keys, where: str) -> None:
    missing = [k for k in keys if k not in table]
    if missing:
        raise _fail(where, f"missing value(s) for {missing}; add them to the table; "
                           f"got keys {sorted(table)}")


def _body(table, i: int) -> BodyParams:
    where = f"body[{i}]"
    values = _values(_check_keys(table, _BODY_KEYS, where), where)
    _require(values, ("J",), where)
    return _build(BodyParams, values, where)


def _link(table, i: int):
    where = f"link[{i}]"
    if not isinstance(table, Mapping):
        raise _fail(where, f"must be a table; got {table!r}")
    kind = table.get("type")
    if kind not in _LINK_KEYS:
        raise _fail(f"{where}.type", f"must be one of {list(_LINK_KEYS)}; got {kind!r}")
    values = _values(_check_keys(table, _LINK_KEYS[kind], where), where)
    del values["type"]
    if kind == "none":
        return None
    if kind == "shaft":
        _require(values, ("k",), where)
        return _build(ShaftLink, values, where)
    _require(values, ("gap_plus", "gap_minus", "k"), where)
    return _build(BacklashLink, values, where)


def _per_body(value, where: str, n_bodies: int) -> tuple:
    if isinstance(value, list):
        if len(value) != n_bodies:
            raise _fail(where, f"needs one value per body ({n_bodies}); got {len(value)} "
                               f"values {value!r}")
        return tuple(_number(v, f"{where}[{j + 1}]") for j, v in enumerate(value))
    return (_number(value, where),) * n_bodies


def parse_drive_config(config: Mapping, *, source: str = "config"
                       ) -> tuple[DriveParams, RunOptions]:
    """Build the drive and run options from a parsed TOML mapping.

    Parameters
    ----------
    config : mapping
        The parsed document (see the module docstring for its tables).
    source : str
        Name used at the start of error messages (the file name).

    Returns
    -------
    params : DriveParams
        The drive.
    options : RunOptions
        Duration, sampling rate, initial state, torques, method and units.

    Raises
    ------
    ConfigError
        If a key is unknown, a required value is missing or a value is unphysical (the
        message names the key path, e.g. ``body[2].J``).

    Examples
    --------
    >>> params, run = parse_drive_config({"body": [{"J": 1.0, "K": 16.0}],
    ...                                   "run": {"duration": 2.0, "x0": 1.0}})
    >>> params.bodies[0].K, run.duration, run.x0
    (16.0, 2.0, (1.0,))
    """
    try:
        return _parse(config)
    except ConfigError as exc:
        raise ConfigError(f"{source}: {exc}") from None


def _parse(config) -> tuple[DriveParams, RunOptions]:
    config = _check_keys(config, _TOP_KEYS, "top level")
    units = "rad"
    if "preset" in config:
        name = config["preset"]
        if name not in PRESETS:
            raise _fail("preset", f"unknown preset; use one of {sorted(PRESETS)}; got {name!r}")
        for key in ("body", "link"):
            if key in config:
                raise _fail(key, f"a preset fixes the bodies and links; remove [[{key}]] or "
                                 f"the preset; got preset = {name!r}")
        base = preset(name)
        units = preset_units(name)
        bodies, links = base.bodies, base.links
        feedback = base.feedback
        if "feedback" in config:
            values = _values(_check_keys(config["feedback"], _FEEDBACK_KEYS, "feedback"),
                             "feedback")
            if feedback is None:
                _require(values, ("P", "D"), "feedback")
                feedback = _build(PDFeedback, values, "feedback")
            else:
                fields = {f.name: getattr(feedback, f.name)
                          for f in dataclasses.fields(PDFeedback)}
                feedback = _build(PDFeedback, {**fields, **values}, "feedback")
    else:
        if "body" not in config:
            raise _fail("body", "missing: give [[body]] tables or a preset "
                                f"(one of {sorted(PRESETS)}); got keys {sorted(config)}")
        tables = config["body"]
        if not isinstance(tables, list) or not tables:
            raise _fail("body", f"must be one or more [[body]] tables; got {tables!r}")
        bodies = tuple(_body(t, i + 1) for i, t in enumerate(tables))
        link_tables = config.get("link", [])
        if not isinstance(link_tables, list) or len(link_tables) != len(bodies) - 1:
            got = len(link_tables) if isinstance(link_tables, list) else repr(link_tables)
            raise _fail("link", f"needs len(body) - 1 = {len(bodies) - 1} [[link]] tables "
                                f"(type = \"none\" for no connection); got {got}")
        links = tuple(_link(t, i + 1) for i, t in enumerate(link_tables))
        feedback = None
        if "feedback" in config:
            values = _values(_check_keys(config["feedback"], _FEEDBACK_KEYS, "feedback"),
                             "feedback")
            _require(values, ("P", "D"), "feedback")
            feedback = _build(PDFeedback, values, "feedback")
    if feedback is not None:  # counted from 1 here, as the user wrote it (0-based leaked before)
        nb = len(bodies)
        if feedback.body >= nb:
            raise _fail("feedback.body", f"names body {feedback.body + 1}, but the drive has "
                                         f"{nb} bod{'y' if nb == 1 else 'ies'} (counted from 1)")
        if bodies[feedback.body].locked:
            raise _fail("feedback.body", f"body {feedback.body + 1} is locked; the feedback "
                                         "must act on a body that moves: unlock it or name "
                                         "another")
    try:
        params = DriveParams(bodies=bodies, links=links, feedback=feedback)
    except ParameterError as exc:
        raise _fail("feedback.body" if feedback is not None else "top level", str(exc)) from None
    run = _run(config.get("run", {}), params.n_bodies, units)
    moving = [i + 1 for i, b in enumerate(params.bodies) if b.locked and run.v0 and run.v0[i]]
    if moving:
        raise _fail("run.v0", f"locked bodies must start at rest; set v0 = 0 for bodies "
                              f"{moving} or unlock them; got v0 = {list(run.v0)}")
    return params, run


def _run(table, n_bodies: int, units: str) -> RunOptions:
    table = _check_keys(table, _RUN_KEYS, "run")
    kwargs = {"units": units}
    for key, value in table.items():
        where = f"run.{key}"
        if key in ("x0", "v0", "torque"):
            kwargs[key] = _per_body(value, where, n_bodies)
        elif key in ("method", "units"):
            if not isinstance(value, str):
                raise _fail(where, f"must be a string; got {value!r}")
            kwargs[key] = value
        else:
            kwargs[key] = _number(value, where)
    try:
        return RunOptions(**kwargs)
    except ParameterError as exc:
        match = re.match(r"^RunOptions\.(\w+)", str(exc))
        raise _fail(f"run.{match.group(1)}" if match else "run", str(exc)) from None


def load_drive_config(path: str | Path) -> tuple[DriveParams, RunOptions]:
    """Read a TOML drive description (see the module docstring for the format).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.

    Returns
    -------
    params : DriveParams
        The drive.
    options : RunOptions
        Duration, sampling rate, initial state, torques, method and units.

    Raises
    ------
    ConfigError
        If the file cannot be read or parsed, a key is unknown, a value is missing or
        unphysical; the message starts with the file name and the key path.
    """
    path = Path(path)
    return parse_drive_config(read_toml(path, "drive config"), source=path.name)


def _refuse_huge_integers(doc: dict, name: str, what: str) -> None:
    """Refuse an integer no float holds (TOML integers are unbounded; float() overflowed)."""
    stack: list[tuple[str, object]] = [("", doc)]
    while stack:
        key, value = stack.pop()
        if isinstance(value, Mapping):
            stack.extend((f"{key}.{k}" if key else str(k), v) for k, v in value.items())
        elif isinstance(value, list):
            # 1-based, as the config messages count bodies and links
            stack.extend((f"{key}[{i + 1}]", v) for i, v in enumerate(value))
        elif isinstance(value, int) and not isinstance(value, bool) \
                and value.bit_length() > 1023:
            raise ConfigError(
                f"{name}: {key} is an integer of about {int(value.bit_length() * 0.30103) + 1} "
                f"digits, beyond any float (about 1.8e308); write the {what}'s values in SI "
                "units with an exponent, e.g. 1e3")


def read_toml(path: str | Path, what: str) -> dict:
    """Read a TOML file, or raise one line naming the file and the fix.

    Parameters
    ----------
    path : str or Path
        The file.
    what : str
        What the file is, for the message (e.g. ``"drive config"``).

    Returns
    -------
    dict
        The parsed document.

    Raises
    ------
    ConfigError
        If the file cannot be read or is not valid TOML.
    """
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
        _refuse_huge_integers(doc, path.name, what)
        return doc
    except OSError as exc:
        raise ConfigError(f"cannot read the {what} {path}: {exc.strerror}; check the "
                          f"path; got {str(path)!r}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path.name}: not valid TOML ({exc}); fix the syntax") from None
    except UnicodeDecodeError as exc:  # issue 28: was the CSV reader's message, no file name
        raise ConfigError(
            f"{path.name}: the {what} is not UTF-8 text (byte 0x{exc.object[exc.start]:02x} at "
            f"offset {exc.start}; UTF-16 or Latin-1?); save it as UTF-8, as TOML requires"
        ) from None
    except RecursionError:  # issue 28: arrays nested thousands deep were an internal error
        raise ConfigError(
            f"{path.name}: the {what} nests arrays or tables deeper than the TOML parser can "
            "follow; driveid's TOML files need three levels at most (tables of numbers, strings "
            "and lists of them): fix the file") from None


def simulate_config(params: DriveParams, options: RunOptions, *,
                    max_steps: int | None = DEFAULT_MAX_STEPS) -> DriveResult:
    """Run :func:`~driveid.sim.drive.simulate_drive` with the options of a config.

    Parameters
    ----------
    params : DriveParams
        The drive.
    options : RunOptions
        Duration, rate, initial state, torques and method.
    max_steps : int or None
        Budget of RK4 grid steps [-] (default 1e9); a run that needs more, or more memory
        than is available, is refused before it starts (``None``: no step budget).

    Returns
    -------
    DriveResult
        The simulated response.

    Raises
    ------
    ParameterError
        If the run would need more memory than is available or more steps than
        ``max_steps``.

    Examples
    --------
    >>> params, run = parse_drive_config({"preset": "testbed-a",
    ...                                   "run": {"duration": 0.5, "x0": 1.0}})
    >>> simulate_config(params, run).x.shape
    (1, 501)
    """
    return simulate_drive(params, duration=options.duration, fs=options.fs, x0=options.x0,
                          v0=options.v0, torque=options.torque, method=options.method,
                          max_steps=max_steps)
