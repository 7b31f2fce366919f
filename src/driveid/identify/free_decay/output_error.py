r"""Output-error identification of free decays: the exact piecewise model fitted to every sample.

The extended log decrement (:mod:`driveid.identify.free_decay.logdec`) keeps a few dozen peak values
and times of a record; this estimator fits the exact piecewise free response (de Marchi
1998, Eqs. 2.139-2.143 per half cycle, 2.156 for the asymmetric equilibria, 2.168 for the
reversals; see :mod:`driveid.identify.free_decay._free_response`) to **every** sample by unweighted
least squares, which reaches the Cramér–Rao bound (:mod:`driveid.identify.crlb`) for white
measurement noise.

Unknowns
--------
Shared: ``omega0``, ``zeta_plus``, ``zeta_minus``, ``theta_k_mean``, ``theta_k_delta``
(``= fk/K``). Per record: the release position and time (a record that starts mid-swing is
detected and fitted with the previous, unseen velocity zero as its release — the same
model, see ``_free_response``), and with ``drift=True`` a linear drift slope. The number
of half cycles before the body sticks is discrete: the count the kinetic friction allows
from the start guess and its neighbours are fitted, counts whose fitted reversals the
kinetic friction forbids are rejected, and the survivors are averaged with weights
``exp(-Δχ²/2)`` (χ² = RSS/s²); their spread enters the covariance.

Noise model, structure, bounds (issue 24)
-----------------------------------------
The white fit's residuals get an AR(p) model (Burg, order by BIC,
:mod:`driveid.identify.core._noise`); when it is not white, every candidate is refitted on
prewhitened residuals ``A(q)(y - f(θ))`` (prediction error, Ljung 1999 §7.3), the model
re-estimated, 2-3 rounds; the covariance is ``σ_w²(J_wᵀJ_w)⁻¹`` with the prewhitened
Jacobian. White noise (order 0) leaves the fit and its error bars exactly as before. Nested
structures (``+ drift``, ``+ quadratic damping``) are tested where the residuals ask for it
(:mod:`driveid.identify.free_decay._free_decay_structures`) and the simplest adequate one by BIC is
reported; an inadequate fit gets sandwich error bars and a warning naming the effect. The
fit is bounded (ζ± >= 0 when ``passive``, θk_mean >= 0, ω0 > 0); estimates at a bound are
listed in ``diagnostics["at_bound"]`` with one-sided 95 % limits. Starts come from the
peaks and from the samples (spectral peak with exponential or linear envelope,
:mod:`driveid.identify.free_decay._free_decay_starts`); the best settled one is kept.

Error bars
----------
``s²(JᵀJ)⁻¹`` (white) with ``s² = RSS/(n - p)`` and the exact Jacobian, carried to ``J``/``K``,
``c_mean``, ``c_delta``, ``fk_mean``, ``fk_delta`` by the delta method. Encoder
quantisation is not white noise (its errors follow the signal), so for quantised records
(detected, or ``quantisation=`` the step) the covariance is that of a parametric bootstrap:
the fitted response plus the residual noise re-quantised on grids of random phase, refitted
``bootstrap`` times; its variances are scaled by ``(t_{B-1,0.975}/1.96)²`` (1.108 at B = 25)
so that ±1.96 standard errors has the Student-t width of a variance estimated from B refits.
With coloured noise the replicates' noise is a long AR model of the residuals less the
rounding's white floor, and the covariance is calibrated for the record's own noise-model
error (:mod:`driveid.identify.free_decay._quantised`; issue 24, low-pass noise with
encoder steps).

A constant position offset (encoder zero ≠ spring zero) is not identifiable from a free
decay: it trades one-for-one with ``theta_k_delta``. Pass the spring zero ``x_ref``; the
estimate's ``fk_delta`` otherwise contains ``K·offset``.

Relative to the thesis: the thesis identifies from peaks only (§2.2.5); the whole-record
fit is our extension, with the thesis's model unchanged.
"""

from __future__ import annotations

import math
import warnings
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
from threadpoolctl import threadpool_limits

from driveid.errors import IdentificationError, ParameterError, RecordWarning
from driveid.identify.core._noise import white_noise
from driveid.identify.core._plausibility import plausibility_checked
from driveid.identify.core.estimate import Estimate, Parameter
from driveid.identify.free_decay._free_decay_counts import (
    _candidates,
    _combine,
    _forbidden,
    _refine,
    _settle,
    visible_half_cycles,
)
from driveid.identify.free_decay._free_decay_starts import peak_start, sample_starts
from driveid.identify.free_decay._free_decay_structures import (
    StreamWhitener,
    assess,
    noise_rounds,
)
from driveid.identify.free_decay._free_decay_verdict import (
    adequacy_of,
    apply_verdict,
    growth_warnings,
    physics_warnings,
    structure_fitted,
)
from driveid.identify.free_decay._free_response import (
    GLOBAL_NAMES,
    SINK_ROWS,
    response,
)
from driveid.identify.free_decay._quantised import bootstrap_covariance, detect_quantum
from driveid.io.record import Record

# detect_quantum lives in _quantised; named here too, where users have imported it from
__all__ = ["detect_quantum", "estimate_output_error", "physical_parameters"]

_ZETA_BOUND = 0.999  # |ζ| < 1: the model is underdamped by construction
#: Above this many samples the stop-count search and the start values use a decimated
#: copy; the final fits use every sample (so the efficiency is unchanged).
_SEARCH_SAMPLES = 60_000
#: Samples of the copy the start strategies are ranked on [-].
_RANK_SAMPLES = 2000
#: Most samples of the final fit; longer records are fitted on every k-th sample. White noise
#: stays white and the model is exact at the kept times, so the estimate stays unbiased and
#: its error bars honest (variance ~k times the full record's bound). No anti-alias filter:
#: the model is compared with the samples themselves, and a filter would change the model.
#: This now bounds time (25 bootstrap refits of an encoder record); the Jacobian is formed
#: in blocks whatever the length (issue 12: the whole n x p Jacobian needed > 2.7 GB).
_MAX_FIT_SAMPLES = 2_000_000


def _units(record: Record) -> dict[str, str]:
    xu = record.units.get("x", "rad")
    if xu == "m":
        return {"x": "m", "J": "kg", "K": "N/m", "c": "N·s/m", "f": "N"}
    return {"x": xu, "J": "kg·m²", "K": f"N·m/{xu}", "c": f"N·m·s/{xu}", "f": "N·m"}


def physical_parameters(base, mass: float | None, stiffness: float | None) -> dict[str, float]:
    """Map ``(omega0, zeta_plus, zeta_minus, theta_k_mean, theta_k_delta)`` to J, K, c, fk.

    Parameters
    ----------
    base : sequence of float
        ``omega0`` [rad/s], ``zeta_plus``, ``zeta_minus`` [-], ``theta_k_mean``,
        ``theta_k_delta`` [m or rad].
    mass : float or None
        Known J [kg or kg·m²].
    stiffness : float or None
        Known K [N/m or N·m/rad] (used when ``mass`` is None).

    Returns
    -------
    dict
        ``J, K, c_mean, c_delta, fk_mean, fk_delta`` (thesis 2.145, 2.150, 2.139, 2.156).
    """
    omega0, zp, zm, tkm, tkd = (float(v) for v in base)
    if mass is not None:
        J, K = mass, mass * omega0**2
    else:
        J, K = stiffness / omega0**2, stiffness
    crit = 2.0 * math.sqrt(J * K)
    return {"J": J, "K": K, "c_mean": 0.5 * crit * (zp + zm), "c_delta": 0.5 * crit * (zp - zm),
            "fk_mean": K * tkm, "fk_delta": K * tkd}


def _physical_jacobian(base, mass, stiffness, names):
    base = np.asarray(base, float)
    G = np.empty((len(names), 5))
    for i in range(5):
        h = 1e-6 * max(abs(base[i]), 1e-4)
        up, down = base.copy(), base.copy()
        up[i] += h
        down[i] -= h
        a, b = (physical_parameters(v, mass, stiffness) for v in (up, down))
        G[:, i] = [(a[n] - b[n]) / (2 * h) for n in names]
    return G


def _joined(arrays, join=np.concatenate):
    """One record's array itself, several joined (a copy of one record is 8 B a sample)."""
    return arrays[0] if len(arrays) == 1 else join(arrays)


class _Problem:
    """Records, their per-record unknowns and the stop counts of one candidate.

    ``noise`` (a :class:`NoiseModel`, white by default) prewhitens the fit: target, model
    and Jacobian go through ``A(q)`` record by record (the filter is linear).
    """

    def __init__(self, times, values, drift, passive=True):
        self.t = times
        self.y = values
        self.drift = drift
        self.passive = passive
        self.per = 3 if drift else 2
        self.n = sum(t.size for t in times)
        self.segments = [t.size for t in times]
        self.noise = white_noise(np.zeros(1))

    def decimated(self, step):
        """Return the same problem on every ``step``-th sample (for the discrete search)."""
        return _Problem([t[::step] for t in self.t], [y[::step] for y in self.y], self.drift,
                        self.passive)

    def bounds(self, size):
        """Bounds: ω0 > 0, ζ± in [0, 1) (passive) or (-1, 1), θk_mean >= 0."""
        lower = np.full(size, -np.inf)
        upper = np.full(size, np.inf)
        lower[0], upper[1:3] = 1e-12, _ZETA_BOUND
        lower[1:3] = 0.0 if self.passive else -_ZETA_BOUND
        lower[3] = 0.0
        return lower, upper

    def model(self, p, counts, jacobian=True):
        parts, jacs = [], []
        n_par = p.size
        for r, (t, n_half) in enumerate(zip(self.t, counts, strict=True)):
            k = 5 + self.per * r
            x, jac, _ = response(t, p[:5], p[k], p[k + 1], n_half, jacobian=jacobian)
            rel = t - t[0]
            if self.drift:
                x = x + p[k + 2] * rel
            parts.append(x)
            if jacobian:
                full = np.zeros((t.size, n_par))
                full[:, :5] = jac[:, :5]
                full[:, k:k + 2] = jac[:, 5:]
                if self.drift:
                    full[:, k + 2] = rel
                jacs.append(full)
        return _joined(parts), (_joined(jacs, np.vstack) if jacobian else None)

    def normal_equations(self, p, counts, target, noise=None):
        """Return ``(f, JᵀJ, Jᵀ(target - f))`` with J formed in blocks, never whole.

        Each record's rows touch only its own columns (the shared five, its release and
        drift), so each block of at most ``SINK_ROWS`` rows adds a small product into
        the ``p x p`` matrix: memory O(p² + block) besides ``f`` (8 B a sample).
        """
        n_par = p.size
        jtj = np.zeros((n_par, n_par))
        jtr = np.zeros(n_par)
        parts, offset = [], 0
        for r, (t, n_half) in enumerate(zip(self.t, counts, strict=True)):
            k = 5 + self.per * r
            cols = np.r_[0:5, k:k + self.per]
            y_r = target[offset:offset + t.size]
            slope = p[k + 2] if self.drift else 0.0
            # the prewhitening filter runs on over the blocks with its state carried
            whiten = None if noise is None or noise.is_white else \
                StreamWhitener(noise, cols.size + 1)

            def sink(lo, hi, x_rows, rows, t=t, y_r=y_r, cols=cols, slope=slope,
                     whiten=whiten):
                if self.drift:
                    rel = t[lo:hi] - t[0]
                    block = np.column_stack([rows, rel])
                    resid = y_r[lo:hi] - (x_rows + slope * rel)
                else:
                    block, resid = rows, y_r[lo:hi] - x_rows
                if whiten is not None:
                    both = whiten(np.column_stack([block, resid]))
                    block, resid = both[:, :-1], both[:, -1]
                jtj[np.ix_(cols, cols)] += block.T @ block
                jtr[cols] += block.T @ resid

            x, _, _ = response(t, p[:5], p[k], p[k + 1], n_half, sink=sink)
            if self.drift:
                x = x + slope * (t - t[0])
            parts.append(x)
            offset += t.size
        return _joined(parts), jtj, jtr

    def fit(self, p0, counts, y=None, max_iter=100):
        target = _joined(self.y) if y is None else y
        lower, upper = self.bounds(p0.size)
        noise, segs = self.noise, self.segments
        if noise.is_white:  # exactly the unweighted fit

            def whiten(v):
                return v
        else:

            def whiten(v):
                return noise.whiten(v, segs)

        def linearise(p):
            if self.n <= SINK_ROWS:  # small: the whole Jacobian, kept for diagnostics
                f, jac = self.model(p, counts)
                r, jac = whiten(target - f), whiten(jac)
                return r, jac.T @ jac, jac.T @ r, jac
            f, jtj, jtr = self.normal_equations(p, counts, target, noise)
            np.subtract(target, f, out=f)  # the residual in place: one n-vector less
            return whiten(f), jtj, jtr, None

        with np.errstate(over="ignore", invalid="ignore"):
            return _levenberg_marquardt(
                lambda p: whiten(self.model(p, counts, False)[0]), linearise,
                whiten(target), np.clip(p0, lower, upper), lower, upper, max_iter)


class _Solution:
    """LM result: ``jtj`` = JᵀJ at ``x``; ``jac`` itself only for small problems."""

    def __init__(self, x, cost, jtj, jac, status, nfev):
        self.x, self.cost, self.jtj, self.jac = x, cost, jtj, jac
        self.status, self.nfev = status, nfev


def _levenberg_marquardt(model, linearise, target, p, lower, upper, max_iter=100):
    """Levenberg–Marquardt on the normal equations with Marquardt's diagonal scaling.

    The normal equations (p x p) replace the SVD of the n x p Jacobian that scipy's
    ``least_squares`` takes per iteration: the condition numbers here are ~1e2-1e4, so
    squaring them costs nothing, and a 30 000-sample iteration drops from ~50 ms to ~15 ms.
    They also let a long record's Jacobian be formed in blocks (``linearise`` returns
    ``(r, JᵀJ, Jᵀr, J or None)``): memory O(p²) + a block, not 8 p B a sample.
    Bounds (ω0 > 0, |ζ| < 1) are kept by projection.
    """
    r, A, g, jac = linearise(p)
    cost = 0.5 * float(r @ r)
    lam, nfev, status = 1e-3, 1, 0
    for _ in range(max_iter):
        d = np.diag(A).copy()
        d[d <= 0] = 1.0
        improved = False
        # active set: a parameter at a bound whose gradient points out of the box stays
        # there (a clipped step would crawl along the bound for max_iter iterations)
        free = ~(((p <= lower) & (g < 0)) | ((p >= upper) & (g > 0)))
        for _ in range(30):
            try:
                step = np.zeros_like(p)
                step[free] = np.linalg.solve((A + lam * np.diag(d))[np.ix_(free, free)],
                                             g[free])
            except np.linalg.LinAlgError:
                lam *= 10.0
                continue
            trial = np.clip(p + step, lower, upper)
            f_t = model(trial)
            nfev += 1
            r_t = target - f_t
            cost_t = 0.5 * float(r_t @ r_t)
            if np.isfinite(cost_t) and cost_t <= cost:
                improved = True
                break
            lam *= 4.0
        if not improved:
            status = 2  # no decrease possible: at the minimum to round-off
            break
        small_step = np.all(np.abs(trial - p) <= 1e-12 * (np.abs(p) + 1e-12))
        small_gain = cost - cost_t <= 1e-14 * cost
        p, cost = trial, cost_t
        r, A, g, jac = linearise(p)
        lam = max(lam / 3.0, 1e-12)
        if small_step or small_gain:
            status = 1
            break
    return _Solution(p, cost, A, jac, status, nfev)


def _best_start(records, coarse, x_ref, mass, stiffness):
    """Settle the fit from every start strategy on the search copy; keep the lowest RSS.

    Strategies: the peak log decrement (``peak_start``), and from the samples the spectral
    peak with an exponential or a linear (Coulomb) envelope (:mod:`._free_decay_starts`), so
    that coarse, mid-swing or Coulomb-tailed records do not hinge on the peak estimator.
    """
    starts, failures = [], []
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            glob, releases, _ = peak_start(records, x_ref, mass, stiffness, _SEARCH_SAMPLES)
            starts.append(("peaks", glob, releases))
        except IdentificationError as exc:
            failures.append(str(exc))
    # the peak start's resampling is said (the fit itself uses the actual timestamps); its
    # peak-shape complaints are moot for one start of several
    for w in caught:
        if issubclass(w.category, RecordWarning):
            warnings.warn(w.message, stacklevel=3)
    starts += [(name, glob, rel) for name, glob, rel, _ in sample_starts(coarse.t, coarse.y)]
    # starts are ranked by settled fits on a copy of ~2000 samples; the best is settled
    # on the search copy (a merely short fit ranks a wrong local minimum first)
    step = max(1, coarse.n // _RANK_SAMPLES)
    rank = coarse.decimated(step) if step > 1 else coarse
    target = _joined(rank.y)
    best = None
    for name, glob, releases in starts:
        p0 = list(glob)
        for x_r, t_r in releases:
            p0 += [x_r, t_r] + ([0.0] if coarse.drift else [])
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                p, counts, _ = _settle(rank, np.array(p0), max_iter=25)
                r = target - rank.model(p, counts, False)[0]
        except (IdentificationError, np.linalg.LinAlgError, ValueError, OverflowError):
            continue
        rss = float(r @ r)
        if not (np.all(np.isfinite(p)) and math.isfinite(rss)):
            continue
        if best is None or rss < best[0] * (1.0 - 1e-6):  # ties: the earlier (peaks)
            best = (rss, p, name)
    if best is not None:
        with np.errstate(over="ignore", invalid="ignore"):
            p, counts, settled = _settle(coarse, best[1])
        best = (best[0], p, counts, settled, best[2])
    if best is None:
        detail = f" (the peak estimator: {failures[0]})" if failures else ""
        raise IdentificationError(
            "no start strategy (peaks, exponential or linear envelope) gave a converging free-"
            f"decay fit{detail}; check that the record is a free decay, or crop it with "
            "--t-start/--t-end")
    return best[1], best[2], best[3], best[4]


@plausibility_checked
def estimate_output_error(
    records: Record | Sequence[Record],
    *,
    mass: float | None = None,
    stiffness: float | None = None,
    x_ref: float = 0.0,
    drift: bool = False,
    quantisation: float | str | None = "auto",
    bootstrap: int = 25,
    rng: np.random.Generator | int | None = None,
    progress: Callable[[int, int], Any] | None = None,
    passive: bool = True,
) -> Estimate:
    """Fit the exact piecewise free response to every sample of one or more free decays.

    Parameters
    ----------
    records : Record or sequence of Record
        Free decays of one system (e.g. a positive- and a negative-start run), uniformly
        or non-uniformly sampled.
    mass : float, optional
        Known J [kg or kg·m²]; gives K, c and fk in physical units.
    stiffness : float, optional
        Known K [N/m or N·m/rad]; gives J, c and fk in physical units.
    x_ref : float
        Spring zero in the record's position frame [m or rad]. Not identifiable from a
        free decay (it trades with ``theta_k_delta``); 0 assumes encoder zero = spring zero.
    drift : bool
        Fit a linear drift of the measured position per record [m/s or rad/s].
    quantisation : float, "auto" or None
        Encoder step [m or rad]; ``"auto"`` detects it; ``None`` treats the data as
        unquantised. A quantised record gets bootstrap error bars.
    bootstrap : int
        Bootstrap replicates for quantised records [-]; >= 25.
    rng : Generator or int, optional
        Random generator or seed of the bootstrap; default seed 0, so that the same
        record always gets the same error bars.
    progress : callable, optional
        Called as ``progress(done, total)`` after each bootstrap refit (the long part of a
        quantised record: about 0.2-0.4 s a refit at 30 000 samples).
    passive : bool
        Bound the damping ratios at ζ± >= 0 (a passive system); False admits negative
        damping (PD feedback with negative D). ``theta_k_mean >= 0`` always.

    Returns
    -------
    Estimate
        Method ``"output-error"``: ``omega0`` [rad/s], ``zeta_plus``, ``zeta_minus`` [-],
        ``theta_k_mean``, ``theta_k_delta`` [m or rad] and with J or K also ``J``, ``K``,
        ``c_mean``, ``c_delta``, ``fk_mean``, ``fk_delta``; ``covariance`` of all estimated
        ones; ``data_used`` holds per record ``release_x``, ``release_t``, ``n_half``,
        ``drift``, and ``x_ref``.

    Raises
    ------
    IdentificationError
        Too few peaks for the start values, a fit that does not converge, a singular or
        zero covariance.
    ParameterError
        Both ``mass`` and ``stiffness``, a non-positive one, ``bootstrap < 25``, or a bad
        ``quantisation``.

    Notes
    -----
    See the module docstring. Speed: one Jacobian evaluation costs O(samples) with one
    vectorised block per half cycle (the closed form needs no integration); above 60 000
    samples the start values and the discrete stop-count search run on a decimated copy
    and only the final fits of the plausible counts use every sample.

    Memory (issue 12): above 131 072 samples the Jacobian is never formed whole: ``JᵀJ``
    and ``Jᵀr`` are summed over blocks of 131 072 rows (O(p² + block)), so a fit holds
    about eight vectors of the fitted samples (data, model, residuals, trial step, and the
    fitted response and residuals kept in ``data_used``): ~2.7x the record's t, x, u
    (measured 3.7x with reading at 6e5 samples, ``tests/io/test_memory_bounds.py``). Above
    2e6 samples every k-th sample is fitted (see the warning), so at 1e7 samples the fit
    adds ~0.6x.

    Examples
    --------
    >>> from driveid.sim import OscillatorParams, simulate_free_decay
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
    ...                      fk_delta=0.03)
    >>> est = estimate_output_error(simulate_free_decay(p, x0=1.0, duration=20).record,
    ...                             mass=1.0)
    >>> round(est.value("fk_mean"), 6), round(est.value("c_delta"), 6)
    (0.07, 0.1)
    """
    if isinstance(records, Record):
        records = [records]
    records = list(records)
    if not records:
        raise IdentificationError("no record given; pass one record or a list of records")
    if mass is not None and stiffness is not None:
        raise ParameterError("give the mass J or the stiffness K, not both (one fixes the other)")
    for name, value in (("mass", mass), ("stiffness", stiffness)):
        if value is not None and not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number; got {value!r}")
    if not (isinstance(bootstrap, int) and bootstrap >= 25):
        raise ParameterError(f"bootstrap must be an integer >= 25 replicates; got {bootstrap!r}")
    # each record's clock from its first sample: a clock that reads 1.7e9 s (Unix time)
    # leaves ω0·t no digits for the phase and the Jacobian vanished (exit 70); the release
    # times are reported on the file's clock again
    t_first = [float(r.t[0]) for r in records]
    records = [r if t0 == 0.0 else r.replace(t=np.asarray(r.t, float) - t0)
               for r, t0 in zip(records, t_first, strict=True)]
    n_given = sum(r.n for r in records)
    subsample = math.ceil(n_given / _MAX_FIT_SAMPLES)
    # only the kept samples are shifted by x_ref (a full copy was 8 B a sample more)
    y = [np.asarray(r.x, float)[::subsample] - float(x_ref) for r in records]
    if quantisation == "auto":
        # x itself when x_ref = 0 ((x - 0) + 0 == x), so no copy of a long record
        found = [detect_quantum(np.asarray(r.x, float) if x_ref == 0.0
                                else (np.asarray(r.x, float) - float(x_ref)) + x_ref)
                 for r in records]
        quantum = found[0] if all(q is not None for q in found) else None
    elif quantisation is None:
        quantum = None
    else:
        if not (isinstance(quantisation, (int, float)) and quantisation > 0):
            raise ParameterError(
                f"quantisation must be 'auto', None or the encoder step > 0 [m or rad]; got "
                f"{quantisation!r}")
        quantum = float(quantisation)
    # one BLAS thread: the products are small (p = 7..20) and threads only contend
    with threadpool_limits(limits=1):
        problem = _Problem([np.asarray(r.t, float)[::subsample] for r in records], y, drift,
                           passive)
        step = math.ceil(problem.n / _SEARCH_SAMPLES)
        coarse = problem.decimated(step) if step > 1 else problem
        p_best, counts0, settled, start_name = _best_start(records, coarse, x_ref, mass,
                                                           stiffness)
        p0 = p_best
        candidates = _candidates(coarse, p_best, counts0, settled)
        if coarse is not problem:
            candidates = _refine(problem, coarse, candidates)
        if not candidates:
            shown = max(visible_half_cycles(y_r) for y_r in problem.y)
            if shown < 4:  # a release that sticks at once (fifth hostile campaign)
                raise IdentificationError(
                    f"the record shows {shown} half cycle(s) of motion before it rests; a "
                    "free-decay fit needs four or more: release from further out (the "
                    "friction band is a large share of this release), or measure the "
                    "friction with a ramp (driveid identify breakaway)")
            raise IdentificationError(
                "no stop count is consistent with the kinetic friction of the fit; the record "
                "is not a free decay of this model (check for drift, offsets or forcing)")
        chosen = min(candidates, key=lambda c: c["rss"])
        n_par = p0.size
        if problem.n - n_par <= 0:
            raise IdentificationError(f"{problem.n} samples cannot determine {n_par} unknowns")
        # prediction error with an AR noise model of the residuals (white: no change)
        candidates, chosen = noise_rounds(problem, candidates, chosen, n_par, _forbidden)
        dof = problem.n - problem.noise.order * len(records) - n_par
        if dof <= 0:
            raise IdentificationError(f"{problem.n} samples cannot determine {n_par} unknowns "
                                      f"and an AR({problem.noise.order}) noise model")
        s2 = chosen["rss"] / dof
        for c in candidates:
            c["chi2"] = c["rss"] / s2 if s2 > 0 else (0.0 if c is chosen else math.inf)
            try:
                c["cov"] = _ls_covariance(c["sol"], s2)
            except IdentificationError:
                if c is chosen:
                    raise
                c["cov"] = None  # a degenerate rival stop count: dropped, not fatal
        candidates = [c for c in candidates if c["cov"] is not None]
        if quantum is not None:
            boot = bootstrap_covariance(problem, chosen, s2, quantum, bootstrap, rng,
                                         progress)
            if not problem.noise.is_white:
                # coloured: the larger of the bootstrap and the prewhitened analytic error
                # bars (replicates of an estimated AR spectrum came out ~30 % short on
                # AR(1) 0.9 with 0.01 rad steps)
                if np.mean(np.diag(chosen["cov"])[:5] / np.diag(boot)[:5]) > 1.0:
                    boot = chosen["cov"]
            for c in candidates:
                c["cov"] = boot
        p, cov, weights = _combine(candidates)
        verdict = assess(problem, chosen, p)
        p, cov, covariance_kind = apply_verdict(problem, verdict, candidates, p, cov, quantum,
                                                _combine)
        est = _estimate(records, problem, p, cov, chosen, candidates, weights, s2, quantum,
                        mass, stiffness, x_ref, bootstrap, verdict, covariance_kind,
                        start_name, t_first)
    if subsample > 1:
        est = est.with_warnings(
            f"{n_given} samples: fitted on every {subsample}th sample "
            f"({problem.n}) to bound the time; unbiased, with error bars about "
            f"{math.sqrt(subsample):.1f}x the full record's bound (crop with --t-start/--t-end "
            "to fit every sample of a shorter window)")
    return est


def _second_mode_parameters(p, cov, at):
    """``f2`` [Hz] and ``zeta2`` [-] of a fitted second mode (damped ``ω₂``, rate ``σ₂``)."""
    omega, sigma = float(p[at]), float(p[at + 1])
    norm = math.hypot(omega, sigma)
    # delta method: f2 = ω₂/2π, ζ₂ = σ₂/√(ω₂² + σ₂²)
    grads = {"f2": np.array([1.0 / (2 * math.pi), 0.0]),
             "zeta2": np.array([-sigma * omega, omega * omega]) / norm**3}
    block = cov[at:at + 2, at:at + 2]
    values = {"f2": omega / (2 * math.pi), "zeta2": sigma / norm}
    return {name: Parameter(values[name], float(math.sqrt(max(g @ block @ g, 0.0))),
                            "Hz" if name == "f2" else "-") for name, g in grads.items()}


def _ls_covariance(sol, s2):
    # JᵀJ of the full Jacobian when it was kept (as before), else the blockwise sum
    jtj = sol.jac.T @ sol.jac if sol.jac is not None else sol.jtj
    try:
        cov = np.linalg.inv(jtj) * s2
    except np.linalg.LinAlgError:
        raise IdentificationError(
            "the record cannot separate the unknowns (singular Jacobian); record more half "
            "cycles in both directions") from None
    return cov


def _condition(sol):
    """Condition number of the Jacobian [-]: its SVD, or sqrt(cond(JᵀJ)) for long records."""
    if sol.jac is not None:
        return float(np.linalg.cond(sol.jac))
    return float(math.sqrt(np.linalg.cond(sol.jtj)))


def _estimate(records, problem, p, cov, chosen, candidates, weights, s2, quantum, mass,
              stiffness, x_ref, bootstrap, verdict, covariance_kind, start_name, t_first):
    u = _units(records[0])
    richer = verdict["richer"]
    noise = richer["noise"] if richer is not None else problem.noise
    se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    if not np.all(np.isfinite(p)) or np.any(se[:5] <= 0) or not np.all(np.isfinite(se[:5])):
        raise IdentificationError(
            "the fit gave a zero or non-finite standard error: the record carries no noise "
            "information about some parameter; add the record's noise or record longer")
    names = list(GLOBAL_NAMES)
    units = ["rad/s", "-", "-", u["x"], u["x"]]
    params = {n: Parameter(float(p[i]), float(se[i]), un)
              for i, (n, un) in enumerate(zip(names, units, strict=True))}
    cov_names, cov_matrix = names, cov[:5, :5]
    quad = richer["layout"].get("quad") if richer is not None else None
    if quad is not None:
        params["zeta_quad"] = Parameter(float(p[quad]), float(se[quad]), f"1/{u['x']}")
    mode = richer["layout"].get("mode") if richer is not None else None
    if mode is not None:
        params.update(_second_mode_parameters(p, cov, mode))
    if mass is not None or stiffness is not None:
        phys = physical_parameters(p[:5], mass, stiffness)
        free = [n for n in ("J", "K") if not ((n == "J" and mass is not None)
                                             or (n == "K" and stiffness is not None))]
        free += ["c_mean", "c_delta", "fk_mean", "fk_delta"]
        G = np.vstack([np.eye(5), _physical_jacobian(p[:5], mass, stiffness, free)])
        cov_matrix = G @ cov[:5, :5] @ G.T
        cov_names = names + free
        phys_units = {"J": u["J"], "K": u["K"], "c_mean": u["c"], "c_delta": u["c"],
                      "fk_mean": u["f"], "fk_delta": u["f"]}
        for name in ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta"):
            if name in free:
                i = cov_names.index(name)
                params[name] = Parameter(phys[name], float(math.sqrt(max(cov_matrix[i, i], 0))),
                                         phys_units[name])
            else:
                params[name] = Parameter(phys[name], math.nan, phys_units[name], fixed=True)
        if quad is not None:  # q = 4 c2 / (3 pi J)
            scale = 0.75 * math.pi * phys["J"]
            params["c_quad"] = Parameter(scale * float(p[quad]), scale * float(se[quad]),
                                         "N·s²/m²" if u["x"] == "m"
                                         else f"N·m·s²/{u['x']}²")
    lower, _ = problem.bounds(5)
    # at a bound: within a thousandth of a standard error of it (the fits stop there)
    at_bound = [n for i, n in enumerate(GLOBAL_NAMES) if i in (1, 2, 3)
                and params[n].value - lower[i] <= 1e-3 * params[n].stderr]
    if quad is not None and p[quad] <= 1e-3 * se[quad]:
        at_bound.append("zeta_quad")
    warnings = physics_warnings(params, at_bound, x_ref, u, _ZETA_BOUND)
    per = problem.per
    mid_swing = [bool(p[6 + per * r] < t[0] - 0.5 * float(np.median(np.diff(t[:64]))))
                 for r, t in enumerate(problem.t)]
    if any(mid_swing):
        warnings.append("a record starts mid-swing: its release is the velocity zero before "
                        "the first sample (extrapolated)")
    warnings += growth_warnings(problem.y)
    adequacy, adequacy_warnings = adequacy_of(verdict, problem, p, covariance_kind)
    warnings += adequacy_warnings
    if richer is not None:
        residual = richer["residual"] if richer["step"] == 1 else \
            _joined(problem.y) - structure_fitted(problem, richer)
        fitted = _joined(problem.y) - residual
        drift_at = richer["layout"].get("drift")
    else:
        fitted, _ = problem.model(p, chosen["counts"], jacobian=False)
        residual = _joined(problem.y) - fitted
        drift_at = None
    drifts = [float(p[7 + per * r]) if per == 3 else 0.0 for r in range(len(records))]
    if drift_at is not None:
        drifts = [d + float(p[drift_at + r]) for r, d in enumerate(drifts)]
    one_sided = {n: [0.0, params[n].value + 1.645 * params[n].stderr] for n in at_bound}
    return Estimate(
        method="output-error",
        params=params,
        covariance={"names": cov_names, "matrix": cov_matrix},
        warnings=tuple(warnings),
        data_used={
            "release_x": [float(p[5 + per * r] + x_ref) for r in range(len(records))],
            "release_t": [float(p[6 + per * r]) + t_first[r] for r in range(len(records))],
            "drift": drifts,
            "n_half": [int(n) for n in (richer or chosen)["counts"]],
            "x_ref": float(x_ref),
            **({"second_mode": {
                "omega": float(p[mode]), "sigma": float(p[mode + 1]),
                "a": [float(p[mode + 2 + 2 * r]) for r in range(len(records))],
                "b": [float(p[mode + 3 + 2 * r]) for r in range(len(records))]}}
               if mode is not None else {}),
            "fit_x": fitted + x_ref,
            "residual": residual,
        },
        diagnostics={
            "n_samples": problem.n,
            "n_unknowns": int(p.size),
            "residual_rms": math.sqrt(float(residual @ residual) / problem.n),
            "noise_std": math.sqrt(s2) if noise.is_white else math.sqrt(noise.variance),
            "quantum": quantum,
            "bootstrap": bootstrap if quantum is not None else 0,
            "n_candidates": len(candidates),
            "candidate_weights": [float(w) for w in weights],
            "mid_swing": list(mid_swing),
            "condition_number": _condition(chosen["sol"]),
            "nfev": int(chosen["sol"].nfev),
            "start": start_name,
            "noise_model": noise.to_dict(),
            "structure": adequacy["structures"]["chosen"] if adequacy["structures"]
            else "viscous + Coulomb",
            "adequacy": adequacy,
            "at_bound": {n: {"bound": 0.0, "value": params[n].value,
                             "stderr": params[n].stderr, "at_bound": True,
                             "upper_95": one_sided[n][1],
                             "interval": "one-sided [0, upper_95]"} for n in at_bound},
            "one_sided_95": one_sided,
        },
    )
