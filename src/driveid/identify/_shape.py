r"""Which test is this record? The test-shape classifier behind ``identify auto``.

The thesis identifies each effect from a test designed for it (free decays §2.2.5, forced
sine runs §2.2.6, PHO campaigns §2.2.7, breakaway ramps §4.2) and its future work (§6.1)
asks to "fully automate the identification procedure". The first step is to recognise the
test a record comes from; the estimators that apply follow from it. Features, each cheap
(O(n log n)) and unit-free:

* ``P``/``D`` in the record's metadata: a PHO run (delayed PD feedback, Eq. 2.180);
* no input (or a constant one) and an oscillation whose envelope shrinks: a free decay;
* the input's power in one spectral line (±1 bin): a sinusoidal (forced / loop) test;
* the velocity sitting on two or more non-zero levels most of the time: constant-speed
  plateaus (a friction map);
* the input flat between jumps: steps or a (DC-biased) square wave;
* the input changing at a constant rate between dwells: ramps from rest (breakaway);
* the input's spectrum flat across its occupied band (spectral flatness, the geometric over
  the arithmetic mean of the Welch PSD): broadband excitation (PRBS, multisine, chirp);
* anything else with an input: a long operating record.

Each rule gives a score in [0, 1] and one sentence of evidence; the highest score wins.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.signal import welch

from driveid.io.record import Record

__all__ = ["SHAPES", "ShapeVerdict", "classify_record"]

#: The shapes, most specific first: a tie goes to the earlier one.
SHAPES = ("pho", "free-decay", "sine", "ramp", "plateaus", "step", "broadband", "operating")

#: A rule must score at least this to be chosen over "operating" [-].
_MIN_SCORE = 0.5
#: Below this ratio of the input's variation to its noise the input is read as absent [-].
_MIN_SNR = 5.0


@dataclass(frozen=True)
class ShapeVerdict:
    """The test shape of one record, with the evidence.

    Attributes
    ----------
    shape : str
        One of :data:`SHAPES`, or ``"none"`` when nothing can be identified.
    scores : dict of str to float
        Score of every shape [-], 0..1.
    evidence : tuple of str
        One sentence per feature that decided.
    features : dict
        The measured features (fractions [-], frequencies [Hz], counts).
    """

    shape: str
    scores: dict[str, float]
    evidence: tuple[str, ...]
    features: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON form."""
        return {"shape": self.shape, "scores": dict(self.scores),
                "evidence": list(self.evidence), "features": dict(self.features)}


def _blocks(y: np.ndarray, b: int) -> np.ndarray:
    """Means of consecutive blocks of ``b`` samples (the noise shrinks by √b)."""
    m = y.size // b
    return y[:m * b].reshape(m, b).mean(axis=1) if b > 1 else y


def _noise_std(y: np.ndarray) -> float:
    """Noise of a piecewise-linear signal: the median absolute second difference / √6."""
    dd = np.diff(y, 2)
    return float(1.4826 * np.median(np.abs(dd)) / math.sqrt(6.0)) if dd.size else 0.0


def _block_size(n: int) -> int:
    return max(1, n // 1000)


def _input_is_signal(u: np.ndarray) -> float:
    """Signal-to-noise ratio of the input after block averaging [-]."""
    b = _block_size(u.size)
    noise = _noise_std(u) / math.sqrt(b)
    ub = _blocks(u, b)
    return float(np.std(ub) / noise) if noise > 0 else math.inf


def _input_features(u: np.ndarray, fs: float) -> dict[str, float]:
    b = _block_size(u.size)
    ub = _blocks(u, b)
    span = float(np.ptp(ub)) or 1.0
    noise = _noise_std(u) / math.sqrt(b)
    du = np.diff(ub)
    quiet = np.abs(du) <= 4.0 * math.sqrt(2.0) * noise + 1e-4 * span
    jumps = np.abs(du) > 0.1 * span
    jump_events = int(np.sum(np.diff(np.r_[0, jumps.astype(int)]) == 1))
    # levels between the jumps: steps leave only noise about them, smooth moves do not
    cuts = np.flatnonzero(jumps) + 1
    resid = np.concatenate([seg - np.median(seg) for seg in np.split(ub, cuts) if seg.size])
    step_residual = float(1.4826 * np.median(np.abs(resid)) / noise) if noise > 0 else math.inf
    # a sine: the best single line (and DC) explains the input
    fb = fs / b
    centred = ub - float(np.mean(ub))
    spec = np.fft.rfft(centred)
    k = int(np.argmax(np.abs(spec[1:]))) + 1
    tb = np.arange(ub.size) / fb
    f_peak = float(np.fft.rfftfreq(ub.size, 1.0 / fb)[k])
    basis = np.column_stack([np.ones_like(tb)] + [g(2 * np.pi * f * tb) for f in
                            (f_peak * (1 + d / (ub.size)) for d in (-0.5, 0.0, 0.5))
                            for g in (np.sin, np.cos)])
    coef, *_ = np.linalg.lstsq(basis, ub, rcond=None)
    resid = ub - basis @ coef
    denom = float(centred @ centred)
    line = 1.0 - float(resid @ resid) / denom if denom > 0 else 0.0
    return {"input_noise": noise, "quiet_fraction": float(np.mean(quiet)),
            "step_residual": step_residual,
            "jump_events": jump_events,
            "line_fraction": line, "line_frequency_hz": f_peak,
            "spectral_flatness": _log_band_flatness(ub, fb), "levels": _levels(ub, span),
            "active_fraction": _active_fraction(ub)}


def _runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """Half-open index ranges of the True runs of ``mask``."""
    edges = np.diff(np.r_[0, mask.astype(np.int8), 0])
    return list(zip(np.flatnonzero(edges == 1), np.flatnonzero(edges == -1), strict=True))


def _levels(ub: np.ndarray, span: float) -> int:
    """Count the input levels holding >= 5 % of the blocks (2 for PRBS and square waves)."""
    bins = np.round((ub - float(np.min(ub))) / (0.05 * span))
    _, counts = np.unique(bins, return_counts=True)
    return int(np.sum(counts >= 0.05 * ub.size))


def _log_band_flatness(u: np.ndarray, fs: float) -> float:
    """Spectral flatness of the input's PSD averaged in third-octave bands [-].

    Over the band holding the central 93 % of the power (2 % to 95 %): designed
    excitation (PRBS, multisine, chirp) is flat there (~0.5-1); operating moves and steps
    fall off by decades (< 0.2).
    """
    nper = int(min(u.size, 8192))
    freq, psd = welch(u - float(np.mean(u)), fs=fs, nperseg=nper, detrend="linear")
    total = float(np.sum(psd[1:]))
    if total <= 0:
        return 0.0
    cum = np.cumsum(psd[1:]) / total
    f_hi = float(freq[1:][int(np.searchsorted(cum, 0.95))])
    f_lo = max(float(freq[1:][int(np.searchsorted(cum, 0.02))]), float(freq[1]))
    if f_hi <= 2 * f_lo:
        return 0.0
    edges = f_lo * 2.0 ** (np.arange(0, math.log2(f_hi / f_lo) + 1e-9, 1.0 / 3.0))
    bands = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (freq >= lo) & (freq < hi)
        if np.any(sel):
            bands.append(float(np.mean(psd[sel])))
    bands = np.array([v for v in bands if v > 0])
    if bands.size < 4:
        return 0.0
    return float(np.exp(np.mean(np.log(bands))) / np.mean(bands))


def _slope_levels(x: np.ndarray, t: np.ndarray) -> tuple[float, int]:
    """Find runs of constant non-zero slope: least-squares slopes over 100 windows of 1 %.

    Returns the fraction of the record on such runs and the number of distinct slopes: speed
    plateaus when ``x`` is the position, constant-rate ramps when it is the input.
    """
    m = x.size // 100
    if m < 4:
        return 0.0, 0
    xs, ts = x[:100 * m].reshape(100, m), t[:100 * m].reshape(100, m)
    tc = ts - ts.mean(axis=1, keepdims=True)
    xc = xs - xs.mean(axis=1, keepdims=True)
    sxx = np.sum(tc * tc, axis=1)
    slope = np.sum(tc * xc, axis=1) / sxx
    resid = xc - slope[:, None] * tc
    se = np.sqrt(np.sum(resid**2, axis=1) / max(m - 2, 1) / sxx)
    vmax = float(np.max(np.abs(slope)))
    if vmax == 0.0:
        return 0.0, 0
    # a plateau: neighbouring windows agree within 3 % of the top speed (or their errors),
    # and the speed is not ~0; at least 3 windows (3 % of the record) in a row
    tol = 0.03 * vmax + 3.0 * np.hypot(se[1:], se[:-1])
    same = np.r_[False, np.abs(np.diff(slope)) <= tol] & (np.abs(slope) > 0.05 * vmax)
    same = same | np.r_[same[1:], False]
    kept = [(i, j) for i, j in _runs(same) if j - i >= 3]
    levels = sorted(float(np.median(slope[i:j])) for i, j in kept)
    distinct = sum(1 for k, lv in enumerate(levels) if k == 0 or lv - levels[k - 1] > 0.1 * vmax)
    return float(sum(j - i for i, j in kept) / 100.0), int(distinct)


def _active_fraction(ub: np.ndarray) -> float:
    """Fraction of 20 windows where the input varies (> 20 % of its overall scatter) [-]."""
    m = ub.size // 20
    if m < 3:
        return 1.0
    w = ub[:20 * m].reshape(20, m)
    overall = float(np.std(ub))
    return float(np.mean(np.std(w, axis=1) > 0.2 * overall)) if overall > 0 else 0.0


def _decay_features(x: np.ndarray) -> dict[str, float]:
    n = x.size
    rest = float(np.median(x[-max(n // 10, 2):]))
    y = x - rest
    signs = np.sign(y[np.abs(y) > 0.02 * float(np.max(np.abs(y)) or 1.0)])
    crossings = int(np.sum(signs[1:] != signs[:-1])) if signs.size > 1 else 0
    quarter = max(n // 4, 1)
    first = float(np.max(np.abs(y[:quarter])))
    last = float(np.max(np.abs(y[-quarter:])))
    ratio = first / last if last > 0 else math.inf
    return {"crossings": crossings, "envelope_ratio": min(ratio, 1e12)}


def classify_record(record: Record) -> ShapeVerdict:
    """Classify the test a record comes from (free decay, PHO, sine, steps, ramps, ...).

    Parameters
    ----------
    record : Record
        One experiment: ``t`` [s], ``x`` [m or rad], ``u`` [N or N·m] where measured.

    Returns
    -------
    ShapeVerdict
        The shape with the highest score, each shape's score and the evidence.

    Examples
    --------
    >>> from driveid.sim import OscillatorParams, simulate_free_decay
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, fk_mean=0.05)
    >>> classify_record(simulate_free_decay(p, x0=1.0, duration=10).record).shape
    'free-decay'
    """
    fs = record.fs
    x = np.asarray(record.x, float)
    u = None if record.u is None else np.asarray(record.u, float)
    scale = max(float(np.max(np.abs(u))), 1e-300) if u is not None else 0.0
    has_input = u is not None and float(np.ptp(u)) > 1e-9 * scale
    snr = _input_is_signal(u) if has_input else 0.0
    scores = dict.fromkeys(SHAPES, 0.0)
    evidence: list[str] = []
    feats: dict[str, Any] = {"has_input": bool(has_input), "fs_hz": fs,
                             "duration_s": record.duration, "input_snr": snr}
    if has_input and snr < _MIN_SNR:
        evidence.append(f"the force column is noise about a constant (its variation is "
                        f"{snr:.2g}x its noise): read as no input")
        has_input = False
    meta = record.meta or {}
    if all(isinstance(meta.get(k), (int, float)) for k in ("P", "D")):
        scores["pho"] = 1.0
        evidence.append(f"the record's metadata names PD feedback (P = {meta['P']:g}, "
                        f"D = {meta['D']:g}): a PHO run")
    decay = _decay_features(x)
    feats.update(decay)
    if not has_input:
        if decay["crossings"] >= 3 and decay["envelope_ratio"] > 1.2:
            scores["free-decay"] = min(1.0, 0.6 + 0.05 * decay["crossings"])
            evidence.append(
                f"no input{' (constant)' if u is not None else ''}; the position crosses its "
                f"rest value {decay['crossings']} times and its envelope shrinks "
                f"{decay['envelope_ratio']:.3g}x: a free decay")
        else:
            evidence.append(
                f"no input and no decaying oscillation ({decay['crossings']} crossings, "
                f"envelope ratio {decay['envelope_ratio']:.3g})")
        return _verdict(scores, evidence, feats, has_input)
    feats.update(_input_features(u, fs))
    t = np.asarray(record.t, float)
    feats["plateau_fraction"], feats["plateau_levels"] = _slope_levels(x, t)
    feats["ramp_fraction"], feats["ramp_rates"] = _slope_levels(u, t)
    if feats["line_fraction"] > 0.98:
        scores["sine"] = feats["line_fraction"]
        evidence.append(f"one line at {feats['line_frequency_hz']:.4g} Hz explains "
                        f"{100 * feats['line_fraction']:.1f} % of the input: a sinusoidal test")
    if feats["plateau_levels"] >= 2 and feats["plateau_fraction"] > 0.4 \
            and scores["sine"] == 0:
        scores["plateaus"] = 1.0
        evidence.append(f"the speed sits on {feats['plateau_levels']} non-zero levels for "
                        f"{100 * feats['plateau_fraction']:.0f} % of the record: "
                        "constant-speed plateaus")
    # designed excitation is flat in spectrum, never pauses and changes fast (>= 10 changes
    # of 10 % of its range within 0.1 % of the record); operating records dwell and glide
    broadband = feats["spectral_flatness"] > 0.4 and (
        (feats["active_fraction"] >= 0.8 and feats["jump_events"] >= 10)
        or (feats["active_fraction"] == 1.0 and feats["quiet_fraction"] < 0.1))
    if feats["quiet_fraction"] > 0.8 and feats["jump_events"] >= 1 \
            and feats["step_residual"] < 3.0 and not (broadband and feats["jump_events"] >= 20):
        scores["step"] = feats["quiet_fraction"]
        evidence.append(f"the input is flat {100 * feats['quiet_fraction']:.0f} % of the time "
                        f"between {feats['jump_events']} jumps: steps or a square wave")
    if feats["ramp_fraction"] > 0.3 and feats["jump_events"] <= 2 and scores["sine"] == 0:
        scores["ramp"] = 1.0  # force ramps are more specific than the plateaus they cause
        evidence.append(f"the input changes at {feats['ramp_rates']} constant rates for "
                        f"{100 * feats['ramp_fraction']:.0f} % of the record: force ramps")
    if broadband and scores["sine"] == 0 and scores["step"] == 0 and scores["ramp"] == 0:
        scores["broadband"] = min(1.0, 0.4 + feats["spectral_flatness"])
        evidence.append(f"the input's spectrum is flat across its band (third-octave flatness "
                        f"{feats['spectral_flatness']:.2f}): broadband excitation")
    scores["operating"] = 0.3
    return _verdict(scores, evidence, feats, has_input)


def _verdict(scores, evidence, feats, has_input) -> ShapeVerdict:
    best = max(scores, key=lambda s: scores[s])
    if scores[best] < _MIN_SCORE:
        best = "operating" if has_input else "none"
        if has_input:
            evidence.append("no test shape fits clearly: treated as an operating record")
    return ShapeVerdict(best, {k: round(float(v), 3) for k, v in scores.items()},
                        tuple(evidence), feats)
