"""The rows of the IDIM regression: filtered, differentiated, decimated (EMPS recipe).

:func:`idim_regressor` builds the observation matrix and the force of the inverse model of
:mod:`driveid.identify.friction.idim` from one record (re-exported there).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from driveid.errors import ParameterError, RecordError
from driveid.identify.core._expressions import evaluate_expression
from driveid.io.record import Record
from driveid.signal.differentiate import differentiate, zero_phase_lowpass
from driveid.signal.envelope import block_decimate
from driveid.signal.steady import standstill_mask

__all__ = ["MODELS", "IdimRecordTooShort", "idim_regressor"]

#: Friction models understood by :func:`driveid.identify.friction.idim.estimate_idim`.
MODELS = ("symmetric", "asymmetric")


class IdimRecordTooShort(RecordError):
    """Too few rows are left after the edges are dropped and the rows decimated.

    Carries the counts, so that a caller whose decimation is not the user's own option
    (``identify contour``) can word the fix itself: ``dropped`` edge samples at each end,
    ``decimate``, ``need`` and ``got`` rows [-].
    """

    def __init__(self, dropped: int, decimate: int, need: int, got: int) -> None:
        self.dropped, self.decimate, self.need, self.got = dropped, decimate, need, got
        super().__init__(
            f"record too short for IDIM after dropping {dropped} edge samples and decimating "
            f"by {decimate}; need >= {need} samples; got {got}: record a longer run, "
            "or lower the decimation (CLI: --decimate 1)")

    def __reduce__(self):  # picklable (a fleet worker's error travels to the client)
        return type(self), (self.dropped, self.decimate, self.need, self.got)


def _check_settings(model: str, cutoff_hz: float, decimate: int, edge: int) -> None:
    if model not in MODELS:
        raise ParameterError(f"model must be one of {MODELS}; got {model!r}")
    if int(decimate) != decimate or decimate < 1:
        raise ParameterError(f"decimate must be an integer >= 1 [-]; got {decimate}")
    if int(edge) != edge or edge < 0:
        raise ParameterError(f"edge must be an integer >= 0 [samples]; got {edge}")
    if not (math.isfinite(cutoff_hz) and cutoff_hz > 0):
        raise ParameterError(f"cutoff_hz must be a positive frequency [Hz]; got {cutoff_hz}")


def idim_regressor(
    record: Record,
    *,
    model: str = "symmetric",
    cutoff_hz: float = 100.0,
    decimate: int = 10,
    edge: int = 50,
    offset: float | None = None,
    load: str | np.ndarray | None = None,
    regressors: Sequence[str] = (),
    min_speed: float | None = None,
    parallel: bool = False,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Build the decimated observation matrix and force of the IDIM model.

    Parameters
    ----------
    record : Record
        Position ``x`` [m or rad] and force ``u`` [N or N·m].
    model : {"symmetric", "asymmetric"}
        Friction model (see module docstring).
    cutoff_hz : float
        Zero-phase 4th-order Butterworth cut-off on the position [Hz]; EMPS uses 100.
    decimate : int
        Decimation factor of observation matrix and force [-]; 1 disables it. Each row is
        the mean of ``decimate`` consecutive samples of every column and of the force (a
        linear filter applied to both sides, so the model holds for the means;
        :func:`~driveid.signal.envelope.block_decimate`, the last ``n mod decimate`` samples
        dropped). EMPS used
        MATLAB's ``decimate`` (order-8 Chebyshev I at 0.8 of the new Nyquist, zero phase):
        its stopband left the decimated noise coloured in a way no AR model of a few hundred
        rows follows, and IDIM's error bars covered 0.86-0.91 on white noise (sd/se up to
        1.31, issue 24); block means keep white noise white (docs/validation.md).
    edge : int
        Samples dropped at both ends after differentiation [-]; at least
        ``3·fs/cutoff_hz`` are dropped (the filter's start-up transient).
    offset : float or None
        Known force offset [N or N·m], subtracted from the force (its column is then
        dropped); ``None`` estimates it (symmetric model).
    load : str or array_like, shape (n,), optional
        Known load force [N or N·m] subtracted from ``u``: an array, or an expression of
        ``t x v a u`` (see :mod:`driveid.identify.core._expressions`), e.g. ``"1.47*sin(x)"``.
    regressors : sequence of str
        Extra columns with unknown coefficients, expressions of ``t x v a u`` (filtered
        position, velocity, acceleration), e.g. ``("sin(x)",)`` for gravity ``m g l sin q``.
    min_speed : float or None
        Decimated rows slower than this are dropped [m/s or rad/s]; ``None`` or 0 keeps
        them. Rows at standstill are always dropped: there the force is held by static
        friction, which the model does not describe, and the sign of a velocity that is
        zero up to filter ripple is arbitrary. Standstill: the raw position moves by at
        most two encoder counts (its smallest step), or by at most 8 noise sd (from its
        second differences) on a noisy sensor, within ``fs/cutoff_hz`` samples, widened by
        twice that on each side (the zero-phase filter smears the stop).
    parallel : bool
        Parallel filtering: when ``cutoff_hz`` lies below the decimation's band
        (``fs / (2 decimate)``), pass the force and the friction and extra columns through the
        same zero-phase filter as the position, so that ``J x''`` of the filtered position
        meets a force of the same band (without it a low cut-off biases J upwards).

    Returns
    -------
    tuple of ndarray
        ``(W, y, t, v)``: W shape (m, p) [mixed units], force y shape (m,) [N or N·m],
        times t shape (m,) [s], decimated velocity v shape (m,) [m/s or rad/s].

    Raises
    ------
    RecordError
        If the record has no force column or is too short after dropping the edges.
    ParameterError
        If a setting or expression is invalid, or ``cutoff_hz`` so low that the filter's
        start-up transient (``3/cutoff_hz`` at each end) leaves too few samples (the
        message gives the lowest cut-off the record allows).
    """
    _check_settings(model, cutoff_hz, decimate, edge)
    if record.u is None:
        raise RecordError(
            "IDIM needs the applied force or torque u; read the record with a force column "
            "(CLI: --force NAME); got a record with columns "
            f"{list(record.columns)}"
        )
    # the Butterworth filter, the differences and the decimation assume one sampling interval;
    # an uneven clock (a robot log with 1-13 ms steps) is put on the median grid first, warned
    record = record.resampled_uniform(
        purpose="IDIM's zero-phase filter, differentiation and decimation")
    fs = record.fs
    if not cutoff_hz < fs / 2:
        raise ParameterError(
            f"cutoff_hz must be below fs/2 = {fs / 2:g} Hz; got {cutoff_hz}"
        )
    # decimated: at least 24 rows for 4+ unknowns and their noise model (the Chebyshev
    # filter of before needed 27 x decimate samples for its padding)
    min_len = 24 * int(decimate) if decimate > 1 else 8
    half = (record.n - min_len) // 2
    transient = math.ceil(3.0 * fs / cutoff_hz)  # the filter's start-up, each end [samples]
    if half > 0 and record.n - 2 * transient < min_len:
        # issue 28: 1e-9 Hz 'dropped 3000000000000 edge samples'; the filter's start-up
        # transient (3/cutoff_hz at each end) must leave min_len samples
        lowest = _round_up(3.0 * fs / half)
        raise ParameterError(
            f"the cut-off cutoff_hz={cutoff_hz:g} Hz is below what this record resolves: the "
            f"filter's start-up transient, 3/cutoff_hz = {3.0 / cutoff_hz:.3g} s at each "
            f"end, leaves fewer than the {min_len} samples IDIM needs of "
            f"{record.n / fs:.3g} s; give at least cutoff_hz={lowest:g} (CLI: --cutoff-hz) "
            "[Hz], or record a longer run")
    xf, v, a = differentiate(record.x, fs, cutoff_hz=cutoff_hz)
    u = np.asarray(record.u, float)
    values = {"t": record.t, "x": xf, "v": v, "a": a, "u": u}
    y = u.copy()
    if load is not None:
        y = y - (evaluate_expression(load, values) if isinstance(load, str)
                 else _per_sample(load, record.n, "load"))
    if offset is not None:
        y -= float(offset)  # y is ours (a copy of u): in place
    extra = [evaluate_expression(r, values) for r in regressors]
    del values, xf  # only expressions use the filtered position
    # parallel filtering: a position filter narrower than the decimation's leaves the force
    # wider band than J·x'' of the filtered position, which biases J upwards; the force and
    # the columns not built from derivatives then pass the same zero-phase filter
    parallel = bool(parallel) and cutoff_hz < fs / (2 * int(decimate))
    if parallel:
        y = zero_phase_lowpass(y, fs, cutoff_hz)
        extra = [zero_phase_lowpass(c, fs, cutoff_hz) for c in extra]
    # the zero-phase filter's start-up transient lasts a few 1/cutoff_hz
    cut = max(int(edge), transient)
    sl = slice(cut, record.n - cut)
    v, a, y, t = v[sl], a[sl], y[sl], record.t[sl]
    extra = [c[sl] for c in extra]
    if v.size < min_len:
        raise IdimRecordTooShort(cut, int(decimate), min_len, int(v.size))
    # one column at a time: decimating each equals decimating the stacked n x p matrix,
    # which held p full columns plus the filter's padded copies (issue 12)
    def same(column: np.ndarray) -> np.ndarray:
        # sgn(v) and the one-sided velocities are not linear in x: filtered like the force
        return zero_phase_lowpass(column, fs, cutoff_hz) if parallel else column

    if model == "symmetric":
        cols = [lambda: a, lambda: v, lambda: same(np.sign(v))] + (
            [lambda: np.ones_like(v)] if offset is None else [])
    else:
        cols = [lambda: a, lambda: same(np.where(v > 0, v, 0.0)),
                lambda: same((v > 0).astype(float)), lambda: same(np.where(v < 0, v, 0.0)),
                lambda: same(-(v < 0).astype(float))]
    cols += [lambda c=c: c for c in extra]
    if decimate > 1:
        q = int(decimate)
        W = np.column_stack([block_decimate(make(), q) for make in cols])
        y, v_dec, t = block_decimate(y, q), block_decimate(v, q), block_decimate(t, q)
    else:
        W = np.column_stack([make() for make in cols])
        v_dec = v
    min_speed = 0.0 if min_speed is None else float(min_speed)
    if not (math.isfinite(min_speed) and min_speed >= 0):
        raise ParameterError(f"min_speed must be >= 0 [m/s or rad/s]; got {min_speed}")
    still = standstill_mask(np.asarray(record.x, float), max(1, round(fs / cutoff_hz)))[sl]
    if decimate > 1:  # a stop anywhere in a block puts static friction into its mean
        still = block_decimate(still.astype(float), int(decimate)) > 0
    moving = ~still & (np.abs(v_dec) > min_speed)
    return W[moving], y[moving], t[moving], v_dec[moving]


def _round_up(value: float) -> float:
    """``value`` rounded up to three significant digits (a bound that still holds)."""
    step = 10.0 ** (math.floor(math.log10(value)) - 2)
    return math.ceil(value / step - 1e-9) * step


def _per_sample(value: Any, n: int, name: str) -> np.ndarray:
    arr = np.asarray(value, dtype=float).ravel()
    if arr.size == 1:
        return np.full(n, float(arr[0]))
    if arr.size != n or not np.all(np.isfinite(arr)):
        raise ParameterError(f"{name} must hold one finite value per sample ({n}) [N or "
                             f"N·m]; got {arr.size} values")
    return arr
