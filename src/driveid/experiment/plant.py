r"""Plants a PHO campaign drives: the adapter interface, the simulator, a real-time loopback.

The contract (:class:`Plant`)
-----------------------------
A plant performs one *parametric harmonic oscillation* run (thesis §2.2.7, App. B.3.2):

1. hold the axis at the initial displacement ``x0`` [rad or m] (at rest);
2. at ``t = 0`` release it into delayed PD position feedback with reference 0,
   ``u(t) = -P x(t - Δ) - D x'(t - Δ)`` [N·m or N], sampled at ``fs`` [Hz] for
   ``duration`` [s];
3. *safety abort*: if ``|u|`` before saturation exceeds ``abort_limit`` the run stops at
   once (command zeroed), and the returned record ends there with ``meta["aborted"] = True``
   and ``meta["abort_reason"]`` saying when and why.

It returns a :class:`~driveid.io.record.Record` with ``t`` [s] starting at the release,
``x`` the measured position [rad or m], ``u`` the command actually applied (after
saturation) [N·m or N], and ``meta`` holding at least ``P``, ``D``, ``x0``, ``delay`` (loop
delay [s], None if unknown), ``plant`` (name), ``units``, ``aborted`` (bool),
``abort_reason`` (str or None) and ``saturation`` (command limit [N·m or N], None if
none). Hardware users implement :meth:`Plant.run_pd` on their own loop (a real-time
task reading the encoder and writing the amplifier command every ``1/fs``), and set
``name``, ``units`` and ``delay``.

Implementations here:

* :class:`SimulatedPlant` — :func:`driveid.sim.drive.simulate_drive` with PD feedback on
  one body, optional encoder quantisation and noise (:func:`driveid.sim.oscillator.measure`);
* :class:`LoopbackPlant` — a loop paced by the wall clock at ``fs`` against a 1-DOF internal
  model, exercising a real-time path exactly as hardware would (read, compute, write per
  sample).
"""

from __future__ import annotations

import dataclasses
import math
import time
from typing import Protocol, runtime_checkable

import numpy as np

from driveid.errors import ParameterError
from driveid.io.record import MIN_SAMPLES, Record
from driveid.sim.drive import DriveParams, PDFeedback, simulate_drive
from driveid.sim.oscillator import measure
from driveid.sim.presets import preset, preset_units

__all__ = ["Plant", "SimulatedPlant", "LoopbackPlant", "AXIS_UNITS", "resolve_simulated_plant"]

#: Unit names of a record by kind of axis (rotational "rad", translational "m").
AXIS_UNITS = {"rad": {"x": "rad", "u": "N·m", "v": "rad/s"},
          "m": {"x": "m", "u": "N", "v": "m/s"}}


def resolve_simulated_plant(params: DriveParams | str, *, units: str | None, name: str | None,
                            body: int | None, noise_std: float
                            ) -> tuple[DriveParams, str, str, int]:
    """Resolve a simulated plant's drive, units, name and measured body, or refuse them.

    Parameters
    ----------
    params : DriveParams or str
        The drive, or a preset name of :data:`driveid.sim.presets.PRESETS`.
    units : str or None
        "rad" or "m"; default from the preset, else "rad".
    name : str or None
        Plant name; default the preset name or "simulated".
    body : int or None
        Index of the measured body; default the body the feedback drives, else 0.
    noise_std : float
        Position noise standard deviation [rad or m], finite and >= 0.

    Returns
    -------
    tuple
        ``(params, units, name, body)``.

    Raises
    ------
    ParameterError
        Not a drive or preset, unknown units, a body index out of range, bad noise.
    """
    if isinstance(params, str):
        name = params if name is None else name
        units = preset_units(params) if units is None else units
        params = preset(params)
    if not isinstance(params, DriveParams):
        raise ParameterError(
            f"params must be a DriveParams or a preset name; got {type(params).__name__}")
    units = "rad" if units is None else units
    if units not in AXIS_UNITS:
        raise ParameterError(f'units must be "rad" or "m"; got {units!r}')
    if body is None:
        body = params.feedback.body if params.feedback is not None else 0
    if not (isinstance(body, int) and 0 <= body < params.n_bodies):
        raise ParameterError(
            f"body must index one of the {params.n_bodies} bodies; got {body!r}")
    if not (math.isfinite(noise_std) and noise_std >= 0):
        raise ParameterError(f"noise_std must be >= 0 [rad or m]; got {noise_std!r}")
    return params, units, name or "simulated", body


@runtime_checkable
class Plant(Protocol):
    """Adapter interface of a plant for PHO campaigns (see the module notes for the contract).

    Attributes
    ----------
    name : str
        Plant name written into the manifest.
    units : {"rad", "m"}
        Rotational (rad, N·m) or translational (m, N) axis.
    delay : float or None
        Feedback loop delay Δ [s] if known, else None (the analysis then estimates it).
    """

    name: str
    units: str
    delay: float | None

    def run_pd(self, *, P: float, D: float, x0: float, duration: float, fs: float,
               abort_limit: float = math.inf) -> Record:
        """Perform one PD-feedback oscillation released from ``x0``.

        Parameters
        ----------
        P : float
            Proportional gain [N·m/rad or N/m].
        D : float
            Derivative gain [N·m·s/rad or N·s/m] (may be negative).
        x0 : float
            Signed initial displacement [rad or m], held at rest until t = 0.
        duration : float
            Record length [s].
        fs : float
            Sampling (and control) rate [Hz].
        abort_limit : float
            Safety limit on ``|u|`` before saturation [N·m or N]; inf: none.

        Returns
        -------
        Record
            ``t``, ``x``, ``u`` and the ``meta`` of the contract.
        """
        ...


def _check_run_args(P, D, x0, duration, fs, abort_limit) -> None:
    for name, value in (("P", P), ("D", D), ("x0", x0)):
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(
                value):
            raise ParameterError(f"{name} must be a finite number; got {value!r}")
    if not (isinstance(duration, (int, float)) and 0 < duration < math.inf):
        raise ParameterError(f"duration must be positive and finite [s]; got {duration!r}")
    if not (isinstance(fs, (int, float)) and 0 < fs < math.inf):
        raise ParameterError(f"fs must be positive and finite [Hz]; got {fs!r}")
    if not (isinstance(abort_limit, (int, float)) and abort_limit > 0):
        raise ParameterError(
            f"abort_limit must be positive [N·m or N] (inf: none); got {abort_limit!r}")


def _pad(t, x, u, fs):
    """Pad an early-aborted run to MIN_SAMPLES by holding the last position (u = 0)."""
    n = t.size
    if n >= MIN_SAMPLES:
        return t, x, u
    k = MIN_SAMPLES - n
    last = x[-1] if n else 0.0
    t0 = t[-1] if n else -1.0 / fs
    t = np.concatenate([t, t0 + np.arange(1, k + 1) / fs])
    return t, np.concatenate([x, np.full(k, last)]), np.concatenate([u, np.zeros(k)])


class SimulatedPlant:
    """A simulated drive under delayed PD feedback (:func:`driveid.sim.drive.simulate_drive`).

    Parameters
    ----------
    params : DriveParams or str
        The drive, or a preset name of :data:`driveid.sim.presets.PRESETS` (default
        ``"testbed-a"``). Its feedback supplies the delay [s] and saturation [N·m or N];
        its gains are replaced by each run's P, D.
    noise_std : float
        Standard deviation of white position noise [rad or m]; >= 0.
    counts_per_rev : float, optional
        Rotary encoder resolution [counts/rev] (quantum 2π/counts_per_rev rad).
    counts_per_unit : float, optional
        Linear encoder resolution [counts/m].
    seed : int, optional
        Seed of the noise generator (successive runs draw fresh noise).
    body : int, optional
        Actuated and measured body; default the feedback's body (else 0).
    units : {"rad", "m"}, optional
        Axis units; default from the preset, else "rad".
    name : str, optional
        Plant name; default the preset name or ``"simulated"``.

    Notes
    -----
    All unlocked bodies start displaced by ``x0`` (a rigid shift: links unstressed, the
    backlash centred) and at rest; locked bodies stay at 0.

    Examples
    --------
    >>> plant = SimulatedPlant("testbed-a")
    >>> rec = plant.run_pd(P=5.0, D=0.1, x0=0.5, duration=0.5, fs=1000.0)
    >>> rec.meta["P"], round(rec.meta["delay"], 5), rec.n
    (5.0, 0.01377, 501)
    """

    def __init__(self, params: DriveParams | str = "testbed-a", *, noise_std: float = 0.0,
                 counts_per_rev: float | None = None, counts_per_unit: float | None = None,
                 seed: int | None = None, body: int | None = None, units: str | None = None,
                 name: str | None = None) -> None:
        params, units, name, body = resolve_simulated_plant(params, units=units, name=name,
                                                            body=body, noise_std=noise_std)
        fb = params.feedback
        if units == "m" and counts_per_rev is not None:
            raise ParameterError(
                "a translational plant (units m) takes counts_per_unit [counts/m] (CLI: "
                f"--counts-per-metre), not counts_per_rev; got counts_per_rev={counts_per_rev!r}")
        self.params = params
        self.name = name
        self.units = units
        self.body = body
        self.delay = fb.delay if fb is not None else 0.0
        self.saturation = fb.saturation if fb is not None else math.inf
        self.noise_std = float(noise_std)
        self.counts_per_rev = counts_per_rev
        self.counts_per_unit = counts_per_unit
        self._rng = np.random.default_rng(seed)
        # validate the measurement model once, before a campaign starts
        measure(Record(t=np.arange(MIN_SAMPLES) * 1e-3, x=np.zeros(MIN_SAMPLES)),
                noise_std=self.noise_std, counts_per_rev=counts_per_rev,
                counts_per_unit=counts_per_unit)

    def __repr__(self) -> str:
        return (f"SimulatedPlant({self.name!r}, delay={self.delay:g} s, "
                f"noise_std={self.noise_std:g})")

    def run_pd(self, *, P: float, D: float, x0: float, duration: float, fs: float,
               abort_limit: float = math.inf) -> Record:
        """Simulate one PD-feedback oscillation released from ``x0`` (see :class:`Plant`).

        Parameters
        ----------
        P : float
            Proportional gain [N·m/rad or N/m].
        D : float
            Derivative gain [N·m·s/rad or N·s/m].
        x0 : float
            Signed initial displacement [rad or m].
        duration : float
            Record length [s].
        fs : float
            Sampling rate [Hz].
        abort_limit : float
            Safety limit on ``|u|`` before saturation [N·m or N]; inf: none.

        Returns
        -------
        Record
            Measured ``x``, applied command ``u``; ``meta`` per the :class:`Plant` contract.
        """
        _check_run_args(P, D, x0, duration, fs, abort_limit)
        fb = self.params.feedback or PDFeedback(P=P, D=D)
        fb = dataclasses.replace(fb, P=float(P), D=float(D), body=self.body, reference=0.0,
                                 abort_limit=float(abort_limit))
        params = dataclasses.replace(self.params, feedback=fb)
        start = [0.0 if b.locked else float(x0) for b in params.bodies]
        result = simulate_drive(params, duration=duration, fs=fs, x0=start)
        keep = np.isfinite(result.x[self.body])
        t, x, u = _pad(result.t[keep], result.x[self.body][keep], result.command[keep], fs)
        meta = {
            "plant": self.name, "P": float(P), "D": float(D), "x0": float(x0),
            "x0_sign": int(math.copysign(1, x0)), "delay": self.delay,
            "units": dict(AXIS_UNITS[self.units]), "aborted": bool(result.aborted),
            "abort_reason": result.abort_reason,
            "saturation": None if math.isinf(self.saturation) else self.saturation,
            "abort_limit": None if math.isinf(abort_limit) else float(abort_limit),
            "source": "driveid.experiment.SimulatedPlant",
        }
        rec = Record(t=t, x=x, u=u, meta=meta, max_jitter=None)
        return measure(rec, noise_std=self.noise_std, counts_per_rev=self.counts_per_rev,
                       counts_per_unit=self.counts_per_unit, rng=self._rng)


class LoopbackPlant:
    """A test plant whose control loop runs in real time against a 1-DOF internal model.

    Every sample, paced by the wall clock (``time.perf_counter`` deadlines, ``time.sleep``
    in between): read the position, compute the delayed PD command from the readings
    ``delay_samples`` samples ago (velocity by backward difference, as a hardware loop
    would), check the abort limit, saturate, write the command; the internal model then
    advances one sample period. The model ``J x'' + c x' + K x + fk sgn(x') = u`` with
    sticking while ``|u - K x| <= fk`` is integrated with ``substeps`` semi-implicit Euler
    steps per sample.

    Parameters
    ----------
    J : float
        Inertia [kg·m²] or mass [kg]; > 0.
    c : float
        Viscous friction [N·m·s/rad or N·s/m]; >= 0.
    fk : float
        Kinetic (Coulomb) friction [N·m or N]; >= 0.
    K : float
        Stiffness [N·m/rad or N/m]; >= 0.
    delay_samples : int
        Computation delay in whole samples [-]; >= 0 (see Notes for the loop delay).
    saturation : float
        Command limit [N·m or N] (default inf).
    counts_per_rev : float, optional
        Encoder quantisation of the position reading [counts/rev].
    substeps : int
        Integration steps per sample [-].
    units : {"rad", "m"}
        Axis units.
    name : str
        Plant name.

    Notes
    -----
    The record's ``t`` is the nominal sample clock ``k / fs`` (what a hardware loop
    timestamps); the achieved timing goes to ``meta["timing"]``: ``rate`` [Hz] from the
    first to the last tick, ``jitter_std`` and ``jitter_max`` (lateness of a tick after its
    deadline) [s], and ``overruns`` (ticks later than one period). The equivalent
    continuous loop delay is ``(delay_samples + 1/2) / fs``: the command is held over each
    sample period (zero-order hold), which lags half a sample (checked against
    :func:`driveid.sim.drive.simulate_drive` in the tests). It is only known once ``fs``
    is, so the attribute ``delay`` is None and each record's ``meta["delay"]`` holds it.
    """

    def __init__(self, *, J: float = 0.0115355, c: float = 0.0007457, fk: float = 0.109456,
                 K: float = 0.0, delay_samples: int = 2, saturation: float = math.inf,
                 counts_per_rev: float | None = None, substeps: int = 4, units: str = "rad",
                 name: str = "loopback") -> None:
        for key, value in (("J", J), ("c", c), ("fk", fk), ("K", K)):
            positive = key == "J"
            if not (isinstance(value, (int, float)) and math.isfinite(value)
                    and (value > 0 if positive else value >= 0)):
                raise ParameterError(
                    f"{key} must be finite and {'> 0' if positive else '>= 0'}; got {value!r}")
        if not (isinstance(delay_samples, int) and delay_samples >= 0):
            raise ParameterError(f"delay_samples must be an int >= 0; got {delay_samples!r}")
        if not (isinstance(substeps, int) and substeps >= 1):
            raise ParameterError(f"substeps must be an int >= 1; got {substeps!r}")
        if units not in AXIS_UNITS:
            raise ParameterError(f'units must be "rad" or "m"; got {units!r}')
        self.J, self.c, self.fk, self.K = float(J), float(c), float(fk), float(K)
        self.delay_samples = delay_samples
        self.saturation = float(saturation)
        self.quantum = None if counts_per_rev is None else 2 * math.pi / counts_per_rev
        self.substeps = substeps
        self.units = units
        self.name = name
        self.delay = None

    def _advance(self, x: float, v: float, u: float, h: float) -> tuple[float, float]:
        for _ in range(self.substeps):
            applied = u - self.K * x
            if v == 0.0 and abs(applied) <= self.fk:
                continue  # stuck: static friction holds the applied force
            direction = math.copysign(1.0, v if v != 0.0 else applied)
            a = (applied - self.c * v - self.fk * direction) / self.J
            v_new = v + a * h
            if v != 0.0 and v_new * v < 0:
                v_new = 0.0  # the velocity crosses zero inside the step: stop, re-check
            x += v_new * h
            v = v_new
        return x, v

    def run_pd(self, *, P: float, D: float, x0: float, duration: float, fs: float,
               abort_limit: float = math.inf) -> Record:
        """Run the PD loop in real time at ``fs`` (see :class:`Plant`).

        Parameters
        ----------
        P : float
            Proportional gain [N·m/rad or N/m].
        D : float
            Derivative gain [N·m·s/rad or N·s/m].
        x0 : float
            Signed initial displacement [rad or m].
        duration : float
            Record length [s]; it takes that long in wall time.
        fs : float
            Loop rate [Hz].
        abort_limit : float
            Safety limit on ``|u|`` before saturation [N·m or N]; inf: none.

        Returns
        -------
        Record
            Nominal ``t``, read ``x``, written ``u``; ``meta["timing"]`` the achieved rate.
        """
        _check_run_args(P, D, x0, duration, fs, abort_limit)
        n = int(math.floor(duration * fs + 1e-9)) + 1
        period = 1.0 / fs
        h = period / self.substeps
        nd = self.delay_samples
        xs = np.empty(n)
        us = np.empty(n)
        late = np.empty(n)
        x, v = float(x0), 0.0
        aborted, reason, k_end = False, None, n
        start = time.perf_counter()
        for k in range(n):
            deadline = start + k * period
            now = time.perf_counter()
            if deadline > now:
                time.sleep(deadline - now)
                now = time.perf_counter()
            late[k] = now - deadline
            reading = x if self.quantum is None else self.quantum * round(x / self.quantum)
            xs[k] = reading
            # held at x0 before the release: the history before t = 0 is x0 at rest
            j = k - nd
            x_del = xs[j] if j >= 0 else float(x0)
            x_prev = xs[j - 1] if j >= 1 else float(x0)
            command = -P * x_del - D * (x_del - x_prev) * fs
            if abs(command) > abort_limit:
                aborted = True
                reason = (f"|command| = {abs(command):.6g} before saturation exceeded "
                          f"abort_limit={abort_limit:g} at t={k * period:.6g} s")
                us[k] = 0.0
                k_end = k + 1
                break
            command = max(-self.saturation, min(self.saturation, command))
            us[k] = command
            x, v = self._advance(x, v, command, h)
        ticks = late[:k_end]
        elapsed = (start + (k_end - 1) * period + ticks[-1]) - (start + ticks[0])
        timing = {
            "rate": float((k_end - 1) / elapsed) if k_end > 1 and elapsed > 0 else None,
            "jitter_std": float(np.std(ticks)), "jitter_max": float(np.max(ticks)),
            "overruns": int(np.sum(ticks > period)),
        }
        t, xr, ur = _pad(np.arange(k_end) / fs, xs[:k_end], us[:k_end], fs)
        units = dict(AXIS_UNITS[self.units])
        meta = {
            "plant": self.name, "P": float(P), "D": float(D), "x0": float(x0),
            "x0_sign": int(math.copysign(1, x0)), "delay": (nd + 0.5) / fs, "units": units,
            "aborted": aborted, "abort_reason": reason,
            "saturation": None if math.isinf(self.saturation) else self.saturation,
            "abort_limit": None if math.isinf(abort_limit) else float(abort_limit),
            "timing": timing, "source": "driveid.experiment.LoopbackPlant",
        }
        return Record(t=t, x=xr, u=ur, meta=meta)
