"""Many simulations in one call, for Monte-Carlo studies.

* :func:`simulate_drive_batch` — many lumped drives of one size (the event-located RK4 path
  of :func:`driveid.sim.drive.simulate_drive`, optionally in parallel threads);
* :func:`simulate_free_decay_batch` — many exact 1-DOF free decays with sticking (the closed
  form of :mod:`driveid.sim.oscillator` compiled; defined in
  :mod:`driveid.sim.free_decay_batch`, re-exported here).
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor

import numba
import numpy as np

from driveid.errors import ParameterError
from driveid.sim.drive import _finish, _prepare, _run_kernel, simulate_drive
from driveid.sim.drive_types import DriveParams, DriveResult, _require
from driveid.sim.free_decay_batch import FreeDecayBatch, simulate_free_decay_batch

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
    rtol: float | None = None,
    max_events_per_step: int = 200,
    parallel: bool = False,
) -> list[DriveResult]:
    """Simulate many drives of the same number of bodies in one call (Monte Carlo).

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
        RK4 step [s] (default per run as in :func:`simulate_drive`).
    rtol : float, optional
        Step-size control as in :func:`simulate_drive` (default ``None``: every step).
    max_events_per_step : int
        Guard against chattering (Zeno) switching inside one step.
    parallel : bool
        Run the drives in ``numba.get_num_threads()`` threads (set with
        ``numba.set_num_threads`` or ``NUMBA_NUM_THREADS``); default one thread.

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
    one by one on the smooth integrator. The batch saves no integration work over a loop of
    :func:`simulate_drive` calls, only their per-call checks; ``parallel`` spreads it over
    cores.

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
                             max_events_per_step, rtol))
        idx.append(i)
    if runs:
        def kernel(run):
            return _run_kernel(run, max_events_per_step)

        if parallel and len(runs) > 1:
            # the kernel releases the GIL; threads rather than a compiled parallel loop,
            # which would link (and compile) a second copy of the kernel
            pool = ThreadPoolExecutor(min(numba.get_num_threads(), len(runs)))
            try:
                outs = list(pool.map(kernel, runs))
            finally:  # on Ctrl-C only the runs in progress finish, the queued ones are dropped
                pool.shutdown(wait=True, cancel_futures=True)
        else:
            outs = [kernel(run) for run in runs]
        for i, run, out in zip(idx, runs, outs, strict=True):
            results[i] = _finish(params_list[i], run, *out[:8], max_events_per_step)
    return results
