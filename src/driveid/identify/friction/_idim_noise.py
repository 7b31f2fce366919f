"""Noise model of the IDIM least squares: AR(p) force residuals, feasible GLS, covariances.

Helpers of :func:`driveid.identify.friction.idim.estimate_idim` (kept apart so that module stays
readable): the decimated rows of each record are split into contiguous runs (standstill gaps
cut them), an AR(p) model of the force residual is fitted on the runs
(:func:`driveid.identify.core._noise.fit_noise_model`), regressors and force are prewhitened and
θ refitted, and the adequacy of the result is judged (:mod:`driveid.identify.core._adequacy`).

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999,
       §7.2 (prediction error with a noise model).
.. [2] D. W. K. Andrews, J. C. Monahan, "An improved heteroskedasticity and autocorrelation
       consistent covariance matrix estimator", Econometrica 60 (1992) 953-966,
       doi:10.2307/2951574.
"""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np
from scipy.optimize import lsq_linear

from driveid.errors import IdentificationError
from driveid.identify.core._adequacy import Adequacy, input_cross_correlation, ljung_box
from driveid.identify.core._noise import MAX_ORDER, NoiseModel, fit_noise_model, hac_covariance
from driveid.identify.core._plausibility import held_at_zero
from driveid.identify.core._slow_noise import excess_covariance
from driveid.identify.friction import _idim_eiv

__all__: list[str] = []


def _solve(blocks: list[Any], w: np.ndarray, support: np.ndarray, *, noise: str = "white",
           positive: np.ndarray | None = None,
           position_noise: list[_idim_eiv.RowNoise] | None = None,
           velocity_column: int | None = 1) -> tuple[Any, ...]:
    W = np.vstack([b[0] for b in blocks])
    y = np.concatenate([b[1] for b in blocks])
    root = np.concatenate([np.full(b[1].size, math.sqrt(wi)) for b, wi in zip(blocks, w,
                                                                             strict=True)])
    # a column with no support (a direction never travelled) carries no information
    keep = support & (np.max(np.abs(W), axis=0) > 0)
    Wk, yk = W[:, keep] * root[:, None], y * root
    theta_k, cov_k, _ = _ols(Wk, yk)
    cov_white = cov_k
    runs = _runs(blocks)
    fit: dict[str, Any] = {"cov_white": cov_white, "warnings": []}
    if noise == "ar":
        debias = None
        if position_noise:
            def debias(X: np.ndarray, y_: np.ndarray, th: np.ndarray,
                       ar: tuple[float, ...]) -> np.ndarray:
                return _errors_in_variables(X, y_, ar, th, np.zeros((th.size, th.size)), keep,
                                            blocks, w, position_noise, velocity_column)[0]
        theta_k, cov_k, fit = _gls(Wk, yk, theta_k, cov_k, runs,
                                   np.concatenate([b[3] for b in blocks]), fit, debias)
    else:
        e_w = yk - Wk @ theta_k
        fit["noise_model"] = NoiseModel((), *(2 * [float(e_w @ e_w) / e_w.size]), e_w.size,
                                        (), "white")
        fit["adequacy"] = Adequacy(whiteness=ljung_box(e_w), covariance="white",
                                   notes=("white-noise error bars (noise='white')",))
        fit["system"] = (Wk, yk)
        fit["system_ar"] = ()
    if position_noise:
        theta_k, cov_k, fit["errors_in_variables"] = _errors_in_variables(
            *fit["system"], tuple(fit["system_ar"]), theta_k, cov_k, keep, blocks, w,
            position_noise, velocity_column)
        _note_errors_in_variables(fit, fit["errors_in_variables"])
    if positive is not None:
        pos = np.asarray(positive, bool)[keep]
        if np.any(theta_k[pos] < 0):
            # M > 0, Fv >= 0, Fc >= 0: the bounded least squares on the same (prewhitened)
            # rows; the standard errors stay those of the unconstrained fit
            A, b = fit["system"]
            lower = np.where(pos, 0.0, -np.inf)
            fit["unconstrained"] = dict(zip(np.flatnonzero(keep).tolist(),
                                            theta_k.tolist(), strict=True))
            res = lsq_linear(A, b, bounds=(lower, np.inf))
            theta_k = np.where(res.active_mask < 0, 0.0, res.x)  # exactly at the bound
    theta = np.zeros(W.shape[1])
    theta[keep] = theta_k
    cov = np.full((W.shape[1], W.shape[1]), math.nan)
    cov[np.ix_(keep, keep)] = cov_k
    e_all = y - W @ theta
    splits = np.cumsum([b[1].size for b in blocks])[:-1]
    return theta, cov, np.split(e_all, splits), W, np.split(y, splits), keep, fit


def _errors_in_variables(X: np.ndarray, y: np.ndarray, ar: tuple[float, ...],
                         theta: np.ndarray, cov: np.ndarray, keep: np.ndarray,
                         blocks: list[Any], w: np.ndarray, noise: list[_idim_eiv.RowNoise],
                         velocity_column: int | None
                         ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Correct the fit on rows ``X, y`` (filtered by ``ar``) for the position noise."""
    where = np.cumsum(keep) - 1  # column index among the kept ones

    def kept(col: int | None) -> int | None:
        return int(where[col]) if col is not None and keep[col] else None

    rows = [sum(r - len(ar) for r in _runs([b]) if r > len(ar)) for b in blocks]
    theta_c, cov_c, info = _idim_eiv.correct(
        X, y, theta, cov, [kept(0), kept(velocity_column)],
        list(zip(noise, (float(x) for x in w), rows, strict=True)), ar)
    info["inertia_column"] = kept(0)
    return theta_c, cov_c, info


def _note_errors_in_variables(fit: dict[str, Any], info: dict[str, Any]) -> None:
    """Hand the corrected normal equations to the bounded refit and say what was done."""
    if not info["applied"]:
        share = info.get("noise_share")
        if share is not None:  # found, but too large to take out
            fit["warnings"].append(
                f"the position's noise (sd {max(info['sigma']):.3g}) makes up "
                f"{100 * min(share, 1.0):.0f} % of the acceleration column's power in the "
                "fit, too much to correct: the inertia is biased towards 0; lower the "
                "cut-off (CLI: --cutoff-hz) or decimate more")
        return
    fit["system"] = info.pop("system")
    shift = info["shift_se"][info["inertia_column"]]
    fit["adequacy"] = dataclasses.replace(
        fit["adequacy"], covariance=fit["adequacy"].covariance + " + errors in variables",
        notes=fit["adequacy"].notes + (
            f"the acceleration column carries the position's noise (sd "
            f"{max(info['sigma']):.3g}, {100 * info['noise_share']:.2g} % of its power in the "
            "fit): the fit is corrected for the bias it causes (errors in variables), which "
            f"moved the inertia by {shift:+.2g} standard errors",))


def _held(fit: dict[str, Any], theta: np.ndarray, names: tuple[str, ...],
          units: tuple[str, ...], stderr: np.ndarray) -> dict[str, tuple[dict, str]]:
    """Parameters the bounded fit holds at 0, with their at-bound record and warning."""
    out = {}
    for j, value in (fit.get("unconstrained") or {}).items():
        if value < 0 and theta[j] <= 0:
            hint = ("a passive drive cannot have it; the model misses an effect of the data "
                    "(backlash, compliance, stiction, a load or an offset), or the excitation "
                    "is too weak; the other parameters were refitted with it at 0")
            out[names[j]] = held_at_zero(names[j], float(value), float(stderr[j]), units[j],
                                         hint)
    return out


def _lag1(residuals: list[np.ndarray]) -> float:
    num = sum(float(r[1:] @ r[:-1]) for r in residuals if r.size > 1)
    den = sum(float(r @ r) for r in residuals)
    return num / den if den > 0 else 0.0


def _ar_ols_covariance(W: np.ndarray, model: NoiseModel, runs: list[int]) -> np.ndarray:
    """Covariance ``(WᵀW)⁻¹ WᵀΣW (WᵀW)⁻¹`` of least squares under AR(p) noise.

    ``Σ`` is the noise model's Toeplitz autocovariance within each run (none across runs),
    applied by circulant embedding and FFT: ``O(n log n)`` per column.
    """
    bread = np.linalg.inv(W.T @ W)
    b = np.concatenate([[1.0], -np.asarray(model.ar, float)])
    meat = np.zeros((W.shape[1], W.shape[1]))
    start = 0
    for n in runs:
        block = W[start:start + n]
        start += n
        if n == 0:
            continue
        size = 1 << int(math.ceil(math.log2(2 * n)))
        gain = np.abs(np.fft.rfft(b, size)) ** 2
        acov = np.fft.irfft(model.innovation_variance / gain, size)
        c = np.concatenate([acov[:n], np.zeros(size - 2 * n + 1), acov[1:n][::-1]])
        sw = np.fft.irfft(np.fft.rfft(c)[:, None] * np.fft.rfft(block, size, axis=0), size,
                          axis=0)[:n]
        meat += block.T @ sw
    return bread @ meat @ bread


def _runs(blocks: list[Any]) -> list[int]:
    """Lengths of the contiguous runs of rows (standstill gaps split a record) [-]."""
    lengths: list[int] = []
    for b in blocks:
        t = np.asarray(b[2], float)
        if t.size < 3:
            lengths += [t.size] if t.size else []
            continue
        dt = np.diff(t)
        cuts = np.flatnonzero(dt > 1.5 * float(np.median(dt))) + 1
        lengths += np.diff(np.concatenate([[0], cuts, [t.size]])).astype(int).tolist()
    return lengths


#: Shortest run whose rows feed the AR fit [-]: shorter ones would cap its order at n/20.
_MIN_RUN = 200


def _noise_of(e: np.ndarray, runs: list[int], n_params: int) -> NoiseModel:
    # the AR order is capped at (shortest run)/20: fit on the longest runs that still hold
    # a third of the rows, so that band-limited noise can get the long filter it needs
    total = sum(runs)
    min_run = next((m for m in (20 * MAX_ORDER, 10 * MAX_ORDER, _MIN_RUN)
                    if sum(r for r in runs if r >= m) >= total / 3), _MIN_RUN)
    long_runs = [r >= min_run for r in runs]
    if any(long_runs) and not all(long_runs):
        starts = np.concatenate([[0], np.cumsum(runs)[:-1]])
        idx = np.concatenate([np.arange(s0, s0 + r) for s0, r, ok in
                              zip(starts, runs, long_runs, strict=True) if ok])
        return fit_noise_model(e[idx], segments=[r for r, ok in zip(runs, long_runs,
                                                                     strict=True) if ok],
                               n_params=n_params)
    return fit_noise_model(e, segments=runs, n_params=n_params)


def _gls(Wk: np.ndarray, yk: np.ndarray, theta: np.ndarray, cov: np.ndarray, runs: list[int],
         v: np.ndarray, fit: dict[str, Any], debias: Any = None
         ) -> tuple[np.ndarray, np.ndarray, dict[str, Any]]:
    """Feasible GLS: AR(p) noise of the residual, prewhitened refit (two passes).

    When even the prewhitened residuals are not white and the GLS and OLS estimates
    disagree by more than two standard errors, the model is wrong in a way that weighting
    cannot fix: the OLS estimate (the benchmark's) is kept with a Newey–West covariance.
    ``debias(X, y, theta, ar)``, where given, removes the position noise's bias from both
    before they are compared: prewhitening weights the acceleration noise's band, so the
    bias alone can move them apart (issue 24, AR(1) 0.97 force noise, 1 µm encoder: 7 of
    the 37 records of 200 that left the generalised fit stay on it).
    """
    p = Wk.shape[1]
    theta_ols = theta
    model_ols = model = _noise_of(yk - Wk @ theta, runs, p)
    for k in range(2):
        model = model_ols if k == 0 else _noise_of(yk - Wk @ theta, runs, p)
        if model.is_white:
            break
        Ww, yw = model.whiten(Wk, runs), model.whiten(yk, runs)
        if yw.size <= p:
            model = NoiseModel((), model.variance, model.variance, model.n, (), "burg")
            break
        theta, cov, _ = _ols(Ww, yw)
    Ww, yw = model.whiten(Wk, runs), model.whiten(yk, runs)
    kept = [r - model.order for r in runs if r > model.order]
    e_w = yw - Ww @ theta
    # more lags than AR coefficients, or the χ² test has no degrees of freedom left
    white = ljung_box(e_w, lags=max(20, model.order + 20), fitted=model.order)
    cross = input_cross_correlation(e_w, model.whiten(v, runs))
    notes = []
    kind = "white" if model.is_white else "prewhitened"
    if not model.is_white:
        notes.append(
            f"force residuals are coloured (AR({model.order}), {model.n_eff:.0f} effective of "
            f"{model.n} samples): fitted by generalised least squares on prewhitened rows; "
            "the standard errors account for the correlation")
    if not white["white"] and not model_ols.is_white:
        e_ols = model_ols.whiten(yk - Wk @ theta_ols, runs)
        white_ols = ljung_box(e_ols, lags=max(20, model_ols.order + 20),
                              fitted=model_ols.order)
        if white_ols["white"]:
            # the noise model whitens the ordinary fit's residual, but prewhitening the
            # regressors amplifies the Coulomb steps, where sgn(v) of the filtered velocity
            # is a sample off: keep the ordinary fit, with its covariance under the AR model
            theta, model, white, e_w = theta_ols, model_ols, white_ols, e_ols
            cov = _ar_ols_covariance(Wk, model_ols, runs)
            kind = "noise model (ordinary least squares)"
            cross = input_cross_correlation(e_w, model.whiten(v, runs))
            notes.append("generalised least squares leaves non-white residuals where the "
                         "ordinary fit's are white under the noise model: the ordinary fit is "
                         "reported, with its covariance under the AR noise model")
    if not white["white"]:
        cov = hac_covariance(Ww, e_w, segments=kept)
        kind = "sandwich"
        se = np.sqrt(np.diag(cov))
        apart = theta - theta_ols
        if debias is not None:
            apart = debias(Ww, yw, theta, tuple(model.ar)) - debias(Wk, yk, theta_ols, ())
        moved = np.abs(apart) / np.where(se > 0, se, np.inf)
        if float(np.max(moved)) > 2.0:
            # weighting shifts a misspecified fit towards the frequencies it fits worst
            theta = theta_ols
            cov = _prewhitened_hac(Wk, yk - Wk @ theta_ols, runs)
            kind = "sandwich (ordinary least squares)"
    # noise slower than the AR model sees (1/f-like drift): its power at the record's
    # slowest frequencies, where the offset and the Coulomb term live, taken through the
    # fit (issue 24: offset coverage 0.35 without it; docs/validation.md). A Bartlett
    # sandwich sees lags up to its bandwidth only, so it gets the excess too (issue 24: 1/f
    # offset coverage 0.25 on that path without it)
    ordinary = theta is theta_ols
    extra, slow = _slow_excess(ordinary, Wk, yk, theta, runs, model_ols if ordinary else model,
                               Ww, e_w, kept)
    fit["slow_noise"] = slow
    slow_note = ""
    if slow["applied"] and extra.shape == cov.shape:
        cov = cov + extra
        kind += " + slow-noise excess"
        slow_note = (f"the residuals hold more power at the record's slowest frequencies than "
                     f"the AR({model.order}) noise model (excess ~ f^-{slow['slope']:.2g}, p = "
                     f"{slow['p_value']:.2g}): the standard errors include it")
    if not white["white"]:
        notes.append(
            f"prewhitened residuals are still not white (Ljung-Box p = {white['p_value']:.2g})"
            + (": noise slower than an AR model (1/f-like drift, see below) or dynamics the "
               "model misses" if slow_note else ": the model misses some dynamics")
            + " (compliance, backlash, a load, friction that is not Coulomb + viscous); "
            "standard errors widened by the Newey-West sandwich"
            + (f"; generalised and ordinary least squares disagree by {np.max(moved):.1f} "
               "standard errors, so the ordinary least-squares values are reported"
               if kind.startswith("sandwich (ordinary") else ""))
        fit["warnings"].append(notes[-1])
    if slow_note:
        notes.append(slow_note)
    if not cross["uncorrelated"]:
        notes.append(
            f"residuals correlate with the velocity (|rho| = {cross['max_abs']:.2f} at lag "
            f"{cross['at_lag']} rows): velocity-dependent friction beyond Coulomb + viscous "
            "(Stribeck: identify friction-map) or, at positive lags, the feedback loop")
    fit["noise_model"] = model
    fit["adequacy"] = Adequacy(whiteness=white, cross=cross, covariance=kind, notes=tuple(notes))
    whitened = not (model.is_white or theta is theta_ols)
    fit["system"] = (Ww, yw) if whitened else (Wk, yk)
    fit["system_ar"] = tuple(model.ar) if whitened else ()
    return theta, cov, fit


def _prewhitened_hac(W: np.ndarray, e: np.ndarray, runs: list[int]) -> np.ndarray:
    """Sandwich covariance with the scores prewhitened by a VAR(1) (Andrews–Monahan 1992).

    The Bartlett kernel's few lags miss most of the long-run variance of scores whose noise
    is as slow as AR(1) 0.97; the VAR(1) takes the slow part and the kernel the rest
    (issue 24: M's intervals on this path covered 0.70, now 0.83, AR(1) 0.97 with a 1 µm
    encoder); per parameter the wider of it and the plain sandwich is kept. Eigenvalues of
    the VAR(1) above 0.97 are shrunk to it, as Andrews and Monahan advise, so that ``I − A``
    stays invertible.
    """
    g = W * e[:, None]
    starts = np.concatenate([[0], np.cumsum(runs)[:-1]]).astype(int)
    head = np.concatenate([np.arange(s0 + 1, s0 + r) for s0, r in zip(starts, runs,
                                                                        strict=True) if r > 1])
    A = np.linalg.lstsq(g[head - 1], g[head], rcond=None)[0].T
    vals, vecs = np.linalg.eig(A)
    if np.max(np.abs(vals)) > 0.97:
        vals = np.where(np.abs(vals) > 0.97, 0.97 * vals / np.abs(vals), vals)
        A = np.real(vecs @ np.diag(vals) @ np.linalg.inv(vecs))
    u = np.zeros_like(g)
    u[head] = g[head] - g[head - 1] @ A.T
    # the Bartlett sum of the innovations u: a sandwich of u with unit residuals and bread
    lags = int(4.0 * (u.shape[0] / 100.0) ** (2.0 / 9.0))
    meat_u = hac_covariance(u, np.ones(u.shape[0]), segments=runs, lags=lags,
                            bread=np.eye(W.shape[1]))
    back = np.linalg.inv(np.eye(W.shape[1]) - A)
    bread = np.linalg.inv(W.T @ W)
    cov = bread @ back @ meat_u @ back.T @ bread
    # neither is reliable alone (a VAR(1) of the scores under-reads low-passed noise: M's
    # coverage 0.91 -> 0.84 at decimate=10): per parameter the wider, with its correlations
    plain = hac_covariance(W, e, segments=runs, bread=bread)
    se, se_plain = np.sqrt(np.diag(cov)), np.sqrt(np.diag(plain))
    return cov * np.outer(*(2 * [np.maximum(se_plain, se) / np.where(se > 0, se, 1.0)]))


def _slow_excess(ordinary: bool, Wk: np.ndarray, yk: np.ndarray, theta: np.ndarray,
                 runs: list[int], model: NoiseModel, Ww: np.ndarray, e_w: np.ndarray,
                 kept: list[int]) -> tuple[np.ndarray, dict[str, Any]]:
    """Return the slow-noise excess of the reported fit and its test.

    Tested on the fit's prewhitened residual; taken through the generalised fit, or through
    the ordinary one where that is reported.
    """
    if not ordinary or model.is_white:
        return excess_covariance(Ww, e_w, kept)
    jw = model.whiten(Wk, runs)
    ew = model.whiten(yk - Wk @ theta, runs)
    kept_o = [r - model.order for r in runs if r > model.order]
    return excess_covariance(jw, ew, kept_o, unwhitened=(Wk, runs, model))


def _ols(W: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    m, p = W.shape
    if m <= p:
        raise IdentificationError(f"need more samples than parameters ({p}); got {m}")
    theta, _, rank, sv = np.linalg.lstsq(W, y, rcond=None)
    if rank < p:
        raise IdentificationError(
            f"observation matrix is rank-deficient (rank {rank} < {p}); excite both "
            "acceleration and velocity (and every extra regressor independently); got rank "
            f"{rank}"
        )
    e = y - W @ theta
    sigma2 = float(e @ e) / (m - p)
    cov = sigma2 * np.linalg.inv(W.T @ W)
    return theta, cov, float(sv[0] / sv[-1])
