"""Exact free decays with stiction of many 1-DOF parameter sets in one compiled call.

The engine behind ``method="exact"`` of :func:`driveid.sim.drive.simulate_drive` and the
Monte-Carlo path of :mod:`driveid.sim.batch` (which re-exports it): the exact piecewise
closed form of :mod:`driveid.sim.oscillator` (thesis 2.136-2.157) compiled in
:func:`driveid.sim._free_decay_kernel.free_decay_batch_kernel`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from driveid.errors import ParameterError, SimulationError
from driveid.sim import _free_decay_kernel as _k
from driveid.sim.drive_types import _require

__all__ = ["FreeDecayBatch", "simulate_free_decay_batch"]


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


def _buffer(given, name: str, shape: tuple) -> np.ndarray:
    if given is None:
        return np.empty(shape)
    ok = (isinstance(given, np.ndarray) and given.shape == shape and given.dtype == np.float64
          and given.flags.c_contiguous and given.flags.writeable)
    _require(ok, f"{name} must be a writeable C-contiguous float64 array of shape {shape} "
             "(n_sets, floor(duration fs) + 1); allocate it with numpy.empty(shape)",
             getattr(given, "shape", type(given).__name__))
    return given


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
    out: np.ndarray | None = None,
    v_out: np.ndarray | None = None,
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
    out, v_out : ndarray, shape (n_sets, n), optional
        Caller's float64 C-contiguous buffers for the positions [m or rad] and (with
        ``return_velocity``) velocities [m/s or rad/s], ``n = floor(duration fs) + 1``:
        written in place and returned as ``x``, ``v``. Reusing them across a Monte-Carlo
        loop avoids allocating (and page-faulting) the output on every call, which is most
        of the time of a large batch.

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
    x = _buffer(out, "out", (Ja.size, n_out))
    v = (_buffer(v_out, "v_out", (Ja.size, n_out)) if return_velocity
         else np.empty((1, 1)))
    stuck_at, n_rev, ok = _k.free_decay_batch_kernel(
        par, xa, va, ua, float(fs), n_out, int(max_reversals), bool(return_velocity), x, v)
    if not ok.all():
        i = int(np.argmax(~ok))
        raise SimulationError(
            f"set {i} needs more than max_reversals={max_reversals} segments before "
            f"t={duration} s; raise max_reversals or add damping/friction"
        )
    return FreeDecayBatch(t=np.arange(n_out) / fs, x=x, v=v if return_velocity else None,
                          stuck_at=stuck_at, n_reversals=n_rev)
