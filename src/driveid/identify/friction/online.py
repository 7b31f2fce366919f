r"""Online tracking of inertia and friction: exponentially weighted recursive least squares.

The inverse model of the drive (thesis Eq. (2.155) with the asymmetric friction of §2.2.5,
DESIGN.md sign conventions), linear in the parameters while the axis moves,

.. math::

    u = J\,a + c_{mean}\,v + c_{delta}\,|v| + fk_{mean}\,\mathrm{sgn}\,v + fk_{delta}
        \;[+\,K x],

is fitted recursively with exponential forgetting, so that the estimate follows friction
that drifts (warm-up, lubrication, wear: the online identification of thesis §6.1).

Why recursive least squares with forgetting (not a Kalman filter)
-----------------------------------------------------------------
Both give the same estimator family; RLS with forgetting is a Kalman filter whose process
noise is proportional to the current covariance. It needs one setting with a physical
meaning — the *memory* ``T_mem`` [s], the time constant of the exponential data window —
instead of a ``p × p`` process-noise matrix whose entries have to be matched to the scale of
each parameter. It also keeps its covariance exact for the weighted estimator (below).

The rule for the forgetting factor
----------------------------------
``λ = exp(-Δt / T_mem)`` per sample with ``T_mem = drift_time / 10`` by default, where
``drift_time`` [s] is the expected time constant of the drift. An exponential window has
its centroid ``T_mem`` in the past, so on a drift ``θ(t)`` the estimate lags by about
``T_mem`` (bias ``≈ T_mem · dθ/dt``); for a first-order rise of ``Δθ`` with time constant
``τ`` the bias is at most ``Δθ/10`` at ``T_mem = τ/10`` and decays with the rise. Shorter
memories trade that lag for variance ``∝ 1/T_mem``. The lag is reported (``lag`` = T_mem).

Streaming in bounded memory
---------------------------
The record is consumed as a generator of chunks. Each chunk's regressor rows ``Φ`` are
built with vectorised numpy, and the sufficient statistics are updated *per block* of
``block`` samples: ``R ← λ^n R + ΦᵀΦ``, ``r ← λ^n r + Φᵀy``, ``S ← λ^{2n} S + ΦᵀΦ``;
``θ = R⁻¹ r``. Within a block the weights are constant (a block of 0.1 s against a memory of
minutes changes nothing measurable); the state is ``O(p²)`` plus one output row per
``decimate`` blocks, whatever the record length. The covariance of the weighted estimate
under white equation error of variance σ² is the sandwich ``σ² R⁻¹ S R⁻¹`` (σ² is the
exponentially weighted mean squared residual); bands are ``±2σ``.

Samples with ``|v| < v_min`` are skipped (sticking and reversals, where the sign regressor
is wrong and the static friction acts, thesis §2.1.1), and so are samples whose
differentiation stencil straddles a reversal (the acceleration jumps there by ``2 fk/J``).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       Eq. (2.155), §6.1.
.. [2] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999,
       §11.2 (recursive least squares with forgetting, its Kalman-filter interpretation).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Iterator
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np

from driveid.errors import IdentificationError, ParameterError, RecordError
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.io.record import Record

__all__ = ["TrackResult", "forgetting_factor", "track_friction", "chunks_of"]

#: Parameter names in regressor order (DESIGN.md); ``K`` is appended with ``stiffness``.
PARAMETERS = ("J", "c_mean", "c_delta", "fk_mean", "fk_delta")


def forgetting_factor(*, fs: float, drift_time: float, ratio: float = 10.0) -> float:
    """Per-sample forgetting factor of the documented rule ``T_mem = drift_time / ratio``.

    Parameters
    ----------
    fs : float
        Sampling rate [Hz].
    drift_time : float
        Expected time constant of the parameter drift [s].
    ratio : float
        Drift time over memory [-], > 1 (10: lag bias at most a tenth of the drift).

    Returns
    -------
    float
        ``λ = exp(-1 / (fs · T_mem))`` [-].

    Raises
    ------
    ParameterError
        On a non-positive argument.

    Examples
    --------
    >>> round(forgetting_factor(fs=1000.0, drift_time=600.0), 9)
    0.999983333
    """
    for name, value in (("fs", fs), ("drift_time", drift_time), ("ratio", ratio)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number; got {value!r}")
    return math.exp(-ratio / (fs * drift_time))


@dataclass(frozen=True, kw_only=True)
class TrackResult:
    """Parameter trajectories of :func:`track_friction`.

    Attributes
    ----------
    t : ndarray, shape (m,)
        Time stamps of the outputs (end of each output block) [s].
    names : tuple of str
        Parameter names (DESIGN.md).
    units : mapping
        Unit per parameter.
    values : ndarray, shape (m, p)
        Estimates [units].
    stderr : ndarray, shape (m, p)
        One-sigma standard errors [units]; bands are ``values ± 2 stderr``.
    memory : float
        Memory ``T_mem`` of the exponential window [s]; the estimates lag by about this.
    n_samples : int
        Samples read [-].
    n_used : int
        Samples used (moving faster than ``v_min``) [-].
    """

    t: np.ndarray
    names: tuple[str, ...]
    units: Any
    values: np.ndarray
    stderr: np.ndarray
    memory: float
    n_samples: int
    n_used: int
    settings: Any = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "units", MappingProxyType(dict(self.units)))
        object.__setattr__(self, "settings", MappingProxyType(dict(self.settings)))

    @property
    def lag(self) -> float:
        """Approximate lag of the estimates behind a drifting truth [s] (= memory)."""
        return self.memory

    def trajectory(self, name: str) -> tuple[np.ndarray, np.ndarray]:
        """Return ``(values, stderr)`` of one parameter, shape (m,) each.

        Parameters
        ----------
        name : str
            Parameter name, e.g. ``"fk_mean"``.

        Returns
        -------
        values, stderr : ndarray
            Estimates and standard errors [unit].
        """
        if name not in self.names:
            raise KeyError(f"no parameter {name!r}; tracked: {list(self.names)}")
        k = self.names.index(name)
        return self.values[:, k], self.stderr[:, k]

    def to_estimate(self) -> Estimate:
        """Return the final values as an :class:`Estimate` with the trajectories.

        Returns
        -------
        Estimate
            Method ``"rls-forgetting"``; ``data_used`` holds ``t`` and per parameter
            ``<name>`` and ``<name>_stderr`` arrays.
        """
        params = {n: Parameter(float(self.values[-1, k]), float(self.stderr[-1, k]),
                               self.units[n]) for k, n in enumerate(self.names)}
        data = {"t": self.t}
        for k, n in enumerate(self.names):
            data[n] = self.values[:, k]
            data[f"{n}_stderr"] = self.stderr[:, k]
        return Estimate(method="rls-forgetting", params=params, data_used=data,
                        diagnostics={"memory_s": self.memory, "n_samples": self.n_samples,
                                     "n_used": self.n_used, "n_outputs": int(self.t.size),
                                     **dict(self.settings)})

    def plot(self, truth: Any = None) -> Any:
        """Draw each trajectory with its ±2σ band; return the matplotlib figure.

        Parameters
        ----------
        truth : mapping of str to callable, optional
            ``name -> f(t)`` true trajectories to overlay (simulations) [units].

        Returns
        -------
        matplotlib.figure.Figure
            One panel per parameter, time in minutes.
        """
        import matplotlib.pyplot as plt

        fig, axes = plt.subplots(len(self.names), 1, sharex=True,
                                 figsize=(7, 1.6 * len(self.names)), squeeze=False)
        minutes = self.t / 60.0
        for ax, (k, name) in zip(axes[:, 0], enumerate(self.names), strict=True):
            val, se = self.values[:, k], self.stderr[:, k]
            ax.plot(minutes, val, lw=1, label="estimate")
            ax.fill_between(minutes, val - 2 * se, val + 2 * se, alpha=0.3, label="±2σ")
            if truth and name in truth:
                ax.plot(minutes, truth[name](self.t), "k--", lw=1, label="truth")
            ax.set_ylabel(f"{name} [{self.units[name]}]")
        axes[-1, 0].set_xlabel("time [min]")
        axes[0, 0].legend(loc="best", fontsize="small")
        axes[0, 0].set_title(f"RLS with forgetting, memory {self.memory:.4g} s (lag)")
        fig.tight_layout()
        return fig

    def to_dict(self) -> dict[str, Any]:
        """Return ``{"t": [...], "parameters": {name: {"value", "stderr", "unit"}}}``.

        Returns
        -------
        dict
            JSON-ready trajectories (one array per parameter, DESIGN.md names), plus
            ``memory_s`` and ``lag_s``.
        """
        return {
            "schema": "driveid-track/1",
            "t": self.t.tolist(),
            "memory_s": self.memory,
            "lag_s": self.lag,
            "parameters": {n: {"value": self.values[:, k].tolist(),
                               "stderr": self.stderr[:, k].tolist(),
                               "unit": self.units[n]}
                           for k, n in enumerate(self.names)},
        }


def chunks_of(record: Record, size: int) -> Iterator[dict[str, np.ndarray]]:
    """Split a record into chunks ``{"t", "x", "u"[, "v"]}`` of ``size`` samples.

    Parameters
    ----------
    record : Record
        With ``u``.
    size : int
        Samples per chunk [-], >= 3.

    Yields
    ------
    dict
        Arrays of one chunk (views, no copy).
    """
    if not (isinstance(size, int) and size >= 3):
        raise ParameterError(f"size must be an int >= 3; got {size!r}")
    for start in range(0, record.n, size):
        sl = slice(start, start + size)
        out = {"t": record.t[sl], "x": record.x[sl], "u": record.u[sl]}
        if record.v is not None:
            out["v"] = record.v[sl]
        yield out


def _first_derivative(y: np.ndarray, dt: float) -> np.ndarray:
    """Five-point central difference at the interior samples 2..n-3 (error O(dt⁴))."""
    return (-y[4:] + 8 * y[3:-1] - 8 * y[1:-3] + y[:-4]) / (12 * dt)


class _Tracker:
    """The O(p²) state of the block-wise EW least squares (private)."""

    def __init__(self, p: int, lam_block: float) -> None:
        self.R = np.zeros((p, p))
        self.S = np.zeros((p, p))
        self.r = np.zeros(p)
        self.yy = 0.0      # EW sum of y² (residual sum of squares by the normal equations)
        self.w = 0.0       # EW sample count
        self.lam = lam_block

    def update(self, phi: np.ndarray, y: np.ndarray) -> None:
        g = phi.T @ phi
        lam = self.lam
        self.R = lam * self.R + g
        self.S = lam * lam * self.S + g
        self.r = lam * self.r + phi.T @ y
        self.yy = lam * self.yy + float(y @ y)
        self.w = lam * self.w + y.size

    def solve(self, p: int) -> tuple[np.ndarray, np.ndarray]:
        scale = np.sqrt(np.maximum(np.diag(self.R), 1e-300))
        Rn = self.R / np.outer(scale, scale)
        if self.w <= p or np.linalg.cond(Rn) > 1e12:
            return np.full(p, np.nan), np.full(p, np.nan)
        Rinv = np.linalg.inv(Rn) / np.outer(scale, scale)
        theta = Rinv @ self.r
        rss = max(self.yy - float(theta @ self.r), 0.0)
        s2 = rss / (self.w - p)
        cov = s2 * Rinv @ self.S @ Rinv
        return theta, np.sqrt(np.maximum(np.diag(cov), 0.0))


def track_friction(chunks: Iterable[dict[str, np.ndarray]] | Record, *, fs: float | None = None,
                   drift_time: float = 600.0, memory: float | None = None,
                   v_min: float | None = None, stiffness: bool = False,
                   block: float = 0.1, output_every: float = 10.0,
                   units: str = "rad") -> TrackResult:
    """Track J, viscous and Coulomb friction (asymmetric) through a long record.

    Parameters
    ----------
    chunks : iterable of dict, or Record
        Chunks ``{"t" [s], "x" [rad or m], "u" [N·m or N], optional "v" [rad/s or m/s]}``
        in time order, of any sizes (a generator keeps memory bounded), or one Record
        (then streamed in chunks of 10 s).
    fs : float, optional
        Sampling rate [Hz]; default from the first chunk.
    drift_time : float
        Expected drift time constant [s]; the memory is ``drift_time / 10`` (module notes).
    memory : float, optional
        Memory ``T_mem`` of the exponential window [s]; overrides the rule.
    v_min : float, optional
        Samples slower than this are skipped [rad/s or m/s]; default 5 % of the rms
        velocity of the first chunk.
    stiffness : bool
        Also fit ``K x`` (a spring or position feedback inside ``u``).
    block : float
        Update block length [s]; << memory.
    output_every : float
        Output interval [s], a multiple of ``block`` (rounded).
    units : {"rad", "m"}
        Rotational or translational units of the parameters.

    Returns
    -------
    TrackResult
        Trajectories of ``J, c_mean, c_delta, fk_mean, fk_delta`` (and ``K``) with
        standard errors every ``output_every`` seconds.

    Raises
    ------
    RecordError
        If a chunk lacks ``u`` or the record holds no moving sample.
    ParameterError
        On a bad argument, e.g. ``output_every`` shorter than ``block``.

    Notes
    -----
    Velocity and acceleration are five-point central differences (of ``x``, or of ``v`` if
    given; truncation error ``O((ω Δt)⁴)``, small enough for the transients after a friction
    reversal), continued across chunk boundaries by carrying the last four samples. Noisy encoder
    signals should be low-pass filtered first (the same causal filter on x and u keeps the
    linear part of the model exact).

    Examples
    --------
    >>> t = np.arange(200000) / 1000
    >>> v = np.cos(t)
    >>> u = 0.01 * -np.sin(t) + 0.002 * v + 0.05 * np.sign(v)
    >>> res = track_friction(Record(t=t, x=np.sin(t), u=u, v=v), memory=50.0)
    >>> round(float(res.trajectory("fk_mean")[0][-1]), 6)
    0.05
    """
    if isinstance(chunks, Record):
        rec = chunks
        if rec.u is None:
            raise RecordError("tracking needs the command u; record it as column 'u'")
        fs = rec.fs if fs is None else fs
        chunks = chunks_of(rec, max(int(round(10.0 * rec.fs)), 3))
        units = "m" if rec.units.get("x") == "m" else units
    if units not in ("rad", "m"):
        raise ParameterError(f'units must be "rad" or "m"; got {units!r}')
    for name, value in (("drift_time", drift_time), ("block", block),
                        ("output_every", output_every)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number [s]; got {value!r}")
    if output_every < block:  # issue 28: 1e-9 s was taken, and outputs came once a block
        raise ParameterError(
            f"output_every={output_every:g} s is shorter than one update block ({block:g} s): "
            f"the tracker outputs at most once a block; give at least output_every={block:g} "
            "(CLI: --every), a multiple of it")
    names = PARAMETERS + (("K",) if stiffness else ())
    p = len(names)
    it = iter(chunks)
    tracker: _Tracker | None = None
    carry: dict[str, np.ndarray] | None = None
    out_t, out_v, out_s = [], [], []
    n_samples = n_used = 0
    pending_phi, pending_y, pending_n = [], [], 0
    t_last = math.nan
    blocks_since_output = 0
    for chunk in it:
        if "u" not in chunk or chunk.get("u") is None:
            raise RecordError("every chunk needs the command 'u' [N·m or N]; got "
                              f"keys {sorted(chunk)}")
        t = np.asarray(chunk["t"], dtype=float)
        if t.size == 0:
            continue
        if tracker is None:
            if fs is None:
                if t.size < 2:
                    raise RecordError("the first chunk needs >= 2 samples to infer fs")
                fs = 1.0 / float(np.median(np.diff(t)))
            if not (isinstance(fs, (int, float)) and fs > 0):
                raise ParameterError(f"fs must be positive [Hz]; got {fs!r}")
            T_mem = drift_time / 10.0 if memory is None else float(memory)
            if not (math.isfinite(T_mem) and T_mem > 0):
                raise ParameterError(f"memory must be positive [s]; got {memory!r}")
            n_block = max(int(round(block * fs)), 1)
            shortest = max(20.0, 2.0 * n_block) / fs
            if T_mem < shortest:  # forgot within a block: "singular regressor, excite both"
                raise ParameterError(
                    f"memory={T_mem:.3g} s is shorter than {shortest:.3g} s, the fewest samples"
                    " (20, and two blocks) its window needs to separate the parameters; give a "
                    "longer memory (CLI --memory, or --drift-time, ten times the memory)")
            if output_every < 0.999 * n_block / fs:  # a block of one sample: 1/fs > block
                raise ParameterError(
                    f"output_every={output_every:g} s is shorter than the sampling interval "
                    f"{1.0 / fs:.3g} s (fs = {fs:.4g} Hz), and the tracker outputs at most once "
                    f"a sample; give at least output_every={n_block / fs:.3g} (CLI: --every)")
            lam_block = math.exp(-n_block / (fs * T_mem))
            per_output = max(int(round(output_every / block)), 1)
            tracker = _Tracker(p, lam_block)
            dt = 1.0 / fs
        n_samples += t.size
        cols = {k: np.asarray(chunk[k], dtype=float) for k in ("x", "u", "v") if k in chunk}
        cols["t"] = t
        if carry is not None:
            cols = {k: np.concatenate([carry[k], cols[k]]) for k in cols if k in carry}
        if cols["t"].size < 5:
            carry = cols
            continue
        x, u, tt = cols["x"], cols["u"], cols["t"]
        if "v" in cols:
            v = cols["v"][2:-2]
            a = _first_derivative(cols["v"], dt)
        else:
            v = _first_derivative(x, dt)
            a = (-x[4:] + 16 * x[3:-1] - 30 * x[2:-2] + 16 * x[1:-3] - x[:-4]) / (12 * dt * dt)
        carry = {k: cols[k][-4:] for k in cols}
        if v_min is None:
            v_min = 0.05 * float(np.sqrt(np.mean(v * v)))
        # skip samples whose stencil straddles a reversal: a jumps there by 2 fk/J
        sg = np.sign(cols["v"] if "v" in cols else np.gradient(x))
        window = [sg[i: sg.size - 4 + i] for i in range(5)]
        moving = (np.abs(v) > v_min) & (np.minimum.reduce(window) == np.maximum.reduce(window))
        sgn = np.sign(v)
        phi_cols = [a, v, np.abs(v), sgn, np.ones_like(v)]
        if stiffness:
            phi_cols.append(x[2:-2])
        phi = np.column_stack(phi_cols)
        y = u[2:-2]
        times = tt[2:-2]
        # feed samples into blocks of n_block, moving or not (time keeps running)
        start = 0
        while start < v.size:
            take = min(n_block - pending_n, v.size - start)
            sel = slice(start, start + take)
            m = moving[sel]
            pending_phi.append(phi[sel][m])
            pending_y.append(y[sel][m])
            pending_n += take
            n_used += int(m.sum())
            t_last = float(times[start + take - 1])
            start += take
            if pending_n == n_block:
                tracker.update(np.concatenate(pending_phi), np.concatenate(pending_y))
                pending_phi, pending_y, pending_n = [], [], 0
                blocks_since_output += 1
                if blocks_since_output == per_output:
                    blocks_since_output = 0
                    theta, se = tracker.solve(p)
                    out_t.append(t_last)
                    out_v.append(theta)
                    out_s.append(se)
    if tracker is None or n_used == 0:
        raise RecordError(
            "no moving samples to track: the record is empty or |v| never exceeds v_min; "
            f"lower v_min (got {v_min!r}) or excite the axis")
    if pending_n:
        tracker.update(np.concatenate(pending_phi), np.concatenate(pending_y))
        theta, se = tracker.solve(p)
        out_t.append(t_last)
        out_v.append(theta)
        out_s.append(se)
    values = np.array(out_v)
    if not np.any(np.isfinite(values)):
        raise IdentificationError(
            "the motion does not separate the parameters (singular regressor): excite "
            "both directions with varying velocity and acceleration")
    unit = ({"J": "kg·m²", "c": "N·m·s/rad", "f": "N·m", "K": "N·m/rad"} if units == "rad"
            else {"J": "kg", "c": "N·s/m", "f": "N", "K": "N/m"})
    unit_of = {"J": unit["J"], "c_mean": unit["c"], "c_delta": unit["c"],
               "fk_mean": unit["f"], "fk_delta": unit["f"], "K": unit["K"]}
    return TrackResult(t=np.array(out_t), names=names,
                       units={n: unit_of[n] for n in names}, values=values,
                       stderr=np.array(out_s), memory=T_mem, n_samples=n_samples,
                       n_used=n_used,
                       settings={"v_min": v_min, "block_s": n_block / fs,
                                 "drift_time_s": drift_time})
