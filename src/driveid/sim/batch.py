"""Many simulations in one compiled call, for Monte-Carlo studies.

* :func:`simulate_drive_batch` — many lumped drives of one size (the event-located RK4 path
  of :func:`driveid.sim.drive.simulate_drive`, optionally in parallel threads);
* :func:`simulate_free_decay_batch` — many exact 1-DOF free decays with sticking (the closed
  form of :mod:`driveid.sim.oscillator` compiled).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.sim import _kernels as _k
from driveid.sim.drive import (
    DriveParams,
    DriveResult,
    _finish,
    _prepare,
    _require,
    simulate_drive,
)

__all__ = ["FreeDecayBatch", "simulate_drive_batch", "simulate_free_decay_batch"]


def simulate_drive_batch(
    params_list,
    *,
    duration: float,
    fs: float = 1000.0,
    x0=None,
    v0=None,
    torque=None,
    reference=None,
    max_step: float | None = None,
    max_events_per_step: int = 200,
    parallel: bool = False,
) -> list[DriveResult]:
    """Simulate many drives of the same number of bodies in one compiled call (Monte Carlo).

    Parameters
    ----------
    params_list : sequence of DriveParams
        The drives; all with the same number of bodies (links and feedback may differ).
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; > 0.
    x0, v0 : array_like, optional
        Initial positions [rad] and velocities [rad/s]: shape (n_bodies,) for every run or
        (n_runs, n_bodies) (default 0).
    torque : array_like, optional
        External torque [N·m] as in :func:`simulate_drive`, the same for every run.
    reference : array_like, shape (n,), optional
        Feedback reference [rad] at the output times for every run (default each run's
        ``feedback.reference``).
    max_step : float, optional
        Largest RK4 step [s] (default per run as in :func:`simulate_drive`).
    max_events_per_step : int
        Guard against chattering (Zeno) switching inside one step.
    parallel : bool
        Spread the runs over numba's threads (``numba.set_num_threads``); default one
        thread.

    Returns
    -------
    list of DriveResult
        One result per drive, equal to ``simulate_drive(p, ..., method="rk4")``.

    Raises
    ------
    ParameterError
        If the drives differ in their number of bodies or an argument is out of range.
    SimulationError
        If a run chatters (see :func:`simulate_drive`).

    Notes
    -----
    Always the event-located RK4 (for exact 1-DOF decays use
    :func:`simulate_free_decay_batch`). Drives with LuGre friction or a motor model run
    one by one on the smooth integrator. The batch saves the Python overhead of one call
    per run (validation, array set-up, result assembly), not integration work.

    Examples
    --------
    >>> from driveid.sim import BodyParams, DriveParams
    >>> runs = [DriveParams(bodies=(BodyParams(J=1.0, K=k, c_mean=0.3),)) for k in (9., 16.)]
    >>> batch = simulate_drive_batch(runs, duration=1.0, x0=[1.0])
    >>> one = simulate_drive(runs[1], duration=1.0, x0=[1.0], method="rk4")
    >>> bool(np.array_equal(batch[1].x, one.x)), len(batch)
    (True, 2)
    """
    params_list = list(params_list)
    _require(len(params_list) > 0 and all(isinstance(p, DriveParams) for p in params_list),
             "params_list must be a non-empty sequence of DriveParams", type(params_list))
    nb = params_list[0].n_bodies
    bad = [i for i, p in enumerate(params_list) if p.n_bodies != nb]
    if bad:
        raise ParameterError(f"every drive of a batch needs {nb} bodies like the first; "
                             f"drive {bad[0]} has {params_list[bad[0]].n_bodies}")
    n = len(params_list)
    starts = []
    for value in (x0, v0):
        arr = np.asarray(0.0 if value is None else value, dtype=float)
        try:
            starts.append(np.broadcast_to(arr if arr.ndim == 2 else np.broadcast_to(arr, (nb,)),
                                          (n, nb)))
        except ValueError:
            raise ParameterError(f"x0 and v0 must have shape ({nb},) or ({n}, {nb}); got "
                                 f"shape {arr.shape}") from None
    x0s, v0s = starts
    results: list = [None] * n
    runs, idx = [], []
    for i, p in enumerate(params_list):
        kw = dict(duration=duration, fs=fs, x0=x0s[i], v0=v0s[i], torque=torque,
                  reference=reference)
        if p.smooth:
            results[i] = simulate_drive(p, **kw)
            continue
        runs.append(_prepare(p, duration, fs, x0s[i], v0s[i], torque, reference, max_step,
                             max_events_per_step))
        idx.append(i)
    if runs:
        kernel = _k.drive_batch_kernel_parallel if parallel else _k.drive_batch_kernel
        out = kernel(
            np.array([r["y0"] for r in runs]), np.array([r["modes0"] for r in runs]),
            np.array([r["par"] for r in runs]), np.array([r["inp"] for r in runs]),
            np.array([r["abort_limit"] for r in runs]), float(fs), runs[0]["n_out"],
            np.array([r["n_sub"] for r in runs], dtype=np.int64), max_events_per_step)
        for q, (i, run) in enumerate(zip(idx, runs, strict=True)):
            results[i] = _finish(params_list[i], run, *(o[q] for o in out),
                                 max_events_per_step)
    return results


@dataclass(frozen=True)
class FreeDecayBatch:
    """Exact free decays of many 1-DOF parameter sets (:func:`simulate_free_decay_batch`).

    Attributes
    ----------
    t : ndarray, shape (n,)
        Output times [s].
    x : ndarray, shape (n_sets, n)
        Positions [rad or m].
    v : ndarray, shape (n_sets, n) or None
        Velocities [rad/s or m/s]; None unless ``return_velocity=True``.
    stuck_at : ndarray, shape (n_sets,)
        Time from which each body stays stuck [s]; NaN if it is still moving at the end.
    n_reversals : ndarray of int, shape (n_sets,)
        Velocity zeros after the start [-].
    """

    t: np.ndarray
    x: np.ndarray
    v: np.ndarray | None
    stuck_at: np.ndarray
    n_reversals: np.ndarray


_BATCH_FIELDS = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta", "fs_mean", "fs_delta")


def simulate_free_decay_batch(
    *,
    J,
    K,
    c_mean=0.0,
    c_delta=0.0,
    fk_mean=0.0,
    fk_delta=0.0,
    fs_mean=None,
    fs_delta=None,
    x0,
    v0=0.0,
    u0=0.0,
    duration: float,
    fs: float = 1000.0,
    max_reversals: int = 100_000,
    return_velocity: bool = False,
) -> FreeDecayBatch:
    """Exact free decays with stiction for many parameter sets at once (Monte Carlo).

    Parameters
    ----------
    J : array_like
        Mass or inertia [kg or kg·m²], > 0; all parameters broadcast to ``(n_sets,)``.
    K : array_like
        Stiffness [N/m or N·m/rad], > 0.
    c_mean, c_delta : array_like
        Viscous friction ``c_mean + c_delta·sgn(x')`` [N·s/m or N·m·s/rad].
    fk_mean, fk_delta : array_like
        Kinetic friction ``fk_mean·sgn(x') + fk_delta`` [N or N·m]; fk_mean >= 0.
    fs_mean, fs_delta : array_like, optional
        Static friction band ``fs_delta ± fs_mean`` [N or N·m]; default the kinetic values.
    x0, v0 : array_like
        Initial position [m or rad] and velocity [m/s or rad/s].
    u0 : array_like
        Constant applied force [N or N·m] (default 0: free decay).
    duration : float
        Simulated time [s]; > 0.
    fs : float
        Output sampling rate [Hz]; > 0.
    max_reversals : int
        Bound on the segments of one run.
    return_velocity : bool
        Also return the velocities (twice the memory: 1000 runs of 20 s at 1 kHz are 160 MB
        per array).

    Returns
    -------
    FreeDecayBatch
        Positions of every set at ``k/fs``, stick times and reversal counts.

    Raises
    ------
    ParameterError
        If a parameter is out of range (reported with the index of the first bad set).
    SimulationError
        If a run needs more than ``max_reversals`` segments.

    Notes
    -----
    The same exact piecewise closed form as :func:`driveid.sim.simulate_free_decay`
    (thesis 2.136-2.157), compiled; inside a segment the samples follow from the exact
    one-sample transition matrix, so a run costs a few flops per sample.

    Examples
    --------
    >>> b = simulate_free_decay_batch(J=1.0, K=16.0, c_mean=[0.3, 0.4], fk_mean=0.07,
    ...                               x0=1.0, duration=5.0)
    >>> b.x.shape
    (2, 5001)
    """
    _require(isinstance(duration, (int, float)) and 0 < duration < math.inf,
             "duration must be positive and finite [s]", duration)
    _require(isinstance(fs, (int, float)) and 0 < fs < math.inf,
             "fs must be positive; pass the output sampling rate in Hz", fs)
    fk_mean_a = np.asarray(fk_mean, dtype=float)
    fk_delta_a = np.asarray(fk_delta, dtype=float)
    values = [J, K, c_mean, c_delta, fk_mean_a, fk_delta_a,
              fk_mean_a if fs_mean is None else fs_mean,
              fk_delta_a if fs_delta is None else fs_delta, x0, v0, u0]
    try:
        arrays = np.broadcast_arrays(*[np.atleast_1d(np.asarray(a, dtype=float))
                                       for a in values])
    except ValueError:
        raise ParameterError(
            "parameters must broadcast to one shape (n_sets,); got shapes "
            f"{[np.shape(a) for a in values]}"
        ) from None
    arrays = [np.ascontiguousarray(a.ravel()) for a in arrays]
    Ja, Ka, cm, cd, fkm, fkd, fsm, fsd, xa, va, ua = arrays
    for name, a in zip(_BATCH_FIELDS + ("x0", "v0", "u0"), arrays, strict=True):
        bad = ~np.isfinite(a)
        if bad.any():
            i = int(np.argmax(bad))
            raise ParameterError(f"{name} must be finite; set {i} has {float(a[i])!r}")
    for name, a, ok in (("J", Ja, Ja > 0), ("K", Ka, Ka > 0), ("fk_mean", fkm, fkm >= 0),
                        ("fs band", fsm, (fsd + fsm >= fkd + fkm - 1e-12)
                         & (fsd - fsm <= fkd - fkm + 1e-12))):
        if not ok.all():
            i = int(np.argmax(~ok))
            rule = {"J": "positive", "K": "positive (the batch needs a spring)",
                    "fk_mean": ">= 0",
                    "fs band": "wide enough: fs_delta ± fs_mean must enclose fk_delta ± fk_mean"}
            raise ParameterError(f"{name} must be {rule[name]}; set {i} has {float(a[i])!r}")
    par = np.ascontiguousarray(np.stack([Ja, Ka, cm, cd, fkm, fkd, fsd - fsm, fsd + fsm],
                                        axis=1))
    n_out = int(math.floor(duration * fs + 1e-9)) + 1
    x, v, stuck_at, n_rev, ok = _k.free_decay_batch_kernel(
        par, xa, va, ua, float(fs), n_out, int(max_reversals), bool(return_velocity))
    if not ok.all():
        i = int(np.argmax(~ok))
        raise SimulationError(
            f"set {i} needs more than max_reversals={max_reversals} segments before "
            f"t={duration} s; raise max_reversals or add damping/friction"
        )
    return FreeDecayBatch(t=np.arange(n_out) / fs, x=x, v=v if return_velocity else None,
                          stuck_at=stuck_at, n_reversals=n_rev)
