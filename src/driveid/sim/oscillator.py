"""Exact free response of the 1-DOF oscillator with asymmetric viscous, kinetic and static friction.

``J x'' + C(x') x' + K x + F_k(x') = u0`` (thesis 2.136, 2.155-2.157) is linear while the
velocity keeps its sign, so the response is a chain of closed-form segments (2.142-2.154)
joined at the velocity zeros, where static friction decides between reversal and sticking
(2.137, 2.138). Every segment end is computed in closed form, so the result is exact to
round-off at any sample time.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass, field

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.io.record import Record

__all__ = [
    "OscillatorParams",
    "FreeDecay",
    "simulate_free_decay",
    "measure",
]


@dataclass(frozen=True, kw_only=True)
class OscillatorParams:
    """Parameters of ``J x'' + C(x') x' + K x + F_k(x') = u`` (thesis 2.136, 2.155).

    Attributes
    ----------
    J : float
        Mass [kg] or inertia [kg·m²]; > 0.
    K : float
        Stiffness [N/m or N·m/rad]; >= 0 (0: no spring, thesis 2.149).
    c_mean, c_delta : float
        Viscous friction ``C = c_mean + c_delta·sgn(x')`` [N·s/m or N·m·s/rad]. Either branch
        may be negative (an energy source, as under negative derivative feedback).
    fk_mean, fk_delta : float
        Kinetic friction ``F_k = fk_mean·sgn(x') + fk_delta`` [N or N·m]; fk_mean >= 0.
    fs_mean, fs_delta : float or None
        Static friction: the body stays stuck while the applied force lies in
        ``[fs_delta - fs_mean, fs_delta + fs_mean]`` [N or N·m]. ``None`` (default) takes the
        kinetic values. The stuck band must contain the kinetic band.
    """

    J: float
    K: float
    c_mean: float = 0.0
    c_delta: float = 0.0
    fk_mean: float = 0.0
    fk_delta: float = 0.0
    fs_mean: float | None = None
    fs_delta: float | None = None

    def __post_init__(self) -> None:
        for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
            value = getattr(self, name)
            if not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ParameterError(f"{name} must be a finite number; got {value!r}")
        if self.J <= 0:
            raise ParameterError(f"J must be positive (mass or inertia); got {self.J!r}")
        if self.K < 0:
            raise ParameterError(f"K must be >= 0 (stiffness); got {self.K!r}")
        if self.fk_mean < 0:
            raise ParameterError(
                f"fk_mean must be >= 0 (Coulomb friction magnitude); got {self.fk_mean!r}"
            )
        fs_mean = self.fk_mean if self.fs_mean is None else float(self.fs_mean)
        fs_delta = self.fk_delta if self.fs_delta is None else float(self.fs_delta)
        object.__setattr__(self, "fs_mean", fs_mean)
        object.__setattr__(self, "fs_delta", fs_delta)
        eps = 1e-12 * max(1.0, abs(self.fk_mean) + abs(self.fk_delta))
        if fs_delta + fs_mean < self.fk_delta + self.fk_mean - eps or (
            fs_delta - fs_mean > self.fk_delta - self.fk_mean + eps
        ):
            raise ParameterError(
                "static friction must hold at least the kinetic friction in each direction: "
                f"need fs_delta ± fs_mean to enclose fk_delta ± fk_mean; got fs_mean={fs_mean}, "
                f"fs_delta={fs_delta}, fk_mean={self.fk_mean}, fk_delta={self.fk_delta}"
            )

    def damping(self, direction: int) -> float:
        """Viscous coefficient for motion in ``direction`` (+1 or -1) [N·s/m or N·m·s/rad]."""
        return self.c_mean + self.c_delta * direction

    def kinetic(self, direction: int) -> float:
        """Signed kinetic friction force for motion in ``direction`` [N or N·m]."""
        return self.fk_mean * direction + self.fk_delta

    @property
    def omega0(self) -> float:
        """Undamped natural frequency sqrt(K/J) [rad/s] (2.145)."""
        return math.sqrt(self.K / self.J)

    def zeta(self, direction: int) -> float:
        """Damping ratio C/(2 sqrt(JK)) for ``direction`` [-] (2.150); nan when K = 0."""
        if self.K == 0:
            return math.nan
        return self.damping(direction) / (2.0 * math.sqrt(self.J * self.K))


@dataclass(frozen=True)
class FreeDecay:
    """An exact free response and its events.

    Attributes
    ----------
    record : Record
        Sampled response: ``t`` [s], ``x``, ``v`` and the constant ``u``; built (and
        validated) on first access, which costs more than the simulation itself.
    params : OscillatorParams
        The simulated system.
    reversal_t, reversal_x : ndarray
        Times [s] and positions of every velocity zero (the exact peaks), including the
        initial state when it starts at rest and a final stuck one.
    stuck_at : float or None
        Time [s] from which the body stays stuck, ``None`` if it never sticks.
    """

    params: OscillatorParams
    reversal_t: np.ndarray
    reversal_x: np.ndarray
    stuck_at: float | None
    segments: tuple = field(repr=False, default=())
    _columns: tuple = field(repr=False, compare=False, default=())

    @functools.cached_property
    def record(self) -> Record:
        """The sampled response as a :class:`~driveid.io.record.Record` (built once)."""
        t, x, v, u, meta = self._columns
        return Record(t=t, x=x, v=v, u=u, meta=meta, max_jitter=None)

    @property
    def n_reversals(self) -> int:
        """Number of velocity zeros after the start [-]."""
        return int(self.reversal_t.size)


def _segment_response(tau, y0, v0, sigma, w0sq):
    """Position offset and velocity after ``tau`` of ``y'' + 2σ y' + ω0² y = 0``.

    Uses the unified form (2.142, 2.151, 2.154): ``y = e^{-στ}[y0 C + (v0 + σ y0) S]`` with
    C, S the cos/sin (underdamped), cosh/sinh (overdamped) or 1, τ (critical) kernels, written
    with Taylor series near critical damping so that no case loses accuracy.
    """
    tau = np.asarray(tau, dtype=float)
    w2 = w0sq - sigma * sigma
    z = w2 * tau * tau
    small = np.abs(z) < 1e-3
    root = math.sqrt(abs(w2))
    with np.errstate(over="ignore", invalid="ignore"):
        if w2 > 0:
            c_big, s_big = np.cos(root * tau), np.sin(root * tau) / root
        elif w2 < 0:
            c_big, s_big = np.cosh(root * tau), np.sinh(root * tau) / root
        else:
            c_big, s_big = np.ones_like(tau), tau.copy()
    # series of cos(√z)/cosh and sin(√z)/√z to z^4: error < 1e-15 for |z| < 1e-3
    c_small = 1 - z / 2 * (1 - z / 12 * (1 - z / 30 * (1 - z / 56)))
    s_small = tau * (1 - z / 6 * (1 - z / 20 * (1 - z / 42 * (1 - z / 72))))
    c = np.where(small, c_small, c_big)
    s = np.where(small, s_small, s_big)
    decay = np.exp(-sigma * tau)
    y = decay * (y0 * c + (v0 + sigma * y0) * s)
    v = decay * (v0 * c - (sigma * v0 + w0sq * y0) * s)
    return y, v


def _segment_end(tau, y0, v0, sigma, w0sq):
    """Position offset after ``tau`` [s], as :func:`_segment_response` but for one float.

    Scalar ``math`` instead of numpy: the event loop calls it once a segment, where a numpy
    call on one element cost more than the segment's samples.
    """
    w2 = w0sq - sigma * sigma
    z = w2 * tau * tau
    if abs(z) < 1e-3:
        c = 1 - z / 2 * (1 - z / 12 * (1 - z / 30 * (1 - z / 56)))
        s = tau * (1 - z / 6 * (1 - z / 20 * (1 - z / 42 * (1 - z / 72))))
    elif w2 > 0:
        root = math.sqrt(w2)
        c, s = math.cos(root * tau), math.sin(root * tau) / root
    else:
        root = math.sqrt(-w2)
        try:
            c, s = math.cosh(root * tau), math.sinh(root * tau) / root
        except OverflowError:
            c = s = math.inf
    try:
        return math.exp(-sigma * tau) * (y0 * c + (v0 + sigma * y0) * s)
    except OverflowError:  # pragma: no cover - tau is finite and the motion decays here
        return math.inf


def _time_to_rest(y0, v0, sigma, w0sq):
    """First τ > 0 with zero velocity for the spring case (K > 0); inf if none."""
    den = sigma * v0 + w0sq * y0
    w2 = w0sq - sigma * sigma
    if v0 == 0.0:
        # starting at rest: the next zero is half a damped period later (underdamped only)
        return math.pi / math.sqrt(w2) if w2 > 0 else math.inf
    if w2 > 0:
        root = math.sqrt(w2)
        theta = math.atan2(root * v0, den) % math.pi
        return (theta if theta > 0 else math.pi) / root
    if den == 0.0:
        return math.inf
    g = v0 / den
    if g <= 0:
        return math.inf
    if w2 == 0.0:
        return g
    root = math.sqrt(-w2)
    if root * g >= 1.0:
        return math.inf
    return math.atanh(root * g) / root


def _springless(tau, x0, v0, J, C, F):
    """Position and velocity after ``tau`` of ``J x'' + C x' = F`` (K = 0, thesis 2.149)."""
    tau = np.asarray(tau, dtype=float)
    if C == 0.0:
        return x0 + v0 * tau + 0.5 * F / J * tau**2, v0 + F / J * tau
    rate = C / J
    v_inf = F / C
    # -expm1(-rate τ)/rate keeps full accuracy for small rate·τ
    gain = -np.expm1(-rate * tau) / rate
    return x0 + v_inf * tau + (v0 - v_inf) * gain, v_inf + (v0 - v_inf) * np.exp(-rate * tau)


def _springless_time_to_rest(v0, J, C, F):
    if v0 == 0.0:
        return math.inf
    if C == 0.0:
        tau = -v0 * J / F if F != 0 else math.inf
        return tau if tau > 0 else math.inf
    v_inf = F / C
    ratio = v_inf / (v_inf - v0)
    if not 0 < ratio < 1:
        return math.inf
    return -math.log(ratio) / (C / J)


def simulate_free_decay(
    params: OscillatorParams,
    *,
    x0: float,
    v0: float = 0.0,
    u0: float = 0.0,
    duration: float,
    fs: float = 1000.0,
    t: np.ndarray | None = None,
    max_reversals: int = 1_000_000,
) -> FreeDecay:
    """Simulate the exact free (or constant-force) response with true sticking.

    Parameters
    ----------
    params : OscillatorParams
        The system.
    x0, v0 : float
        Initial position [m or rad] and velocity [m/s or rad/s] at t = 0.
    u0 : float
        Constant applied force [N or N·m] (0: free decay).
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; ignored when ``t`` is given.
    t : ndarray, shape (n,), optional
        Arbitrary increasing output times [s] within ``[0, duration]``.
    max_reversals : int
        Safety bound on the number of segments (undamped motion reverses forever).

    Returns
    -------
    FreeDecay
        Sampled record (``t``, ``x``, ``v``, ``u``), exact reversal events, stick time.

    Raises
    ------
    ParameterError
        If ``duration`` or ``fs`` is not positive, or ``t`` is not increasing.
    SimulationError
        If more than ``max_reversals`` segments would be needed.

    Notes
    -----
    Between velocity zeros the direction ``s`` is fixed and, with ``y = x - x_eq(s)``,
    ``x_eq(s) = (u0 - fk_mean·s - fk_delta)/K``, the motion obeys
    ``y'' + 2σ_s y' + ω0² y = 0`` with ``σ_s = C_s/(2J)`` (2.140-2.143, 2.156, 2.157). At a
    velocity zero the body sticks if the applied force ``u0 - K x`` lies in the static band
    ``[fs_delta - fs_mean, fs_delta + fs_mean]`` (2.137, 2.138), else it moves in the
    direction of the net force.

    On the uniform grid of ``fs`` with ``K > 0`` the samples come from the compiled kernel of
    :func:`driveid.sim.free_decay_batch.simulate_free_decay_batch` (the same closed form,
    each segment's samples by its exact one-sample transition matrix: agreement to about
    1e-14 of the amplitude); the events always come from the loop here. ``record`` is built
    when first read.

    Examples
    --------
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.07)
    >>> sim = simulate_free_decay(p, x0=1.0, duration=5.0)
    >>> round(float(sim.reversal_x[1]), 6)  # first peak: exact closed form
    -0.880528
    """
    if not (isinstance(duration, (int, float)) and duration > 0):
        raise ParameterError(f"duration must be positive [s]; got {duration!r}")
    uniform = t is None
    if uniform:
        if not fs > 0:
            raise ParameterError(f"fs must be positive; pass the sampling rate in Hz; got {fs!r}")
        n = int(math.floor(duration * fs + 1e-9)) + 1
        t = np.arange(n) / fs
    else:
        t = np.asarray(t, dtype=float)
        if t.ndim != 1 or t.size == 0 or np.any(np.diff(t) <= 0):
            raise ParameterError("t must be a non-empty increasing 1-D array of times [s]")
    J, K = params.J, params.K
    # the compiled kernel samples the uniform grid (issue 28: the numpy evaluation per
    # segment and sample made one run 27x slower than the same closed form compiled)
    compiled = uniform and K > 0
    x_out = np.empty_like(t)
    v_out = np.empty_like(t)
    rev_t: list[float] = []
    rev_x: list[float] = []
    segments = []
    t_now, x_now, v_now = 0.0, float(x0), float(v0)
    stuck_at = None
    for _ in range(max_reversals):
        if v_now == 0.0:
            applied = u0 - K * x_now
            rev_t.append(t_now)
            rev_x.append(x_now)
            if params.fs_delta - params.fs_mean <= applied <= params.fs_delta + params.fs_mean:
                stuck_at = t_now
                segments.append((t_now, math.inf, 0, x_now, 0.0))
                break
            direction = 1 if applied > params.fs_delta else -1
        else:
            direction = 1 if v_now > 0 else -1
        C = params.damping(direction)
        F = u0 - params.kinetic(direction)
        if K > 0:
            x_eq = F / K
            sigma, w0sq = C / (2 * J), K / J
            tau = _time_to_rest(x_now - x_eq, v_now, sigma, w0sq)
        else:
            tau = _springless_time_to_rest(v_now if v_now else 0.0, J, C, F)
            if v_now == 0.0:
                # starting from rest with K = 0: accelerate; velocity returns to zero only
                # if the force opposes the motion, which it cannot after breakaway
                tau = math.inf
        t_end = t_now + tau
        segments.append((t_now, t_end, direction, x_now, v_now))
        if not compiled:
            # samples in [t_now, t_end): index ranges, not masks, keep a segment O(its samples)
            i0 = int(np.searchsorted(t, t_now, "left"))
            i1 = int(np.searchsorted(t, t_end, "left")) if math.isfinite(t_end) else t.size
            mask = slice(i0, i1)
            if i1 > i0 and K > 0:
                y, v = _segment_response(t[mask] - t_now, x_now - x_eq, v_now, sigma, w0sq)
                x_out[mask], v_out[mask] = y + x_eq, v
            elif i1 > i0:
                x_out[mask], v_out[mask] = _springless(t[mask] - t_now, x_now, v_now, J, C, F)
        if not math.isfinite(t_end) or t_end > t[-1]:
            break
        if K > 0:
            x_now = _segment_end(tau, x_now - x_eq, v_now, sigma, w0sq) + x_eq
        else:
            x_now = float(_springless(tau, x_now, v_now, J, C, F)[0])
        t_now, v_now = t_end, 0.0
    else:
        raise SimulationError(
            f"more than max_reversals={max_reversals} velocity reversals before "
            f"t={duration} s; shorten the duration or add damping/friction"
        )
    if compiled:
        _sample_compiled(params, x0, v0, u0, fs, max_reversals, x_out, v_out)
    elif stuck_at is not None:
        rest = slice(int(np.searchsorted(t, stuck_at, "left")), t.size)
        x_out[rest], v_out[rest] = x_now, 0.0
    meta = {
        "source": "driveid.sim.simulate_free_decay",
        "params": {k: getattr(params, k) for k in params.__dataclass_fields__},
        "x0": x0,
        "v0": v0,
        "units": {"u": "N·m", "x": "rad", "v": "rad/s"},
    }
    u_out = np.full_like(t, u0)
    for column in (t, x_out, v_out, u_out):  # read-only and owning: the Record wraps them
        column.setflags(write=False)
    return FreeDecay(
        params=params,
        reversal_t=np.array(rev_t),
        reversal_x=np.array(rev_x),
        stuck_at=stuck_at,
        segments=tuple(segments),
        _columns=(t, x_out, v_out, u_out, meta),
    )


def _sample_compiled(params, x0, v0, u0, fs, max_reversals, x_out, v_out) -> None:
    """Fill x_out and v_out, shape (n,), on the grid k/fs with the compiled closed form."""
    from driveid.sim import _free_decay_kernel as _fk

    par = np.array([[params.J, params.K, params.c_mean, params.c_delta, params.fk_mean,
                     params.fk_delta, params.fs_delta - params.fs_mean,
                     params.fs_delta + params.fs_mean]])
    n = x_out.size
    _, _, ok = _fk.free_decay_batch_kernel(
        par, np.array([float(x0)]), np.array([float(v0)]), np.array([float(u0)]), float(fs),
        n, int(max_reversals) + 1, True, x_out.reshape(1, n), v_out.reshape(1, n))
    if not ok[0]:  # pragma: no cover - the event loop above raises first
        raise SimulationError(f"more than max_reversals={max_reversals} velocity reversals")


def measure(
    record: Record,
    *,
    noise_std: float = 0.0,
    counts_per_rev: float | None = None,
    counts_per_unit: float | None = None,
    rng: np.random.Generator | int | None = None,
) -> Record:
    """Apply a measurement model to the position: Gaussian noise, then encoder quantisation.

    Parameters
    ----------
    record : Record
        Exact record.
    noise_std : float
        Standard deviation of additive white Gaussian noise [m or rad]; >= 0.
    counts_per_rev : float, optional
        Rotary encoder resolution [counts/rev]: quantum 2π/counts_per_rev [rad].
    counts_per_unit : float, optional
        Linear encoder resolution [counts/m]: quantum 1/counts_per_unit [m].
    rng : Generator or int, optional
        Random generator or seed for the noise.

    Returns
    -------
    Record
        The measured record (``x`` replaced, ``v`` dropped: an encoder gives no velocity),
        with the model in ``meta["measurement"]``.

    Raises
    ------
    ParameterError
        If noise_std < 0, a resolution is not positive, or both resolutions are given.
    """
    if noise_std < 0:
        raise ParameterError(f"noise_std must be >= 0; got {noise_std!r}")
    if counts_per_rev is not None and counts_per_unit is not None:
        raise ParameterError("give counts_per_rev (rotary) or counts_per_unit (linear), not both")
    quantum = None
    for name, value, scale in (
        ("counts_per_rev", counts_per_rev, 2 * math.pi),
        ("counts_per_unit", counts_per_unit, 1.0),
    ):
        if value is not None:
            if not value > 0:
                raise ParameterError(f"{name} must be positive [counts]; got {value!r}")
            quantum = scale / value
    x = np.array(record.x, dtype=float)
    if noise_std > 0:
        x = x + np.random.default_rng(rng).normal(0.0, noise_std, x.size)
    if quantum is not None:
        x = quantum * np.round(x / quantum)
    meta = dict(record.meta)
    meta["measurement"] = {"noise_std": noise_std, "quantum": quantum}
    return Record(t=record.t, x=x, u=record.u, meta=meta, max_jitter=record.max_jitter)
