"""TOML description of a circular contour test on two (or three) feed axes.

Each axis is a drive as ``driveid simulate drive`` reads it (``[[x.body]]``, ``[[x.link]]``,
parsed by :func:`driveid.sim.config.parse_drive_config`), translational (m, N, kg), under a
sampled PID position controller ``[x.controller]``; the ``[path]`` table gives the circle::

    [[x.body]]            # motor and screw, reflected to the table [kg, N·s/m, N]
    J = 20.0
    fk_mean = 5.0
    [[x.body]]            # table
    J = 80.0
    c_mean = 300.0
    fk_mean = 50.0
    [[x.link]]            # screw-nut backlash
    type = "backlash"
    gap_plus = 6e-6       # [m]
    gap_minus = 6e-6
    k = 3e8               # [N/m]
    c = 7e3               # [N·s/m]
    [x.controller]
    kp = 6e6              # [N/m]
    kd = 3.4e4            # [N·s/m]
    ki = 1.8e8            # [N/(m·s)]
    kv = 0.0              # velocity feed-forward [N·s/m]
    ka = 100.0            # acceleration feed-forward [kg]
    rate = 2000.0         # controller sampling rate [Hz]
    body = 1              # actuated body (the motor), counted from 1
    sensor = 1            # measured body: 1 = semi-closed loop (motor encoder)

    [path]
    shape = "circle"
    radius = 0.05         # [m]
    feed = 0.1            # tangential speed [m/s]
    direction = "ccw"     # "ccw" or "cw"
    revolutions = 1.0     # turns at constant feed [-]
    fs = 1000.0           # record rate [Hz]
    start_angle = 45.0    # [deg] from the first axis, between two reversals
    ramp = 0.05           # feed ramp-up and -down time [s]
    plane = "xy"          # "xy", "yz" or "zx"; a third axis table is held at 0

    [noise]               # measurement noise of the written record (optional)
    position = 1e-7       # [m] rms on every position column
    command = 0.5         # [N] rms on every command column
    seed = 1

Every error is a :class:`~driveid.errors.ConfigError` naming the file and the key path.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from driveid.errors import ConfigError, ParameterError

# the drive config's key checks and messages, so both files read alike
from driveid.sim.config import _check_keys, _fail, parse_drive_config, read_toml
from driveid.sim.drive_types import DriveParams

__all__ = ["AxisConfig", "CirclePath", "ContourConfig", "ControllerParams", "MeasurementNoise",
           "load_contour_config", "parse_contour_config"]

_AXES = ("x", "y", "z")
_PLANES = {"xy": ("x", "y"), "yz": ("y", "z"), "zx": ("z", "x")}
_AXIS_KEYS = ("body", "link", "controller")
_CONTROLLER_KEYS = ("kp", "kd", "ki", "kv", "ka", "rate", "body", "sensor", "saturation")
_PATH_KEYS = ("shape", "radius", "feed", "direction", "revolutions", "fs", "start_angle",
              "ramp", "plane")
_NOISE_KEYS = ("position", "command", "seed")
_TOP_KEYS = _AXES + ("path", "noise")


def _positive(owner: str, name: str, value, *, zero_ok: bool = False) -> float:
    ok = not isinstance(value, bool) and isinstance(value, (int, float))
    try:  # a TOML integer of hundreds of digits is no float (OverflowError before)
        number = float(value) if ok else math.nan
    except OverflowError:
        number = math.inf
    ok = ok and math.isfinite(number) and (number >= 0 if zero_ok else number > 0)
    if not ok:
        bound = ">= 0" if zero_ok else "positive"
        huge = isinstance(value, int) and not isinstance(value, bool) and number == math.inf
        got = (f"an integer of about {int(value.bit_length() * 0.30103) + 1} digits" if huge
               else repr(value))
        raise ParameterError(f"{owner}.{name} must be finite and {bound}; got {got}")
    return number


@dataclass(frozen=True, kw_only=True)
class ControllerParams:
    """Sampled PID position controller of one axis with feed-forward (zero-order hold).

    ``u_k = kp e_k + kd (v_ref,k - v_k) + ki I_k + kv v_ref,k + ka a_ref,k``,
    ``e_k = r_k - x_k``, ``I_k = I_{k-1} + e_k / rate``.

    Attributes
    ----------
    kp : float
        Position gain [N/m]; > 0.
    kd : float
        Velocity (derivative) gain [N·s/m]; >= 0.
    ki : float
        Integral gain [N/(m·s)]; >= 0 (default 0).
    kv : float
        Velocity feed-forward [N·s/m]; >= 0 (default 0).
    ka : float
        Acceleration feed-forward [kg]; >= 0 (default 0).
    rate : float
        Sampling rate [Hz]; > 0 (default 2000).
    body : int
        Actuated body, 0-based (default 0, the motor).
    sensor : int
        Measured body, 0-based (default: ``body``, a semi-closed loop).
    saturation : float
        Command limit [N] (default inf).
    """

    kp: float
    kd: float
    ki: float = 0.0
    kv: float = 0.0
    ka: float = 0.0
    rate: float = 2000.0
    body: int = 0
    sensor: int | None = None
    saturation: float = math.inf

    def __post_init__(self) -> None:
        _positive("ControllerParams", "kp", self.kp)
        for name in ("kd", "ki", "kv", "ka"):
            _positive("ControllerParams", name, getattr(self, name), zero_ok=True)
        _positive("ControllerParams", "rate", self.rate)
        if not (isinstance(self.saturation, (int, float)) and self.saturation > 0):
            raise ParameterError(f"ControllerParams.saturation must be positive [N] (inf: "
                                 f"none); got {self.saturation!r}")
        if self.sensor is None:
            object.__setattr__(self, "sensor", self.body)
        for name in ("body", "sensor"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 0:
                raise ParameterError(f"ControllerParams.{name} must be a body index >= 0; "
                                     f"got {value!r}")


@dataclass(frozen=True, kw_only=True)
class AxisConfig:
    """One feed axis: its drive (bodies and links, translational) and its controller.

    Attributes
    ----------
    name : str
        Axis name, ``"x"``, ``"y"`` or ``"z"``.
    drive : DriveParams
        Bodies (motor first, table last) and links, without ``feedback``.
    controller : ControllerParams
        The position controller.
    """

    name: str
    drive: DriveParams
    controller: ControllerParams

    def __post_init__(self) -> None:
        n = self.drive.n_bodies
        for key in ("body", "sensor"):
            index = getattr(self.controller, key)
            if index >= n:
                raise ParameterError(f"{self.name}.controller.{key} must name one of the "
                                     f"{n} bodies (counted from 1); got {index + 1}")
        if self.drive.bodies[self.controller.body].locked:
            raise ParameterError(f"{self.name}.controller.body must not be locked; got body "
                                 f"{self.controller.body + 1}")
        if self.drive.feedback is not None or self.drive.smooth:
            raise ParameterError(f"axis {self.name}: give the controller in [{self.name}."
                                 "controller], not [feedback]; LuGre and motor models are not "
                                 "available under a sampled controller")

    @property
    def table(self) -> int:
        """Index of the table (the last body, whose position the contour shows) [-]."""
        return self.drive.n_bodies - 1

    @property
    def mass(self) -> float:
        """Total moving mass of the axis [kg]."""
        return float(sum(b.J for b in self.drive.bodies if not b.locked))


@dataclass(frozen=True, kw_only=True)
class CirclePath:
    """The circular path ``(R cos θ, ±R sin θ)`` with a smooth feed ramp.

    Attributes
    ----------
    radius : float
        Nominal radius R [m]; > 0.
    feed : float
        Tangential speed at constant feed [m/s]; > 0.
    direction : {"ccw", "cw"}
        Direction of travel in the plane.
    revolutions : float
        Turns at constant feed [-]; > 0.
    fs : float
        Record sampling rate [Hz]; > 0.
    start_angle : float
        Angle of the start point from the first plane axis [deg] (default 45: between
        reversals, so the four quadrant crossings lie inside the constant-feed part).
    ramp : float
        Duration of the raised-cosine feed ramp at each end [s]; >= 0.
    plane : {"xy", "yz", "zx"}
        The two axes that draw the circle.
    """

    radius: float
    feed: float
    direction: str = "ccw"
    revolutions: float = 1.0
    fs: float = 1000.0
    start_angle: float = 45.0
    ramp: float = 0.05
    plane: str = "xy"

    def __post_init__(self) -> None:
        for name in ("radius", "feed", "revolutions", "fs"):
            _positive("CirclePath", name, getattr(self, name))
        _positive("CirclePath", "ramp", self.ramp, zero_ok=True)
        if not math.isfinite(self.start_angle):
            raise ParameterError(f"CirclePath.start_angle must be finite [deg]; got "
                                 f"{self.start_angle!r}")
        if self.direction not in ("ccw", "cw"):
            raise ParameterError(f'CirclePath.direction must be "ccw" or "cw"; got '
                                 f"{self.direction!r}")
        if self.plane not in _PLANES:
            raise ParameterError(f"CirclePath.plane must be one of {list(_PLANES)}; got "
                                 f"{self.plane!r}")

    @property
    def axes(self) -> tuple[str, str]:
        """Names of the two axes of the plane."""
        return _PLANES[self.plane]

    @property
    def omega(self) -> float:
        """Angular rate of the path at constant feed, ``feed / radius`` [rad/s]."""
        return self.feed / self.radius

    @property
    def duration(self) -> float:
        """Duration of the path: the two ramps plus the constant feed [s]."""
        return self.constant_feed + 2.0 * self.ramp

    @property
    def constant_feed(self) -> float:
        """Duration of the constant-feed part, ``2π revolutions / omega`` [s]."""
        return 2.0 * math.pi * self.revolutions / self.omega


@dataclass(frozen=True, kw_only=True)
class MeasurementNoise:
    """White Gaussian noise added to the written record.

    Attributes
    ----------
    position : float
        Standard deviation on every position column [m]; >= 0.
    command : float
        Standard deviation on every command column [N]; >= 0.
    seed : int or None
        Seed of ``numpy.random.default_rng``.
    """

    position: float = 0.0
    command: float = 0.0
    seed: int | None = None

    def __post_init__(self) -> None:
        _positive("MeasurementNoise", "position", self.position, zero_ok=True)
        _positive("MeasurementNoise", "command", self.command, zero_ok=True)


@dataclass(frozen=True, kw_only=True)
class ContourConfig:
    """The axes, the path and the measurement noise of a contour test.

    Attributes
    ----------
    axes : mapping of str to AxisConfig
        The configured axes (two or three of x, y, z).
    path : CirclePath
        The circle.
    noise : MeasurementNoise
        Noise of the written record.
    """

    axes: Mapping[str, AxisConfig]
    path: CirclePath
    noise: MeasurementNoise = field(default_factory=MeasurementNoise)

    def __post_init__(self) -> None:
        missing = [a for a in self.path.axes if a not in self.axes]
        if missing:
            raise ParameterError(f"the plane {self.path.plane!r} needs the axes "
                                 f"{list(self.path.axes)}; add [{missing[0]}] tables; got "
                                 f"{sorted(self.axes)}")


def _build(cls, kwargs: dict, where: str):
    try:
        return cls(**kwargs)
    except (ParameterError, TypeError) as exc:
        raise _fail(where, str(exc)) from None


def _axis(name: str, table, source: str) -> AxisConfig:
    table = _check_keys(table, _AXIS_KEYS, name)
    if "controller" not in table:
        raise _fail(f"{name}.controller", "missing: every axis needs a [" + name +
                    ".controller] table with kp and kd")
    drive_doc = {k: table[k] for k in ("body", "link") if k in table}
    drive, _ = parse_drive_config(drive_doc, source=f"{source}: {name}")
    ctl = _check_keys(table["controller"], _CONTROLLER_KEYS, f"{name}.controller")
    for key in ("kp", "kd"):
        if key not in ctl:
            raise _fail(f"{name}.controller", f"missing {key}; add it [N/m or N·s/m]")
    for key in ("body", "sensor"):
        if key in ctl:
            value = ctl[key]
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise _fail(f"{name}.controller.{key}",
                            f"must be a body number >= 1 (counted from 1); got {value!r}")
            ctl[key] = value - 1
    controller = _build(ControllerParams, ctl, f"{name}.controller")
    return _build(AxisConfig, {"name": name, "drive": drive, "controller": controller}, name)


def parse_contour_config(document: Mapping, *, source: str = "config") -> ContourConfig:
    """Build a :class:`ContourConfig` from a parsed TOML mapping.

    Parameters
    ----------
    document : mapping
        The parsed document (tables ``x``, ``y``, optional ``z``, ``path``, ``noise``).
    source : str
        Name at the start of error messages (the file name).

    Returns
    -------
    ContourConfig
        The axes, path and noise.

    Raises
    ------
    ConfigError
        If a key is unknown, a value is missing or out of range; the message names the file
        and the key path.

    Examples
    --------
    >>> doc = {"x": {"body": [{"J": 50.0}], "controller": {"kp": 1e6, "kd": 1e4}},
    ...        "y": {"body": [{"J": 50.0}], "controller": {"kp": 1e6, "kd": 1e4}},
    ...        "path": {"radius": 0.05, "feed": 0.1}}
    >>> cfg = parse_contour_config(doc)
    >>> cfg.path.axes, round(cfg.path.omega, 6)
    (('x', 'y'), 2.0)
    """
    try:
        top = _check_keys(document, _TOP_KEYS, "top level")
        axes = {a: _axis(a, top[a], source) for a in _AXES if a in top}
        if "path" not in top:
            raise _fail("path", "missing: add a [path] table with radius [m] and feed [m/s]")
        path_doc = _check_keys(top["path"], _PATH_KEYS, "path")
        shape = path_doc.pop("shape", "circle")
        if shape != "circle":
            raise _fail("path.shape", f'only "circle" is simulated; got {shape!r}')
        for key in ("radius", "feed"):
            if key not in path_doc:
                raise _fail("path", f"missing {key}; add it ([m] or [m/s])")
        path = _build(CirclePath, path_doc, "path")
        noise = _build(MeasurementNoise, _check_keys(top.get("noise", {}), _NOISE_KEYS, "noise"),
                       "noise")
        return _build(ContourConfig, {"axes": axes, "path": path, "noise": noise},
                      "top level")
    except ConfigError as exc:
        text = str(exc)
        raise ConfigError(text if text.startswith(source) else f"{source}: {text}") from None


def load_contour_config(path: str | Path) -> ContourConfig:
    """Read a contour-test TOML file (see the module docstring for the format).

    Parameters
    ----------
    path : str or Path
        The ``.toml`` file.

    Returns
    -------
    ContourConfig
        The axes, path and noise.

    Raises
    ------
    ConfigError
        If the file cannot be read or parsed or a value is invalid.
    """
    path = Path(path)
    return parse_contour_config(read_toml(path, "contour config"), source=path.name)
