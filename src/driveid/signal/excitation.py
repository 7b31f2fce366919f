r"""Excitation signals for forced-response and step identification (thesis §2.2.1, ch. 4).

Each generator returns a frozen :class:`Excitation`: the time grid ``t`` [s], the input
``u`` [N·m or N], its band, amplitude limits, crest factor and a one-sided amplitude
spectrum. The input is a force or torque added to whatever the plant does already (an open
axis, or the external input of a PD loop, thesis §2.2.7.2).

Signals
-------
* :func:`chirp` — linear or logarithmic swept sine between ``f_min`` and ``f_max``;
* :func:`multisine` — equal-amplitude lines on the grid ``k/T`` with Schroeder phases
  ``φ_k = -π k (k - 1) / F`` [3]_, periodic in the record, hence leakage-free for the H1
  estimator of :mod:`driveid.identify.forced.frf` when whole periods are analysed;
* :func:`prbs` — maximum-length binary sequence held for ``fs/f_clock`` samples;
* :func:`filtered_random` — Gaussian noise band-limited by a 4th-order Butterworth filter
  (zero phase), scaled to the requested peak;
* :func:`square_wave` — DC-biased square wave for the step/square-wave identification of
  :mod:`driveid.identify.friction.square_wave` (the thesis's low-bias breakaway test, ch. 4);
* :func:`ramps_with_dwell` — trapezoidal force ramps ``0 → +A → 0 → -A → 0`` with dwells;
* :func:`sine` — one stepped-sine run (describing-function friction, thesis ch. 4 grid).

Every generator peaks at ``|u - bias| = amplitude`` exactly (chirp, sine, square wave,
ramps) or by scaling (multisine, filtered random), so the amplitude limit the user names
is the limit the plant sees.

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, Rensselaer Polytechnic Institute, 1998,
       §2.2.1 and ch. 4.
.. [2] R. Pintelon, J. Schoukens, *System Identification: A Frequency Domain Approach*,
       2nd ed., Wiley-IEEE Press, 2012, §5.2 (multisines, crest factor, Schroeder phases).
       doi:10.1002/9781118287422
.. [3] M. R. Schroeder, "Synthesis of low-peak-factor signals and binary sequences with
       low autocorrelation", IEEE Trans. Inf. Theory 16(1), 85-89, 1970.
       doi:10.1109/TIT.1970.1054411
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from types import MappingProxyType
from typing import Any

import numpy as np
from scipy import signal as _sig

from driveid.errors import ParameterError

__all__ = [
    "Excitation",
    "KINDS",
    "chirp",
    "multisine",
    "prbs",
    "filtered_random",
    "square_wave",
    "ramps_with_dwell",
    "sine",
]

#: Signal kinds understood by ``driveid excite KIND``.
KINDS = ("chirp", "multisine", "prbs", "random", "square", "ramp", "sine")


@dataclass(frozen=True, kw_only=True)
class Excitation:
    """One excitation signal, sampled.

    Attributes
    ----------
    kind : str
        One of :data:`KINDS`.
    t : ndarray, shape (n,)
        Sample times from 0 [s].
    u : ndarray, shape (n,)
        Input force or torque [N or N·m].
    fs : float
        Sampling rate [Hz].
    band : tuple of float
        Excited band ``(f_lo, f_hi)`` [Hz] (``(0, 0)`` for quasi-static signals).
    period : float or None
        Period of a periodic signal [s] (multisine, square, sine, PRBS), else None.
    settings : mapping
        The generator's arguments, for the manifest.
    """

    kind: str
    t: np.ndarray
    u: np.ndarray
    fs: float
    band: tuple[float, float]
    period: float | None = None
    settings: Mapping[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        object.__setattr__(self, "settings", MappingProxyType(dict(self.settings)))
        for name in ("t", "u"):
            arr = np.asarray(getattr(self, name), dtype=float)
            arr.setflags(write=False)
            object.__setattr__(self, name, arr)

    @property
    def amplitude_limits(self) -> tuple[float, float]:
        """Smallest and largest input ``(min u, max u)`` [N or N·m]."""
        return float(self.u.min()), float(self.u.max())

    @property
    def crest_factor(self) -> float:
        """Peak over rms of the signal about its mean [-] (√2 for one sine)."""
        centred = self.u - self.u.mean()
        rms = float(np.sqrt(np.mean(centred**2)))
        return float(np.max(np.abs(centred)) / rms) if rms > 0 else math.nan

    def spectrum(self) -> tuple[np.ndarray, np.ndarray]:
        """One-sided amplitude spectrum of ``u`` (rectangular window).

        Returns
        -------
        f : ndarray, shape (n//2 + 1,)
            Frequencies [Hz].
        amplitude : ndarray, shape (n//2 + 1,)
            Sine amplitude per bin [N or N·m] (the DC bin holds the mean).
        """
        n = self.u.size
        amp = np.abs(np.fft.rfft(self.u)) * 2.0 / n
        amp[0] /= 2.0
        if n % 2 == 0:
            amp[-1] /= 2.0
        return np.fft.rfftfreq(n, 1.0 / self.fs), amp


def _positive(name: str, value: Any, unit: str, *, allow_zero: bool = False) -> float:
    ok = (not isinstance(value, bool) and isinstance(value, (int, float))
          and math.isfinite(value) and (value >= 0 if allow_zero else value > 0))
    if not ok:
        rule = ">= 0" if allow_zero else "> 0"
        raise ParameterError(f"{name} must be a finite number {rule} [{unit}]; got {value!r}")
    return float(value)


def _grid(duration: float, fs: float) -> np.ndarray:
    duration = _positive("duration", duration, "s")
    fs = _positive("fs", fs, "Hz")
    n = int(round(duration * fs))
    if n < 8:
        raise ParameterError(
            f"duration * fs = {duration * fs:.3g} samples; need at least 8: record longer or "
            "sample faster")
    return np.arange(n) / fs


def _band(f_min: float, f_max: float, fs: float) -> tuple[float, float]:
    f_min = _positive("f_min", f_min, "Hz")
    f_max = _positive("f_max", f_max, "Hz")
    if f_max <= f_min:
        raise ParameterError(f"f_max must exceed f_min; got f_min={f_min}, f_max={f_max} Hz")
    if f_max >= fs / 2:
        raise ParameterError(
            f"f_max={f_max} Hz must be below the Nyquist frequency fs/2 = {fs / 2} Hz; "
            "sample faster or lower f_max")
    return f_min, f_max


def chirp(*, f_min: float, f_max: float, duration: float, fs: float, amplitude: float,
          method: str = "linear") -> Excitation:
    """Swept sine from ``f_min`` to ``f_max`` over the record.

    Parameters
    ----------
    f_min, f_max : float
        Start and end frequency [Hz]; ``0 < f_min < f_max < fs/2``.
    duration : float
        Record length [s].
    fs : float
        Sampling rate [Hz].
    amplitude : float
        Peak input [N or N·m], > 0.
    method : {"linear", "logarithmic"}
        Frequency law (``scipy.signal.chirp``).

    Returns
    -------
    Excitation
        Kind ``"chirp"``, band ``(f_min, f_max)``.

    Raises
    ------
    ParameterError
        On a non-positive or inconsistent argument.

    Examples
    --------
    >>> ex = chirp(f_min=1, f_max=10, duration=5, fs=200, amplitude=0.5)
    >>> round(ex.amplitude_limits[1], 6) <= 0.5
    True
    """
    t = _grid(duration, fs)
    f_min, f_max = _band(f_min, f_max, fs)
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    if method not in ("linear", "logarithmic"):
        raise ParameterError(f'method must be "linear" or "logarithmic"; got {method!r}')
    u = amplitude * _sig.chirp(t, f0=f_min, t1=t[-1], f1=f_max, method=method, phi=-90)
    return Excitation(kind="chirp", t=t, u=u, fs=float(fs), band=(f_min, f_max),
                      settings={"f_min": f_min, "f_max": f_max, "duration": duration,
                                "fs": fs, "amplitude": amplitude, "method": method})


def multisine(*, f_min: float, f_max: float, duration: float, fs: float, amplitude: float,
              period: float | None = None) -> Excitation:
    r"""Schroeder-phased multisine with equal line amplitudes in ``[f_min, f_max]``.

    Parameters
    ----------
    f_min, f_max : float
        Band [Hz]; lines at the multiples of ``1/period`` inside it.
    duration : float
        Record length [s]; a whole number of periods is recommended.
    fs : float
        Sampling rate [Hz].
    amplitude : float
        Peak input [N or N·m], > 0: the signal is scaled so that ``max |u| = amplitude``.
    period : float, optional
        Period [s]; default ``duration`` (one period). Frequency resolution ``1/period``.

    Returns
    -------
    Excitation
        Kind ``"multisine"``; ``settings["frequencies"]`` holds the lines [Hz];
        ``crest_factor`` is the achieved peak/rms.

    Raises
    ------
    ParameterError
        On a bad argument or when no line falls inside the band.

    Notes
    -----
    Phases ``φ_k = -π k (k - 1) / F`` for lines ``k = 1..F`` (Schroeder 1970, reference
    [3] of the module). For a flat amplitude spectrum of many consecutive lines the crest
    factor is about 1.7 (Pintelon & Schoukens 2012, reference [2] of the module, §5.2:
    Schroeder phases give ≈ 1.7 against ≈ 3-4 for random phases); tested in
    ``tests/signal/test_excitation.py``.

    Examples
    --------
    >>> ex = multisine(f_min=1, f_max=20, duration=10, fs=1000, amplitude=0.5)
    >>> len(ex.settings["frequencies"]), round(float(np.max(np.abs(ex.u))), 6)
    (191, 0.5)
    """
    t = _grid(duration, fs)
    f_min, f_max = _band(f_min, f_max, fs)
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    period = float(duration) if period is None else _positive("period", period, "s")
    if period > float(duration) * (1 + 1e-9):
        # issue 28: a period of 100 s in a 1 s record wrote a signal that never repeats
        raise ParameterError(
            f"period {period:g} s is longer than the duration {duration:g} s: the record would "
            "hold no whole period; give --period at most the duration (ideally a whole "
            "fraction of it)")
    df = 1.0 / period
    # no line at 0 Hz (issue 28: a period of 1e-9 s made the DC line the only one: u const)
    k_lo = max(1, int(math.ceil(f_min / df - 1e-9)))
    k_hi = int(math.floor(f_max / df + 1e-9))
    if k_hi < k_lo:
        raise ParameterError(
            f"no multiple of 1/period = {df:.4g} Hz lies in [{f_min}, {f_max}] Hz; lengthen "
            "the period or widen the band")
    freqs = np.arange(k_lo, k_hi + 1) * df
    n_lines = freqs.size
    k = np.arange(1, n_lines + 1)
    phases = -np.pi * k * (k - 1) / n_lines
    per = period * fs
    if abs(per - round(per)) <= 1e-9 * per:
        # a whole number of samples a period: one inverse FFT of the lines, repeated (issue
        # 28: the sum of 4e5 lines over 1e6 samples, one cosine at a time, took hours)
        size = int(round(per))
        spectrum = np.zeros(size // 2 + 1, complex)
        spectrum[np.arange(k_lo, k_hi + 1)] = np.exp(1j * phases)
        u = np.fft.irfft(spectrum, size)[np.arange(t.size) % size]
    else:
        if float(n_lines) * t.size > 2e9:  # about a minute of cosines
            raise ParameterError(
                f"multisine: {n_lines} lines x {t.size} samples is more than 2e9 cosine "
                f"evaluations, since the period {period:g} s is not a whole number of samples "
                f"at {fs:g} Hz; give a period of a whole number of samples (fast), a narrower "
                "band or a shorter record")
        u = np.zeros_like(t)
        for f, ph in zip(freqs, phases, strict=True):
            u += np.cos(2 * np.pi * f * t + ph)
    u *= amplitude / np.max(np.abs(u))
    return Excitation(kind="multisine", t=t, u=u, fs=float(fs), band=(f_min, f_max),
                      period=period,
                      settings={"f_min": f_min, "f_max": f_max, "duration": duration,
                                "fs": fs, "amplitude": amplitude, "period": period,
                                "frequencies": freqs})


def prbs(*, f_clock: float, duration: float, fs: float, amplitude: float,
         order: int | None = None) -> Excitation:
    """Maximum-length pseudo-random binary sequence ``±amplitude``.

    Parameters
    ----------
    f_clock : float
        Bit rate [Hz]; each bit is held ``round(fs/f_clock)`` samples. The spectrum is
        flat within 3 dB up to about ``0.44 f_clock``.
    duration : float
        Record length [s].
    fs : float
        Sampling rate [Hz]; ``fs >= f_clock``.
    amplitude : float
        Level [N or N·m], > 0.
    order : int, optional
        Shift-register length (period ``2**order - 1`` bits), 2..24; default: the smallest
        whose period covers the record.

    Returns
    -------
    Excitation
        Kind ``"prbs"``, band ``(1/period, 0.44 f_clock)``.

    Raises
    ------
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> ex = prbs(f_clock=50, duration=2, fs=500, amplitude=1.0)
    >>> sorted(set(ex.u.tolist()))
    [-1.0, 1.0]
    """
    t = _grid(duration, fs)
    f_clock = _positive("f_clock", f_clock, "Hz")
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    hold = int(round(fs / f_clock))
    if hold < 1:
        raise ParameterError(f"f_clock={f_clock} Hz must not exceed fs={fs} Hz")
    n_bits = int(math.ceil(t.size / hold))
    if n_bits < 3:  # 1 or 2 bits: a constant or a single step, written as a "PRBS" before
        raise ParameterError(
            f"f_clock={f_clock:g} Hz gives {n_bits} bit(s) in {duration:g} s: a PRBS needs "
            f"many bits; raise f_clock to well above 3/duration = {3 / duration:.3g} Hz or "
            "lengthen the duration")
    if order is None:
        order = max(2, int(math.ceil(math.log2(n_bits + 1))))
    if not (isinstance(order, int) and 2 <= order <= 24):
        raise ParameterError(f"order must be an int in 2..24; got {order!r}")
    seq = _sig.max_len_seq(order)[0].astype(float) * 2.0 - 1.0
    bits = np.resize(seq, n_bits)
    u = amplitude * np.repeat(bits, hold)[: t.size]
    period = (2**order - 1) * hold / fs
    return Excitation(kind="prbs", t=t, u=u, fs=float(fs),
                      band=(1.0 / period, 0.44 * fs / hold), period=period,
                      settings={"f_clock": fs / hold, "duration": duration, "fs": fs,
                                "amplitude": amplitude, "order": order})


def filtered_random(*, f_min: float, f_max: float, duration: float, fs: float,
                    amplitude: float, seed: int | None = None) -> Excitation:
    """Gaussian noise band-limited to ``[f_min, f_max]``, scaled to peak ``amplitude``.

    Parameters
    ----------
    f_min, f_max : float
        Pass band of a 4th-order Butterworth filter applied forward and backward [Hz].
    duration : float
        Record length [s].
    fs : float
        Sampling rate [Hz].
    amplitude : float
        Peak input [N or N·m], > 0.
    seed : int, optional
        Seed of ``numpy.random.default_rng`` (reproducible signal).

    Returns
    -------
    Excitation
        Kind ``"random"``.

    Raises
    ------
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> ex = filtered_random(f_min=1, f_max=20, duration=4, fs=500, amplitude=2.0, seed=1)
    >>> round(float(np.max(np.abs(ex.u))), 9)
    2.0
    """
    t = _grid(duration, fs)
    f_min, f_max = _band(f_min, f_max, fs)
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    # the zero-phase filter runs forward and back over the record: it needs one period of
    # the lowest frequency and its own start-up (27 samples) (issue 28: was an internal error)
    shortest = max(1.0 / f_min, 28.0 / fs)
    if duration < shortest:
        raise ParameterError(
            f"duration {duration:g} s is too short for a random signal in {f_min:g}..{f_max:g}"
            f" Hz at {fs:g} Hz: it needs at least {shortest:.3g} s (one period of f_min and "
            "28 samples for the band-pass filter); give a longer --duration or a higher "
            "--f-min")
    rng = np.random.default_rng(seed)
    sos = _sig.butter(4, [f_min, f_max], btype="bandpass", fs=fs, output="sos")
    u = _sig.sosfiltfilt(sos, rng.standard_normal(t.size))
    u *= amplitude / np.max(np.abs(u))
    return Excitation(kind="random", t=t, u=u, fs=float(fs), band=(f_min, f_max),
                      settings={"f_min": f_min, "f_max": f_max, "duration": duration,
                                "fs": fs, "amplitude": amplitude, "seed": seed})


def square_wave(*, frequency: float, duration: float, fs: float, amplitude: float,
                bias: float = 0.0) -> Excitation:
    """DC-biased square wave ``bias ± amplitude`` (the thesis's step test, ch. 4).

    Parameters
    ----------
    frequency : float
        Square-wave frequency [Hz]; each half period must hold >= 4 samples.
    duration : float
        Record length [s].
    fs : float
        Sampling rate [Hz].
    amplitude : float
        Half the step height [N or N·m], > 0.
    bias : float
        DC bias [N or N·m] (a low bias below the static friction tests breakaway).

    Returns
    -------
    Excitation
        Kind ``"square"``; starts at ``bias + amplitude``.

    Raises
    ------
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> ex = square_wave(frequency=1, duration=2, fs=100, amplitude=1.0, bias=0.5)
    >>> ex.amplitude_limits
    (-0.5, 1.5)
    """
    t = _grid(duration, fs)
    frequency = _positive("frequency", frequency, "Hz")
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    if not (isinstance(bias, (int, float)) and math.isfinite(bias)):
        raise ParameterError(f"bias must be a finite number [N or N·m]; got {bias!r}")
    if fs / (2 * frequency) < 4:
        raise ParameterError(
            f"frequency={frequency} Hz leaves fewer than 4 samples per half period at "
            f"fs={fs} Hz; lower the frequency or sample faster")
    phase = np.floor(2.0 * frequency * t + 1e-9).astype(int) % 2
    u = bias + amplitude * np.where(phase == 0, 1.0, -1.0)
    return Excitation(kind="square", t=t, u=u, fs=float(fs), band=(frequency, frequency),
                      period=1.0 / frequency,
                      settings={"frequency": frequency, "duration": duration, "fs": fs,
                                "amplitude": amplitude, "bias": float(bias)})


def ramps_with_dwell(*, amplitude: float, ramp_time: float, dwell_time: float, fs: float,
                     n_cycles: int = 1) -> Excitation:
    """Trapezoidal ramps ``0 → +A (dwell) → 0 (dwell) → -A (dwell) → 0 (dwell)``.

    Parameters
    ----------
    amplitude : float
        Plateau level [N or N·m], > 0.
    ramp_time : float
        Duration of each ramp [s], > 0.
    dwell_time : float
        Duration of each plateau [s], >= 0.
    fs : float
        Sampling rate [Hz].
    n_cycles : int
        Number of ± cycles [-], >= 1.

    Returns
    -------
    Excitation
        Kind ``"ramp"``, band ``(0, 0)`` (quasi-static).

    Raises
    ------
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> ex = ramps_with_dwell(amplitude=2.0, ramp_time=1.0, dwell_time=0.5, fs=100)
    >>> ex.amplitude_limits, round(float(ex.t[-1]), 2)
    ((-2.0, 2.0), 5.99)
    """
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    ramp_time = _positive("ramp_time", ramp_time, "s")
    dwell_time = _positive("dwell_time", dwell_time, "s", allow_zero=True)
    fs = _positive("fs", fs, "Hz")
    if not (isinstance(n_cycles, int) and n_cycles >= 1):
        raise ParameterError(f"n_cycles must be an int >= 1; got {n_cycles!r}")
    from driveid.io.consistency import check_allocation

    # the size is known before the knots are laid (issue 28: 1e9 cycles ran on silently in
    # the knot loop); t, u, the interpolation and the CSV text: ~128 B a sample
    total = n_cycles * 4 * (ramp_time + dwell_time)
    check_allocation(total * fs + 1, 128,
                     f"ramps: {n_cycles} cycles of {4 * (ramp_time + dwell_time):g} s at "
                     f"{fs:g} Hz",
                     override="fewer cycles (--cycles), shorter ramps or dwells, or a lower "
                              "rate (--fs)")
    knots_t, knots_u, now = [0.0], [0.0], 0.0
    for _ in range(n_cycles):
        for level in (amplitude, 0.0, -amplitude, 0.0):
            now += ramp_time
            knots_t.append(now)
            knots_u.append(level)
            now += dwell_time
            knots_t.append(now)
            knots_u.append(level)
    t = _grid(now, fs)
    u = np.interp(t, knots_t, knots_u)
    return Excitation(kind="ramp", t=t, u=u, fs=float(fs), band=(0.0, 0.0),
                      settings={"amplitude": amplitude, "ramp_time": ramp_time,
                                "dwell_time": dwell_time, "fs": fs, "n_cycles": n_cycles})


def sine(*, frequency: float, duration: float, fs: float, amplitude: float,
         bias: float = 0.0) -> Excitation:
    """One sine ``bias + amplitude sin(2π f t)`` (a stepped-sine run).

    Parameters
    ----------
    frequency : float
        Frequency [Hz], below fs/4.
    duration : float
        Record length [s].
    fs : float
        Sampling rate [Hz].
    amplitude : float
        Amplitude [N or N·m], > 0.
    bias : float
        DC bias [N or N·m].

    Returns
    -------
    Excitation
        Kind ``"sine"``.

    Raises
    ------
    ParameterError
        On a bad argument.

    Examples
    --------
    >>> round(sine(frequency=2.5, duration=2, fs=200, amplitude=1).crest_factor, 6)
    1.414214
    """
    t = _grid(duration, fs)
    frequency = _positive("frequency", frequency, "Hz")
    amplitude = _positive("amplitude", amplitude, "N or N·m")
    if frequency >= fs / 4:
        raise ParameterError(
            f"frequency={frequency} Hz must be below fs/4 = {fs / 4} Hz (>= 4 samples per "
            "period); sample faster")
    if not (isinstance(bias, (int, float)) and math.isfinite(bias)):
        raise ParameterError(f"bias must be a finite number [N or N·m]; got {bias!r}")
    u = bias + amplitude * np.sin(2 * np.pi * frequency * t)
    return Excitation(kind="sine", t=t, u=u, fs=float(fs), band=(frequency, frequency),
                      period=1.0 / frequency,
                      settings={"frequency": frequency, "duration": duration, "fs": fs,
                                "amplitude": amplitude, "bias": float(bias)})
