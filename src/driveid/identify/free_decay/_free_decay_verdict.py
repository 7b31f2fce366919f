"""Verdicts of the free-decay output-error fit: physics warnings, adequacy, error-bar kind.

Helpers of :mod:`driveid.identify.free_decay.output_error` (issue 24); see
:mod:`driveid.identify.free_decay._free_decay_structures` for the structures and noise models.
"""

from __future__ import annotations

import math

import numpy as np

from driveid.identify.core._adequacy import Adequacy
from driveid.identify.core._noise import hac_covariance
from driveid.identify.core._slow_noise import excess_covariance
from driveid.identify.free_decay._free_decay_structures import (
    inadequacy_notes,
    noise_model_widening,
    slow_noise_widening,
    structure_model,
)

__all__ = ["adequacy_of", "apply_verdict", "growth_warnings", "physics_warnings", "slow_noise",
           "structure_fitted"]

#: AR order from which a non-white prewhitened residual may be the noise spectrum itself [-].
HIGH_ORDER = 20
#: Significance of the low-frequency excess test [-] (1 % false alarms on white noise).
SLOW_P = 0.01


def apply_verdict(problem, verdict, candidates, p, cov, quantum, combine):
    """Take a chosen richer structure's fit, or widen inadequate error bars (sandwich).

    Parameters
    ----------
    problem : output_error._Problem
        The fit problem with its final noise model.
    verdict : dict
        :func:`~driveid.identify.free_decay._free_decay_structures.assess` output.
    candidates : list of dict
        Stop-count candidates (``p``, ``counts``, ``sol``, ``cov``, ``chi2``).
    p : ndarray, shape (k,)
        Candidate-averaged estimate.
    cov : ndarray, shape (k, k)
        Its covariance.
    quantum : float or None
        Encoder step [m or rad] (bootstrap error bars) or None.
    combine : callable
        ``combine(candidates) -> (p, cov, weights)``.

    Returns
    -------
    (ndarray, ndarray, str)
        Estimate, covariance and its kind (``prewhitened``, ``bootstrap``, ``sandwich``).
        A prewhitened covariance is widened for the sampling error of the AR noise model
        (:func:`~driveid.identify.free_decay._free_decay_structures.noise_model_widening`).
    """
    richer = verdict["richer"]
    if richer is not None:
        theta, jac = richer["theta"], richer["jac"]
        n_w = richer["white_residual"].size
        s2_w = richer["rss"] / max(n_w - theta.size, 1)
        try:
            cov_s = np.linalg.inv(jac.T @ jac) * s2_w
        except np.linalg.LinAlgError:
            cov_s = np.full((theta.size, theta.size), np.nan)
        kind = "prewhitened"
        if not richer["whiteness"]["white"]:
            cov_s, kind = hac_covariance(jac, richer["white_residual"]), "sandwich"
        if richer["step"] == 1:  # the richer structure absorbs slow noise too
            cov_s = _with_slow_excess(problem, cov_s, jac, richer["white_residual"],
                                      richer.get("noise"))
        return theta, cov_s, kind
    chosen = min(candidates, key=lambda c: c["rss"])
    if quantum is not None:
        # the replicates' noise is the AR model's: it misses the slow excess as well
        return p, slow_noise_widening(problem, chosen, cov), "bootstrap"
    if verdict["whiteness"]["white"]:
        # widened for the AR model's own sampling error and the slow excess it misses
        # (none for white noise)
        return p, noise_model_widening(problem, chosen, cov), "prewhitened"
    sol = chosen["sol"]
    if sol.jac is None:  # long record: no whole Jacobian for the sandwich
        return p, cov, "prewhitened (sandwich not formed above 131 072 samples)"
    r_w = problem.noise.whiten(np.concatenate(problem.y)
                               - problem.model(sol.x, chosen["counts"], False)[0],
                               problem.segments)
    hac = hac_covariance(sol.jac, r_w)
    for c in candidates:
        c["cov"] = hac
    p, cov, _ = combine(candidates)
    # a Bartlett sandwich sees lags up to its bandwidth only, not the record-long wander
    # (sol.jac is the prewhitened Jacobian of the fit)
    return p, _with_slow_excess(problem, cov, sol.jac, r_w), "sandwich"


def _with_slow_excess(problem, cov, jac_w, residual_w, noise=None):
    """``cov`` plus the slow-noise excess through a prewhitened fit (none for white noise)."""
    noise = problem.noise if noise is None else noise
    if noise.is_white or jac_w.shape[1] != cov.shape[0]:
        return cov
    kept = [max(m - noise.order, 0) for m in problem.segments]
    if sum(kept) != jac_w.shape[0]:
        return cov
    extra, info = excess_covariance(jac_w, residual_w, kept)
    problem.slow_excess = info
    return cov + extra if info["applied"] else cov


def structure_fitted(problem, richer):
    """Return the fitted response of a richer structure on every fitted sample.

    Parameters
    ----------
    problem : output_error._Problem
        The fit problem.
    richer : dict
        The structure's fit (``theta``, ``counts``, ``layout``).

    Returns
    -------
    ndarray, shape (n,)
        Position [m or rad].
    """
    lay = richer["layout"]
    return structure_model(problem.t, richer["theta"], richer["counts"], problem.per,
                           "drift" in lay, "quad" in lay, "mode" in lay)


def physics_warnings(params, at_bound, x_ref, u, zeta_bound):
    """Warnings for estimates at a bound or outside physics, each naming the likely cause.

    Parameters
    ----------
    params : dict
        Name -> Parameter of the estimate.
    at_bound : list of str
        Names at their bound.
    x_ref : float
        Spring zero [m or rad].
    u : dict
        Units by kind (``x``, ``c`` ...).
    zeta_bound : float
        Largest damping ratio of the model [-].

    Returns
    -------
    list of str
    """
    warnings = []
    for name in ("zeta_plus", "zeta_minus"):
        z = params[name].value
        if name in at_bound:
            warnings.append(
                f"{name} is at its bound 0 (95 % one-sided upper limit "
                f"{z + 1.645 * params[name].stderr:.3g}): the record shows no viscous damping "
                "in that direction; Coulomb friction or an amplitude-dependent damping the "
                "model lacks may be taking its place (driveid identify hilbert shows the "
                "damping against amplitude)")
        elif not 0.0 < z < zeta_bound - 1e-6:
            warnings.append(
                f"{name} = {z:.4g} is outside (0, 1): the decay is not an underdamped passive "
                "oscillation (negative damping from feedback, or a bad fit); check the record")
    tkm = params["theta_k_mean"]
    if "theta_k_mean" in at_bound:
        warnings.append(
            f"theta_k_mean is at its bound 0 {u['x']}: no Coulomb friction is resolved (95 % "
            f"one-sided upper limit {1.645 * tkm.stderr:.3g} {u['x']}); a decay that slows "
            "less than exponentially at small amplitude (quadratic damping) pushes it there")
    tkd = params["theta_k_delta"]
    if abs(tkd.value) > abs(tkm.value) + 2 * tkd.stderr:
        # |fk_delta| > fk_mean means one direction's kinetic friction pushes: far more
        # likely a spring zero away from the rest position than physics (a given x_ref of
        # 1e6 gave fk_delta = 1.6e7 N·m unwarned, fifth hostile campaign)
        where = ("an offset between the encoder zero and the spring zero looks the same (not "
                 "identifiable from a free decay) - pass the spring zero with x_ref (CLI: "
                 "--x-ref)" if x_ref == 0.0 else
                 f"the spring zero given (x_ref = {x_ref:g} {u['x']}) is likely not where "
                 "the record oscillates about: check it, or drop it")
        warnings.append(
            f"|fk_delta| exceeds fk_mean ({tkd.value:.3g} vs {tkm.value:.3g} {u['x']} as "
            f"theta_k): one direction's friction would push; {where}")
    return warnings


def growth_warnings(ys):
    """Warn for each record whose oscillation grows: no passive free decay does.

    The amplitude of a window is half its 2.5-97.5 % range (a drift inside a fifth of the
    record barely moves it); growth is a last fifth with the largest amplitude of the five,
    1.5 times the first's (a flat lead-in before the release peaks in a middle fifth). The
    fit holds the damping at >= 0, so it cannot follow such a record: a reversed decay of
    the fifth hostile campaign (x17) came back with c_mean = +0.80 ± 4.1 and only
    'ill-determined' warnings.

    Parameters
    ----------
    ys : list of ndarray
        Each record's positions [m or rad].

    Returns
    -------
    list of str
    """
    out = []
    for r, y in enumerate(ys):
        fifth = y.size // 5
        if fifth < 8:
            continue
        amps = [0.5 * float(np.subtract(*np.percentile(y[k * fifth:(k + 1) * fifth],
                                                       [97.5, 2.5]))) for k in range(5)]
        first, last = amps[0], amps[-1]
        if last > 1.5 * first and last >= max(amps):
            which = f"record {r + 1}'s" if len(ys) > 1 else "the record's"
            out.append(
                f"{which} oscillation grows ({last / max(first, 1e-300):.3g}x from its first "
                "to its last fifth): a passive free decay only decays, and this fit's damping "
                "is held >= 0, so its numbers do not describe the record; it is driven or "
                "unstable (negative damping from a feedback loop), or its time runs "
                "backwards (driveid identify hilbert shows the damping against time)")
    return out


def adequacy_of(verdict, problem, p, covariance_kind):
    """Return the Adequacy record (JSON form) and its warnings.

    Parameters
    ----------
    verdict : dict
        :func:`~driveid.identify.free_decay._free_decay_structures.assess` output.
    problem : output_error._Problem
        The fit problem.
    p : ndarray, shape (k,)
        The estimate.
    covariance_kind : str
        How the error bars were formed.

    Returns
    -------
    (dict, list of str)
        Adequacy and warnings (inadequate: what the residuals show, the command that fits it).
    """
    richer = verdict["richer"]
    test = verdict["structures"]
    white = richer["whiteness"] if richer is not None else verdict["whiteness"]
    notes, warnings = [], []
    if test is not None:
        notes.append(test["comparison"]["reason"])
    if not white["white"]:
        if richer is not None:
            w_res, raw = richer["white_residual"], richer["residual"]
        else:
            raw, w_res = verdict["raw_residual"], verdict["white_residual"]
        dt = float(np.median(np.diff(problem.t[0][:256])))
        omega_d = float(p[0]) * math.sqrt(max(1.0 - float(p[1]) ** 2, 1e-12))
        found = inadequacy_notes(w_res, raw, 1.0 / dt, omega_d,
                                 test["comparison"] if test else None)
        order = (richer["noise"] if richer is not None else problem.noise).order
        if order >= HIGH_ORDER:
            # an AR model of a filter's stopband (zeros at Nyquist) never whitens fully: the
            # residuals can be the noise itself (seen on low-pass noise of a correct model)
            found.append(
                f"or the noise itself: its AR({order}) model is long, as for a sensor "
                "behind a low-pass filter, whose stopband no AR model follows; the sandwich "
                "error bars stay honest then")
        notes += found
        warnings.append(
            "no structure tried (viscous + Coulomb, + drift, + quadratic damping) explains "
            "this record: its prewhitened residuals are not white (Ljung-Box p = "
            f"{white['p_value']:.2g}); " + "; ".join(found)
            + f"; error bars are {covariance_kind}")
    slow = slow_noise(verdict["white_residual"], problem, p)
    excess = getattr(problem, "slow_excess", None)
    widened = bool(excess and excess["applied"])
    if slow["excess"] and widened:
        slow["note"] = slow["note"].replace(
            "are likely too small", "include the excess seen at the record's slowest "
            "frequencies (a power law, taken flat below half of 1/T), but wander slower "
            "than that is not seen and they may still be too small")
    elif widened:
        slow["note"] = (
            "slow noise: the prewhitened residuals' slowest Fourier frequencies hold a "
            f"power-law excess over the noise model (p = {excess['p_value']:.2g}); the error "
            "bars of fk_delta (theta_k_delta) and c_delta include it, but wander slower than "
            "half of 1/T is not seen; record several correlation times longer, fit several "
            "records, or add --drift")
    if slow["note"]:
        notes.append(slow["note"])
        warnings.append(slow["note"])
    adequacy = Adequacy(whiteness=white,
                        structures=_json_structures(test),
                        covariance=covariance_kind, notes=tuple(notes)).to_dict()
    # adequate: the structure finally fitted (the richer one where chosen) leaves white
    # prewhitened residuals
    adequacy["adequate"] = bool(white["white"])
    adequacy["slow_noise"] = {k: v for k, v in slow.items() if k != "note"}
    # the power-law excess at the slowest Fourier frequencies and whether it widened
    adequacy["slow_noise"]["excess_fit"] = getattr(problem, "slow_excess", None)
    return adequacy, warnings




def slow_noise(white_residual, problem, p):
    """Test the prewhitened residuals for power the noise model misses below half the mode.

    Noise slower than the record (1/f-like wander, sensor drift) is absorbed by the offset-
    and drift-like unknowns (``theta_k_delta``, the damping asymmetry): the residuals, and the
    AR model fitted to them, no longer show it, and those error bars come out too small. What
    a record still shows is the part at periods of a tenth to a third of it: the periodogram
    of the prewhitened residuals at the Fourier frequencies below half the damped mode
    frequency, pooled over records, against its white-noise mean ``σ_w²`` (``2m R ~ χ²_{2m}``
    for ``m`` ordinates). Not in the thesis.

    Parameters
    ----------
    white_residual : ndarray, shape (n_w,)
        Prewhitened residuals of every record, stacked [m or rad].
    problem : output_error._Problem
        The fit problem (records, noise model).
    p : ndarray, shape (k,)
        The estimate (``omega0``, ``zeta_plus`` first).

    Returns
    -------
    dict
        ``excess`` (bool), ``ratio`` (mean ordinate / σ_w² [-]), ``ordinates`` (m),
        ``p_value``, ``below_hz`` [Hz], ``note`` (the warning, naming the record length and
        the parameters affected).
    """
    from scipy.stats import chi2

    order = problem.noise.order
    f_d = float(p[0]) * math.sqrt(max(1.0 - float(p[1]) ** 2, 1e-12)) / (2.0 * math.pi)
    w = np.asarray(white_residual, float)
    var = float(w @ w) / max(w.size, 1)
    total, count, start, duration = 0.0, 0, 0, 0.0
    for t in problem.t:
        m = max(t.size - order, 0)
        part = w[start:start + m]
        start += m
        span = float(t[-1] - t[0])
        duration = max(duration, span)
        if part.size < 16 or span <= 0:
            continue
        k = int(0.5 * f_d * span)  # Fourier frequencies j/span below f_d/2
        if k < 1:
            continue
        spec = np.abs(np.fft.rfft(part - part.mean())[1:k + 1]) ** 2 / part.size
        total += float(spec.sum())
        count += spec.size
    out = {"excess": False, "ratio": math.nan, "ordinates": count, "p_value": 1.0,
           "below_hz": 0.5 * f_d, "note": ""}
    if count < 3 or not var > 0:
        return out
    ratio = total / count / var
    p_value = float(chi2.sf(2.0 * count * ratio, 2 * count))
    out.update(ratio=ratio, p_value=p_value, excess=bool(p_value < SLOW_P))
    if out["excess"]:
        out["note"] = (
            f"slow noise: below {0.5 * f_d:.3g} Hz the prewhitened residuals hold {ratio:.1f}x "
            f"the power of the noise model (p = {p_value:.2g}); wander this slow (1/f-like "
            f"noise, sensor drift) is partly absorbed as an offset and a drift in a "
            f"{duration:.3g} s record, so the error bars of fk_delta (theta_k_delta) and "
            "c_delta (the damping asymmetry) are likely too small; record several "
            "correlation times longer, fit several records, or add --drift")
    return out


def _json_structures(test):
    """Return the structure comparison in JSON form, with its decimation."""
    if test is None:
        return None
    comp = dict(test["comparison"])
    comp["decimation"] = int(test["step"])
    return comp
