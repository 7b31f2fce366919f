r"""What a run of :func:`driveid.sim.drive.simulate_drive` will cost, known before it starts.

The RK4 step of the event-located integrator must resolve the drive's fastest mode (a
stiff backlash contact, a shaft, the feedback gain on a light body, a falling Stribeck
branch), so the samples, grid steps, memory and run time follow from the parameters alone
(issue 28: a contact of ``k = 1e15`` on ``J = 1e-6`` ran past two minutes unannounced).
:func:`estimate_drive_cost` computes them without allocating; :func:`check_drive_cost`
refuses a run over the machine's memory or the step budget in one line naming the
stiffest element and the fix. Re-exported by :mod:`driveid.sim.drive`.
"""

from __future__ import annotations

import dataclasses
import math

from driveid.errors import ParameterError
from driveid.sim.drive_types import BacklashLink, DriveParams, _require

__all__ = ["DriveCost", "DEFAULT_MAX_STEPS", "estimate_drive_cost", "check_drive_cost"]


def _highest_rate(params: DriveParams) -> float:
    """Bound the fastest eigenvalue [1/s], to choose the RK4 step."""
    return _stiffest(params)[0]


def _stiffest(params: DriveParams) -> tuple[float, str]:
    """Bound the fastest eigenvalue [1/s] and name the element that sets it."""
    rate, what = 0.0, "none"
    nb = params.n_bodies
    for i, b in enumerate(params.bodies):
        k, c = b.K, abs(b.c_mean) + abs(b.c_delta)
        parts = [(b.K, f"body {i + 1} (K = {b.K:.3g} on J = {b.J:.3g})")]
        for j in (i - 1, i):
            if 0 <= j < nb - 1 and params.links[j] is not None:
                other = params.bodies[j + 1 if j == i else j]
                scale = 1.0 + b.J / other.J  # relative motion uses the reduced inertia
                k += params.links[j].k * scale
                c += params.links[j].c * scale
                kind = "backlash contact" if isinstance(params.links[j], BacklashLink) \
                    else "shaft"
                parts.append((params.links[j].k * scale,
                              f"link {j + 1} ({kind} k = {params.links[j].k:.3g} between J = "
                              f"{params.bodies[j].J:.3g} and {params.bodies[j + 1].J:.3g})"))
        fb = params.feedback
        if fb is not None and fb.body == i:
            k += abs(fb.P)
            c += abs(fb.D)
            parts.append((abs(fb.P), f"feedback (P = {fb.P:.3g} on J = {b.J:.3g})"))
        c += b.stribeck_slope  # the falling Stribeck branch is a negative damping
        body_rate = max(math.sqrt(k / b.J), c / b.J)
        if body_rate > rate:
            rate = body_rate
            what = (max(parts)[1] if math.sqrt(k / b.J) >= c / b.J
                    else f"damping of body {i + 1} (c = {c:.3g} on J = {b.J:.3g})")
    return rate, what


#: Default budget of RK4 grid steps for one run (``simulate_drive(max_steps=...)``, CLI
#: ``--max-steps``): about 1e9 steps is several minutes to an hour of one core (0.1-1 µs a
#: step and body, docs/performance.md); a longer run is refused before it starts.
DEFAULT_MAX_STEPS = 10**9

#: Rough cost of one RK4 grid step per body [s], for the announced time estimate.
_SECONDS_PER_STEP_BODY = 5e-7


@dataclasses.dataclass(frozen=True)
class DriveCost:
    """What a run of :func:`simulate_drive` will cost, known before it starts.

    Attributes
    ----------
    n_samples : int
        Output samples, ``floor(duration·fs) + 1`` [-].
    n_steps : int
        RK4 grid steps (an upper bound with ``rtol`` strides) [-]; 0 for the exact closed
        form.
    step : float
        Grid step [s]: ``0.2/rate`` for the fastest rate of the drive, no larger than the
        output interval or the feedback delay.
    period : float
        ``2π/rate``, the period of the stiffest mode [s] (inf for none).
    stiffest : str
        The element that sets the rate, e.g. ``"link 1 (backlash contact k = 1e+15 ...)"``.
    memory : float
        Bytes the result and its CSV writer hold at once, an upper estimate [B].
    seconds : float
        Rough run time on one core [s].
    history : float
        Bytes of the feedback's state history (4 rows of 8 B a grid step, plus twice the
        steps of the delay), held during the run [B]; 0 without feedback.
    rings : dict of int to float
        Bytes of each body's frictional-memory ring (0-based body -> 32 B a grid step of
        its lag, Eq. 2.12), held during the run [B]; empty without memory.
    """

    n_samples: int
    n_steps: int
    step: float
    period: float
    stiffest: str
    memory: float
    seconds: float
    history: float = 0.0
    rings: dict = dataclasses.field(default_factory=dict)


def estimate_drive_cost(params: DriveParams, *, duration: float, fs: float = 1000.0,
                        max_step: float | None = None, method: str = "auto") -> DriveCost:
    """Estimate samples, steps, memory and time of a run before it starts (no allocation).

    Parameters
    ----------
    params : DriveParams
        The drive.
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; > 0.
    max_step : float, optional
        RK4 step [s], as :func:`simulate_drive` takes it.
    method : {"auto", "rk4", "exact"}
        As :func:`simulate_drive`; ``"exact"`` and an ``"auto"`` run the closed form
        applies to take no steps.

    Returns
    -------
    DriveCost
        The estimate.

    Raises
    ------
    ParameterError
        If ``duration`` or ``fs`` is not positive and finite.

    Examples
    --------
    >>> from driveid.sim.drive_types import BodyParams
    >>> drive = DriveParams(bodies=(BodyParams(J=1e-6, K=0.0), BodyParams(J=1e-6, K=0.0)),
    ...                     links=(BacklashLink(gap_plus=1e-3, gap_minus=1e-3, k=1e15),))
    >>> cost = estimate_drive_cost(drive, duration=2.0)
    >>> f"{cost.n_steps:.1e}", cost.stiffest.startswith("link 1 (backlash contact")
    ('4.5e+11', True)
    """
    _require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
             "duration must be positive and finite [s]", duration)
    _require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
             "fs must be positive; pass the output sampling rate in Hz", fs)
    nb = params.n_bodies
    n_out = math.floor(duration * fs + 1e-9) + 1
    rate, what = _stiffest(params)
    step = _max_step(params, fs, rate, max_step)
    n_sub = max(1, math.ceil((1.0 / fs) / step - 1e-9))
    exact = (method != "rk4" and nb == 1 and not params.bodies[0].locked
             and params.bodies[0].K > 0 and params.feedback is None
             and params.bodies[0].is_plain_coulomb and not params.smooth)
    n_steps = 0 if exact else (n_out - 1) * n_sub
    # x, v, command, six energy rows, time, an input grid and the CSV writer's two copies
    memory = 8.0 * n_out * (8 * nb + 12)
    seconds = n_steps * nb * _SECONDS_PER_STEP_BODY + n_out * 1e-7 * nb
    history = 0.0
    h = 1.0 / (fs * n_sub)
    fb = params.feedback
    if fb is not None:  # the kernel's history: every grid step, and a ring of the delay
        ring = math.ceil(fb.delay / h - 1e-9) + 3 if fb.delay > 0 else 0
        history = 32.0 * (n_steps + 2 + 2 * ring)
    rings = {i: 32.0 * (math.ceil(b.memory / h - 1e-9) + 3)
             for i, b in enumerate(params.bodies) if b.memory > 0}
    return DriveCost(n_samples=n_out, n_steps=n_steps, step=h,
                     period=2 * math.pi / rate if rate > 0 else math.inf, stiffest=what,
                     memory=memory, seconds=seconds, history=history, rings=rings)


def _max_step(params: DriveParams, fs: float, rate: float, max_step: float | None) -> float:
    if not math.isfinite(rate):  # J = 1e-320: sqrt(k/J) overflows, the step would be 0
        raise ParameterError(
            f"simulate_drive: the drive's fastest mode, {_stiffest(params)[1]}, has no finite "
            "rate (an inertia of nearly 0?); check the values and their SI units")
    if max_step is None:
        max_step = 0.2 / rate if rate > 0 else 1.0 / fs
    _require(isinstance(max_step, (int, float)) and max_step > 0,
             "max_step must be positive [s]", max_step)
    fb = params.feedback
    if fb is not None and fb.delay > 0:
        max_step = min(max_step, fb.delay)
    return max_step


def check_drive_cost(cost: DriveCost, *, duration: float,
                     max_steps: int | None = DEFAULT_MAX_STEPS) -> None:
    """Refuse a run whose memory or step count exceeds the machine or the budget.

    Parameters
    ----------
    cost : DriveCost
        From :func:`estimate_drive_cost`.
    duration : float
        The run's simulated time [s] (for the message).
    max_steps : int or None
        Budget of RK4 grid steps [-]; ``None``: none.

    Raises
    ------
    ParameterError
        If the result would not fit in the available memory, or the run needs more than
        ``max_steps`` steps; the message names the estimate, the stiffest element and the
        fix.
    """
    from driveid.io.consistency import available_memory, check_allocation, format_bytes

    free = available_memory()
    if cost.rings and cost.memory + cost.history + sum(cost.rings.values()) > free:
        # a frictional memory of 1e6 s: "out of memory ... use --t-start", an option
        # simulate drive does not have (fifth hostile campaign)
        body = max(cost.rings, key=cost.rings.get)
        raise ParameterError(
            f"simulate_drive: body {body + 1}'s frictional memory needs a ring of about "
            f"{format_bytes(cost.rings[body])} (its lag in grid steps of {cost.step:.2g} s, "
            f"32 B each), more than the {format_bytes(free)} of memory available; a "
            "frictional memory lasts milliseconds (Hess-Soom: a few ms): lower that "
            "[[body]] memory")
    steps_part = 32.0 * (cost.n_steps + 2)
    if cost.memory + cost.history > free and cost.history > cost.memory \
            and steps_part > 0.5 * cost.history:
        # the grid, not the delay: a stiff element's tiny step (J = 1e-300, K = 1e300)
        raise ParameterError(
            f"simulate_drive: {cost.n_steps:.3g} RK4 steps of {cost.step:.2g} s (the step "
            f"resolves the stiffest mode, {cost.stiffest}, period {cost.period:.2g} s) need "
            f"about {format_bytes(cost.history)} of feedback history, more than the "
            f"{format_bytes(free)} of memory available; check that element's values and SI "
            "units (a J near 0 or a stiffness far above the drive's), or shorten the duration")
    if cost.memory + cost.history > free and cost.history > cost.memory:
        # issue 28: [feedback] delay = 1e6 s allocated its ring in the kernel: "out of memory"
        raise ParameterError(
            f"simulate_drive: the feedback's state history needs about "
            f"{format_bytes(cost.history)} ({cost.n_steps:.3g} grid steps of {cost.step:.2g} s "
            f"and the delay's ring, 32 B a step each), more than the {format_bytes(free)} of "
            "memory available; shorten the feedback delay ([feedback] delay, a few control "
            "periods in a real drive) or the duration")
    check_allocation(cost.n_samples, (cost.memory + cost.history) / cost.n_samples,
                     f"simulate_drive: {duration:g} s at fs = {cost.n_samples / duration:.3g} "
                     f"Hz ({cost.n_samples:.3g} samples)",
                     override="shorten the duration or lower the output rate fs (CLI: "
                              "--duration, [run] fs of the config)")
    if max_steps is not None and cost.n_steps > max_steps:
        raise ParameterError(
            f"simulate_drive: {cost.n_steps:.2g} RK4 steps needed ({duration:g} s at a "
            f"{cost.step:.2g} s step, which resolves the stiffest mode, {cost.stiffest}, "
            f"period {cost.period:.2g} s; a longer step makes RK4 unstable on it), over the "
            f"budget of {max_steps:.2g} steps (max_steps, CLI --max-steps), about "
            f"{_duration_words(cost.seconds)} of work; soften that element (lower k, raise J), "
            "shorten the duration, or raise the budget")


def _duration_words(seconds: float) -> str:
    for unit, size in (("days", 86400.0), ("hours", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            return f"{seconds / size:.3g} {unit}"
    return f"{seconds:.3g} s"
