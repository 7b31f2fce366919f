r"""The circular contour test (ISO 230-4, the ball bar) on two feed axes (thesis §1.2.6, §6.1).

Each axis of the plane is a lumped drive (:mod:`driveid.sim.drive_types`: motor, screw
backlash, table; every static friction model the event-located integrator runs) under a
sampled PID position controller with feed-forward (:class:`~driveid.sim.contour_config.
ControllerParams`), following its coordinate of the circle

.. math:: x_{ref} = R\cos\theta(t), \qquad y_{ref} = \pm R\sin\theta(t)

with ``θ' = feed/R`` at constant feed and raised-cosine feed ramps at both ends. The axes are
mechanically independent, so each is simulated on its own by
:func:`~driveid.sim.drive.simulate_drive` with a controller callback (zero-order hold at
``controller.rate``); the contour is the pair of table positions. Friction shows as quadrant
glitches where an axis reverses (the table sticks, the controller's integral winds up), the
backlash as a lost motion across the reversal.

The radial deviation is ``Δr = sqrt(x² + y²) - R`` of the table positions, evaluated over the
constant-feed part. Optional compensation (:class:`AxisCompensation`) adds a friction
feed-forward ``c v_ref + fk_mean sgn(v_ref) + fk_delta`` (thesis 2.155 with the commanded
velocity) and shifts the reference by ``± gap/2`` with the commanded direction (backlash
compensation at reversals).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §1.2.6-1.2.8,
       §6.1.
.. [2] ISO 230-4:2005, Test code for machine tools - Part 4: Circular tests for numerically
       controlled machine tools.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field

import numpy as np

from driveid.errors import ParameterError
from driveid.sim.contour_config import AxisConfig, CirclePath, ContourConfig, MeasurementNoise
from driveid.sim.drive import simulate_drive

__all__ = ["SECONDS_PER_PERIOD", "AxisCompensation", "ContourResult", "circle_reference",
           "closed_loop_gain", "contour_metrics", "simulate_contour"]

_GLITCH_BEFORE = math.radians(10.0)  # a glitch window opens before the reversal [rad]
_GLITCH_AFTER = math.radians(35.0)  # and closes after it, short of the next quadrant [rad]


@dataclass(frozen=True, kw_only=True)
class AxisCompensation:
    """Model-based compensation of one axis: friction feed-forward and backlash offset.

    Attributes
    ----------
    fk_mean, fk_delta : float
        Coulomb friction ``fk_mean sgn(v_ref) + fk_delta`` fed forward [N] (2.155).
    c_mean : float
        Viscous friction fed forward as ``c_mean v_ref`` [N·s/m].
    gap : float
        Total backlash [m]: the reference moves by ``+gap/2`` while the screw pushes the
        table forward and ``-gap/2`` while it pulls it back.
    table_mass : float
        Mass behind the backlash [kg] (default 0). The screw's force is predicted as
        ``table_mass a_ref + c_mean v_ref + fk_mean sgn(v_ref) + fk_delta``; its sign moves
        the backlash offset. With 0 the offset follows the commanded velocity, which is the
        same wherever the table's friction exceeds its inertial force; at high centripetal
        acceleration the table decelerates on its own friction and the contact changes
        sides before the reversal, which only the force sign catches.
    """

    fk_mean: float = 0.0
    fk_delta: float = 0.0
    c_mean: float = 0.0
    gap: float = 0.0
    table_mass: float = 0.0

    def __post_init__(self) -> None:
        for name in ("fk_mean", "fk_delta", "c_mean", "gap", "table_mass"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) \
                    or not math.isfinite(value):
                raise ParameterError(f"AxisCompensation.{name} must be a finite number; "
                                     f"got {value!r}")

    def scaled(self, friction: float) -> AxisCompensation:
        """Return this compensation with the friction terms multiplied by ``friction`` [-].

        Parameters
        ----------
        friction : float
            Factor on fk_mean, fk_delta and c_mean (0.8, 1.2: the ±20 % wrong model).

        Returns
        -------
        AxisCompensation
            The scaled compensation (gap unchanged).
        """
        return AxisCompensation(fk_mean=self.fk_mean * friction,
                                fk_delta=self.fk_delta * friction,
                                c_mean=self.c_mean * friction, gap=self.gap,
                                table_mass=self.table_mass)


def circle_reference(path: CirclePath, t: np.ndarray) -> dict[str, np.ndarray]:
    """Path angle and both axes' reference position, velocity and acceleration.

    Parameters
    ----------
    path : CirclePath
        The circle.
    t : ndarray, shape (n,)
        Times [s].

    Returns
    -------
    dict
        ``theta`` [rad], ``p1, v1, a1`` of the first plane axis and ``p2, v2, a2`` of the
        second [m, m/s, m/s²], each shape (n,).

    Examples
    --------
    >>> from driveid.sim.contour_config import CirclePath
    >>> ref = circle_reference(CirclePath(radius=0.1, feed=0.1, ramp=0.0, start_angle=0.0),
    ...                        np.array([0.0, math.pi / 2]))
    >>> [round(float(v), 12) for v in ref["p1"]], [round(float(v), 12) for v in ref["p2"]]
    ([0.1, 0.0], [0.0, 0.1])
    """
    t = np.asarray(t, dtype=float)
    R, F, Tr, Tc = path.radius, path.feed, path.ramp, path.constant_feed
    w = F / R
    theta = np.empty_like(t)
    rate = np.empty_like(t)
    accel = np.zeros_like(t)
    up, down = t < Tr, t >= Tr + Tc
    mid = ~(up | down)
    if Tr > 0:
        tu = t[up]
        theta[up] = w * (tu / 2 - Tr / (2 * math.pi) * np.sin(math.pi * tu / Tr))
        rate[up] = w * (1 - np.cos(math.pi * tu / Tr)) / 2
        accel[up] = w * math.pi / (2 * Tr) * np.sin(math.pi * tu / Tr)
        td = np.minimum(t[down] - Tr - Tc, Tr)
        theta[down] = w * (Tr / 2 + Tc) + w * (td / 2 + Tr / (2 * math.pi)
                                               * np.sin(math.pi * td / Tr))
        rate[down] = np.where(t[down] - Tr - Tc < Tr, w * (1 + np.cos(math.pi * td / Tr)) / 2,
                              0.0)
        accel[down] = np.where(t[down] - Tr - Tc < Tr,
                               -w * math.pi / (2 * Tr) * np.sin(math.pi * td / Tr), 0.0)
    else:
        theta[down] = w * Tc
        rate[down] = 0.0
    theta[mid] = w * (Tr / 2 + t[mid] - Tr)
    rate[mid] = w
    theta += math.radians(path.start_angle)
    sign = 1.0 if path.direction == "ccw" else -1.0
    c, s = np.cos(theta), np.sin(theta)
    return {"theta": theta,
            "p1": R * c, "v1": -R * s * rate, "a1": -R * c * rate**2 - R * s * accel,
            "p2": sign * R * s, "v2": sign * R * c * rate,
            "a2": sign * (-R * s * rate**2 + R * c * accel)}


def closed_loop_gain(J: float, c: float, controller, omega: float, *,
                     sampled: bool = True) -> complex:
    r"""Closed-loop response ``x/r`` of a linear axis at ``omega`` (the radius check).

    Parameters
    ----------
    J : float
        Moving mass [kg] (one rigid body, no friction, no backlash).
    c : float
        Viscous damping [N·s/m].
    controller : ControllerParams
        Gains, feed-forward and sampling rate.
    omega : float
        Angular frequency [rad/s] (``feed / radius`` on a circle).
    sampled : bool
        True: the sampled-data loop exactly as simulated (plant ``1/(J s² + c s)``
        discretised with a zero-order hold, the discrete PID of ``ControllerParams``), at the
        sampling instants. False: the continuous transfer function
        ``(kp + ki/s + (kd + kv) s + ka s²) / (J s² + c s + kp + ki/s + kd s)``.

    Returns
    -------
    complex
        ``G``: both axes alike, the steady radius is ``R |G|``.

    Notes
    -----
    Sampled: with state ``z_k = (x_k, v_k, I_{k-1})`` the loop is ``z_{k+1} = M z_k + N r_k``
    and the steady phasor ``Z = (e^{jωT} I - M)^{-1} N``, ``G = Z_0``.

    Examples
    --------
    >>> from driveid.sim.contour_config import ControllerParams
    >>> ctl = ControllerParams(kp=2e5, kd=6e3, ki=1e6, rate=1e6)
    >>> a = closed_loop_gain(50.0, 100.0, ctl, 30.0)
    >>> b = closed_loop_gain(50.0, 100.0, ctl, 30.0, sampled=False)
    >>> bool(abs(a - b) < 1e-3)
    True
    """
    kp, kd, ki, kv, ka = (controller.kp, controller.kd, controller.ki, controller.kv,
                          controller.ka)
    if not sampled:
        s = 1j * omega
        return complex((kp + ki / s + (kd + kv) * s + ka * s**2)
                       / (J * s**2 + c * s + kp + ki / s + kd * s))
    from scipy.linalg import expm

    T = 1.0 / controller.rate
    aug = np.zeros((3, 3))
    aug[:2, :2] = np.array([[0.0, 1.0], [0.0, -c / J]]) * T
    aug[1, 2] = T / J
    E = expm(aug)
    Ad, Bd = E[:2, :2], E[:2, 2]
    M = np.zeros((3, 3))
    M[:2, :2] = Ad - np.outer(Bd, [kp + ki * T, kd])
    M[:2, 2] = Bd * ki
    M[2] = [-T, 0.0, 1.0]
    g = (kp + ki * T) + (kd + kv) * 1j * omega - ka * omega**2
    N = np.concatenate([Bd * g, [T]])
    return complex(np.linalg.solve(np.exp(1j * omega * T) * np.eye(3) - M, N)[0])


def _direction(v: np.ndarray) -> np.ndarray:
    """sgn(v) holding the last non-zero sign through exact zeros (the first: the next one)."""
    s = np.sign(v)
    nz = np.flatnonzero(s)
    if nz.size == 0:
        return np.ones_like(v)
    idx = np.maximum.accumulate(np.where(s != 0, np.arange(s.size), 0))
    out = s[idx]
    out[: nz[0]] = s[nz[0]]
    return out


def _axis_run(axis: AxisConfig, path: CirclePath, which: str | None,
              compensation: AxisCompensation | None):
    """One axis under its sampled PID; ``which`` is "1", "2" or None (held at 0)."""
    ctl = axis.controller
    rate, fs = ctl.rate, path.fs
    ratio = max(rate, fs) / min(rate, fs)
    if abs(ratio - round(ratio)) > 1e-9 * ratio:
        raise ParameterError(f"axis {axis.name}: controller.rate / path.fs or its inverse "
                             f"must be an integer; got rate={rate:g} Hz, fs={fs:g} Hz")
    n_ctl = int(math.floor(path.duration * rate + 1e-9)) + 2
    tk = np.arange(n_ctl) / rate
    ref = circle_reference(path, tk)
    if which is None:
        r = vr = ar = np.zeros_like(tk)
    else:
        r, vr, ar = ref["p" + which], ref["v" + which], ref["a" + which]
    ff = ctl.kv * vr + ctl.ka * ar
    if compensation is not None:
        s = _direction(vr)
        friction = compensation.c_mean * vr + compensation.fk_mean * s + compensation.fk_delta
        ff = ff + friction
        side = s if compensation.table_mass <= 0 else _direction(
            compensation.table_mass * ar + friction)
        r = r + 0.5 * compensation.gap * side
    gains = (ctl.kp, ctl.kd, ctl.ki)
    sensor = ctl.sensor
    state = {"integral": 0.0}
    h = 1.0 / rate

    def controller(t, x, vel):
        k = min(int(round(t * rate)), n_ctl - 1)
        e = r[k] - x[sensor]
        state["integral"] += e * h
        return (gains[0] * e + gains[1] * (vr[k] - vel[sensor]) + gains[2] * state["integral"]
                + ff[k])

    # every body starts on the nominal path, the actuated one on its (offset) reference
    x0 = np.full(axis.drive.n_bodies, 0.0 if which is None else ref["p" + which][0])
    x0[ctl.body] = r[0]
    return simulate_drive(axis.drive, duration=path.duration, fs=fs, x0=x0,
                          controller=controller, control_rate=rate,
                          controller_body=ctl.body, saturation=ctl.saturation)


@dataclass(frozen=True)
class ContourResult:
    """A simulated circle test: references, table and motor positions, commands, metrics.

    Attributes
    ----------
    t : ndarray, shape (n,)
        Times [s].
    reference, position, motor, command : dict of str to ndarray, shape (n,)
        Per axis name: reference [m], table position (last body) [m], actuated body position
        [m] and controller command [N].
    path : CirclePath
        The circle.
    metrics : dict
        :func:`contour_metrics` of the table positions.
    compensation : dict of str to AxisCompensation or None
        The compensation simulated, if any.
    """

    t: np.ndarray
    reference: Mapping[str, np.ndarray]
    position: Mapping[str, np.ndarray]
    motor: Mapping[str, np.ndarray]
    command: Mapping[str, np.ndarray]
    path: CirclePath
    metrics: Mapping = field(repr=False)
    compensation: Mapping[str, AxisCompensation] | None = None

    def columns(self, noise: MeasurementNoise | None = None) -> dict[str, np.ndarray]:
        """Return the record columns, with measurement noise if given.

        Parameters
        ----------
        noise : MeasurementNoise, optional
            White noise added to the positions [m] and commands [N] (references exact).

        Returns
        -------
        dict of str to ndarray, shape (n,)
            ``t``, then per axis ``<a>_ref``, then ``<a>``, ``<a>_motor``, ``u_<a>``.
        """
        rng = np.random.default_rng(None if noise is None else noise.seed)
        sp = 0.0 if noise is None else noise.position
        su = 0.0 if noise is None else noise.command
        out = {"t": self.t}
        names = list(self.reference)
        for a in names:
            out[f"{a}_ref"] = self.reference[a]
        for a in names:
            out[a] = self.position[a] + (sp * rng.standard_normal(self.t.size) if sp else 0.0)
        for a in names:
            out[f"{a}_motor"] = self.motor[a] + (sp * rng.standard_normal(self.t.size)
                                                 if sp else 0.0)
        for a in names:
            out[f"u_{a}"] = self.command[a] + (su * rng.standard_normal(self.t.size)
                                               if su else 0.0)
        return out

    def summary(self) -> dict:
        """Return the metrics as a JSON-ready dict (lengths in m, angles in degrees)."""
        m = self.metrics
        return {"radius": self.path.radius, "feed": self.path.feed,
                "plane": self.path.plane, "direction": self.path.direction,
                "radial_error": {"rms": m["rms"], "peak": m["peak"],
                                 "circularity": m["circularity"], "mean": m["mean"]},
                "glitches": list(m["glitches"]), "reversal_spikes": list(m["reversals"])}


def contour_metrics(t: np.ndarray, p1: np.ndarray, p2: np.ndarray, path: CirclePath,
                    *, reference: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Radial deviation, its rms and peak, the quadrant glitches and the reversal spikes.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Times [s] from the start of the path.
    p1, p2 : ndarray, shape (n,)
        Positions of the first and second plane axis [m].
    path : CirclePath
        The nominal circle (centre at the origin).
    reference : tuple of ndarray, shape (n,), optional
        Reference positions of both axes [m]; default the nominal circle at ``t``.

    Returns
    -------
    dict
        ``radial`` (Δr [m], shape (n,)), ``angle`` (measured angle [rad] from the first
        axis, counted in the direction of travel, so "cw" runs count clockwise), ``steady``
        (bool mask of the constant-feed part), ``rms``, ``peak`` (max ``|Δr|``),
        ``circularity`` (max - min), ``mean`` [m] over the constant-feed part;
        ``glitches``: one dict per axis reversal (``axis``, ``t`` [s], ``where_deg`` (angle
        of the glitch's peak), ``height`` [m] (peak of ``Δr`` minus the median, signed),
        ``width_deg`` (above half height)); ``reversals``: per reversal ``axis``, ``t``,
        ``angle_deg`` and ``spike`` [m] (largest change of the axis's following error within
        the glitch window after the reversal).

    Examples
    --------
    >>> from driveid.sim.contour_config import CirclePath
    >>> path = CirclePath(radius=0.05, feed=0.1, ramp=0.0)
    >>> t = np.arange(0.0, path.duration, 1e-3)
    >>> ref = circle_reference(path, t)
    >>> m = contour_metrics(t, 1.001 * ref["p1"], 1.001 * ref["p2"], path)
    >>> round(m["peak"] * 1e6, 3), len(m["glitches"])
    (50.0, 4)
    """
    t = np.asarray(t, float)
    ref = circle_reference(path, t)
    r1, r2 = (ref["p1"], ref["p2"]) if reference is None else reference
    radial = np.hypot(p1, p2) - path.radius
    sign = 1.0 if path.direction == "ccw" else -1.0
    angle = np.arctan2(sign * p2, p1)
    steady = (t >= path.ramp) & (t <= path.ramp + path.constant_feed)
    if not np.any(steady):
        raise ParameterError("the record holds no constant-feed part of the path; record the "
                             "whole path (duration ramp + 2π revolutions/omega)")
    dr = radial[steady]
    base = float(np.median(dr))
    theta = ref["theta"]
    out = {"radial": radial, "angle": angle, "steady": steady,
           "rms": float(np.sqrt(np.mean(dr**2))), "peak": float(np.max(np.abs(dr))),
           "circularity": float(np.max(dr) - np.min(dr)), "mean": float(np.mean(dr)),
           "glitches": [], "reversals": []}
    names = path.axes
    th0, th1 = theta[steady][0], theta[steady][-1]
    for k, (name, vel, err) in enumerate(((names[0], ref["v1"], r1 - p1),
                                          (names[1], ref["v2"], r2 - p2))):
        # axis 1 reverses where sin θ = 0, axis 2 where cos θ = 0
        first = math.ceil((th0 - k * math.pi / 2) / math.pi)
        last = math.floor((th1 - k * math.pi / 2) / math.pi)
        for j in range(first, last + 1):
            tr = j * math.pi + k * math.pi / 2
            window = steady & (theta >= tr - _GLITCH_BEFORE) & (theta <= tr + _GLITCH_AFTER)
            if np.count_nonzero(window) < 3:
                continue
            idx = np.flatnonzero(window)
            dev = radial[idx] - base
            peak = int(np.argmax(np.abs(dev)))
            height = float(dev[peak])
            above = np.abs(dev) >= 0.5 * abs(height)
            lo = hi = peak
            while lo > 0 and above[lo - 1]:
                lo -= 1
            while hi < above.size - 1 and above[hi + 1]:
                hi += 1
            i_rev = int(idx[np.argmin(np.abs(theta[idx] - tr))])
            t_rev = float(t[i_rev])
            out["glitches"].append({
                "axis": name, "t": float(t[idx[peak]]),
                "where_deg": float(np.degrees(angle[idx[peak]]) % 360.0),
                "height": height,
                "width_deg": float(np.degrees(abs(theta[idx[hi]] - theta[idx[lo]]))),
            })
            after = idx[idx >= i_rev]
            change = err[after] - err[i_rev]
            out["reversals"].append({
                "axis": name, "t": t_rev,
                "angle_deg": float(math.degrees(tr) % 360.0),
                "direction": "+" if vel[min(i_rev + 1, vel.size - 1)] > 0 else "-",
                "spike": float(change[np.argmax(np.abs(change))]) if change.size else 0.0,
            })
    out["glitches"].sort(key=lambda g: g["t"])
    out["reversals"].sort(key=lambda g: g["t"])
    return out


#: Measured cost of one control period of one axis (the Python controller call and the
#: integration between calls): 33 µs at 200 kHz on this 2-core machine [s].
SECONDS_PER_PERIOD = 3.5e-5
#: Default budget of control periods (Python controller calls) of one run, all axes [-]:
#: about 6 minutes; the example's circle takes 1.3e4.
DEFAULT_MAX_PERIODS = 10**7


def check_contour_cost(config: ContourConfig,
                       max_periods: float | None = DEFAULT_MAX_PERIODS) -> int:
    """Refuse a circle test whose arrays exceed memory or whose control periods the budget.

    Parameters
    ----------
    config : ContourConfig
        Axes and path: the duration [s] (revolutions, radius, feed, ramps), the record
        rate ``path.fs`` [Hz] and each controller's rate [Hz].
    max_periods : float or None
        Budget of control periods of the run, all axes together [-]; None: none.

    Returns
    -------
    int
        Control periods of the run, all axes [-].

    Raises
    ------
    ParameterError
        Over the memory available or the budget; the message names the estimate and the
        config keys that set it.
    """
    from driveid.io.consistency import check_allocation

    path = config.path
    rate = max(a.controller.rate for a in config.axes.values())
    keys = "[path] revolutions, radius, feed or fs, or [AXIS.controller] rate"
    # the controller's reference arrays (~10 floats a period) and the drive's output
    check_allocation(path.duration * max(rate, path.fs), 10 * 8 * len(config.axes),
                     f"simulate contour: {path.duration:.3g} s at {max(rate, path.fs):.3g} Hz",
                     override=f"lower {keys}")
    periods = sum(math.floor(path.duration * a.controller.rate) + 2
                  for a in config.axes.values())
    if max_periods is not None and periods > max_periods:
        raise ParameterError(
            f"simulate contour: {periods:.3g} control periods ({path.duration:.3g} s at "
            f"{rate:.3g} Hz, {len(config.axes)} axes), over the budget of {max_periods:.3g} "
            f"(CLI --max-periods), about {periods * SECONDS_PER_PERIOD / 60:.3g} min of "
            f"Python controller calls; lower {keys}, or raise the budget")
    return periods


def simulate_contour(config: ContourConfig, *,
                     compensation: Mapping[str, AxisCompensation] | None = None,
                     max_periods: float | None = DEFAULT_MAX_PERIODS) -> ContourResult:
    """Simulate the circle test: every configured axis under its controller.

    Parameters
    ----------
    config : ContourConfig
        Axes, path and noise (noise is applied only by :meth:`ContourResult.columns`).
    compensation : mapping of str to AxisCompensation, optional
        Per axis name, the friction feed-forward and backlash offset to add.
    max_periods : float or None
        Budget of control periods, checked before the run (:func:`check_contour_cost`) [-].

    Returns
    -------
    ContourResult
        References, positions, commands and :func:`contour_metrics`.

    Raises
    ------
    ParameterError
        If the controller rate and record rate are not integer multiples, compensation
        names an axis that is not configured, or the run exceeds memory or ``max_periods``.
    SimulationError
        If an axis chatters (see :func:`~driveid.sim.drive.simulate_drive`).

    Notes
    -----
    An axis off the plane (the third of three) holds its start position 0. The axes are
    mechanically independent, so each runs alone; the cost is about one
    :func:`~driveid.sim.drive.simulate_drive` controller run per axis (the Python callback
    once per control period).

    Examples
    --------
    >>> from driveid.sim.contour_config import parse_contour_config
    >>> axis = {"body": [{"J": 50.0, "c_mean": 100.0}],
    ...         "controller": {"kp": 2e6, "kd": 2e4, "rate": 1000.0}}
    >>> cfg = parse_contour_config({"x": axis, "y": axis, "path": {
    ...     "radius": 0.02, "feed": 0.04, "revolutions": 0.3, "fs": 500.0}})
    >>> res = simulate_contour(cfg)
    >>> sorted(res.position), bool(res.metrics["peak"] < 1e-5)
    (['x', 'y'], True)
    """
    check_contour_cost(config, max_periods)
    path = config.path
    compensation = dict(compensation or {})
    unknown = sorted(set(compensation) - set(config.axes))
    if unknown:
        raise ParameterError(f"compensation names axes {unknown} that the config lacks; "
                             f"configured axes are {sorted(config.axes)}")
    plane = path.axes
    results, refs = {}, {}
    for name, axis in config.axes.items():
        which = "1" if name == plane[0] else "2" if name == plane[1] else None
        results[name] = _axis_run(axis, path, which, compensation.get(name))
    t = results[plane[0]].t
    full = circle_reference(path, t)
    for name in config.axes:
        refs[name] = (full["p1"] if name == plane[0] else full["p2"] if name == plane[1]
                      else np.zeros_like(t))
    position = {a: r.x[config.axes[a].table] for a, r in results.items()}
    motor = {a: r.x[config.axes[a].controller.body] for a, r in results.items()}
    command = {a: np.asarray(r.command, float) for a, r in results.items()}
    metrics = contour_metrics(t, position[plane[0]], position[plane[1]], path,
                              reference=(refs[plane[0]], refs[plane[1]]))
    return ContourResult(t=t, reference=refs, position=position, motor=motor,
                         command=command, path=path, metrics=metrics,
                         compensation=compensation or None)
