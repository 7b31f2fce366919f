r"""Model adequacy of a fit: residual whiteness, residual–input correlation, nested structures.

Every whole-record fit asks three questions of its residuals (Ljung 1999 [1]_, §16.6):

1. Are the prewhitened residuals white? Ljung–Box ``Q = n(n+2) Σ_{k=1}^{m} r_k²/(n-k)``
   against χ²(m - p_noise).
2. Are they uncorrelated with the input (where there is one)? ``S = n Σ_{k=-m}^{m} ρ_{eu}(k)²``
   against χ²(2m + 1), with ``ρ_{eu}`` the cross-correlation of the residuals and the
   prewhitened input.
3. Does a richer structure that real records often need (static above kinetic friction,
   quadratic damping, drift, a second mode) explain the record better? Nested structures are
   compared by the Bayesian information criterion ``N ln σ̂_w² + k ln N`` on the prewhitened
   innovations; the simplest structure within BIC's reach is kept, and the likelihood-ratio
   statistic ``N ln(σ̂²_simple / σ̂²_rich)`` against χ²(Δk) says how strongly the data ask for
   the richer one.

A structure that fails (1) or (2) is called inadequate in plain words, with the effect its
residuals show; its error bars are then widened by the sandwich covariance of
:mod:`driveid.identify.core._noise`.

References
----------
.. [1] L. Ljung, *System Identification: Theory for the User*, 2nd ed., Prentice Hall, 1999.
.. [2] G. M. Ljung, G. E. P. Box, "On a measure of lack of fit in time series models",
       Biometrika 65 (1978) 297-303, doi:10.1093/biomet/65.2.297.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.stats import chi2

__all__ = ["WHITE_P", "ljung_box", "input_cross_correlation", "Structure",
           "compare_structures", "Adequacy"]

#: p-value below which residuals are called not white or input-correlated [-].
WHITE_P = 0.01
#: Likelihood-ratio p-value below which a richer nested structure is asked for [-].
NESTED_P = 0.001


def _acf(e: np.ndarray, m: int) -> np.ndarray:
    denom = float(e @ e)
    if denom == 0.0:
        return np.zeros(m)
    if m <= 64:  # direct lagged products: O(m n) time, no padded FFT (4x the record's bytes)
        return np.array([float(e[k:] @ e[:-k]) for k in range(1, m + 1)]) / denom
    size = 1 << int(math.ceil(math.log2(2 * e.size)))
    spec = np.fft.rfft(e, size)
    return np.fft.irfft(spec * np.conj(spec), size)[1:m + 1] / denom


def ljung_box(residual: np.ndarray, lags: int = 20, fitted: int = 0) -> dict[str, Any]:
    """Ljung–Box whiteness test and the ±1.96/√n band count of a residual sequence.

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Residuals in time order [any unit].
    lags : int
        Autocorrelation lags m [-]; capped at n/5.
    fitted : int
        AR coefficients fitted to these residuals [-]; the χ² degrees of freedom are
        ``m - fitted`` (at least 1).

    Returns
    -------
    dict
        ``test``, ``lags``, ``statistic`` (Q), ``p_value``, ``white`` (p >= 0.01),
        ``band_fraction``, ``acf`` (ndarray, lags 1..m).

    Examples
    --------
    >>> ljung_box(np.random.default_rng(0).normal(size=2000))["white"]
    True
    """
    e = np.asarray(residual, float)
    e = e - float(np.mean(e))
    n = e.size
    m = int(max(1, min(lags, n // 5)))
    acf = _acf(e, m)
    q = float(n * (n + 2) * np.sum(acf**2 / (n - np.arange(1, m + 1))))
    dof = max(m - int(fitted), 1)
    p = float(chi2.sf(q, dof))
    band = 1.96 / math.sqrt(max(n, 1))
    return {"test": "ljung-box", "lags": m, "statistic": q, "p_value": p,
            "white": bool(p >= WHITE_P), "band_fraction": float(np.mean(np.abs(acf) > band)),
            "acf": acf}


def input_cross_correlation(residual: np.ndarray, u: np.ndarray, lags: int = 20
                            ) -> dict[str, Any]:
    """Test residuals for correlation with an input at lags -m..m.

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Prewhitened residuals [any unit].
    u : ndarray, shape (n,)
        The input, prewhitened by the same filter where there is one [any unit].
    lags : int
        Largest lag m [-]; capped at n/5.

    Returns
    -------
    dict
        ``test``, ``lags``, ``statistic`` S, ``p_value`` (χ²(2m+1)), ``uncorrelated``
        (p >= 0.01), ``max_abs`` (largest |ρ|) and ``at_lag``.
    """
    e = np.asarray(residual, float) - float(np.mean(residual))
    x = np.asarray(u, float) - float(np.mean(u))
    n = min(e.size, x.size)
    e, x = e[:n], x[:n]
    m = int(max(1, min(lags, n // 5)))
    norm = math.sqrt(float(e @ e) * float(x @ x))
    if norm == 0.0:
        return {"test": "cross-correlation", "lags": m, "statistic": 0.0, "p_value": 1.0,
                "uncorrelated": True, "max_abs": 0.0, "at_lag": 0}
    rho = np.array([float(e[k:] @ x[:n - k]) if k >= 0 else float(e[:n + k] @ x[-k:])
                    for k in range(-m, m + 1)]) / norm
    s = float(n * np.sum(rho**2))
    p = float(chi2.sf(s, 2 * m + 1))
    worst = int(np.argmax(np.abs(rho)))
    return {"test": "cross-correlation", "lags": m, "statistic": s, "p_value": p,
            "uncorrelated": bool(p >= WHITE_P), "max_abs": float(abs(rho[worst])),
            "at_lag": worst - m}


@dataclass(frozen=True)
class Structure:
    """One fitted model structure, for :func:`compare_structures`.

    Attributes
    ----------
    name : str
        Short name, e.g. ``"kinetic = static"`` or ``"+ quadratic damping"``.
    n_params : int
        Estimated parameters including the noise model's [-].
    innovation_variance : float
        Mean square of the prewhitened residuals σ̂_w² [unit²].
    n : int
        Prewhitened samples [-].
    effect : str
        The physical effect this structure adds, in plain words (empty for the base).
    command : str
        What fits it, named for a user (e.g. ``"identify logdec --damping quadratic"``).
    """

    name: str
    n_params: int
    innovation_variance: float
    n: int
    effect: str = ""
    command: str = ""

    @property
    def bic(self) -> float:
        """``n ln σ̂_w² + k ln n`` [-]."""
        return self.n * math.log(max(self.innovation_variance, 1e-300)) + \
            self.n_params * math.log(max(self.n, 2))


def compare_structures(candidates: Sequence[Structure]) -> dict[str, Any]:
    """Choose among nested structures by BIC; say which effect the data ask for and how strongly.

    Parameters
    ----------
    candidates : sequence of Structure
        The base structure first, then richer ones that contain it.

    Returns
    -------
    dict
        ``chosen`` (name), ``base`` (name), ``table`` (name, n_params, bic, lr, p_value per
        candidate; LR against the base), ``needed`` (names of the richer structures with
        LR p < 0.001) and ``reason`` (one sentence).
    """
    if not candidates:
        raise ValueError("compare_structures needs at least one structure")
    base = candidates[0]
    table = []
    for c in candidates:
        lr = base.n * math.log(max(base.innovation_variance, 1e-300)
                               / max(c.innovation_variance, 1e-300)) if c is not base else 0.0
        dk = c.n_params - base.n_params
        p = float(chi2.sf(lr, dk)) if dk > 0 else 1.0
        table.append({"name": c.name, "n_params": c.n_params, "bic": c.bic,
                      "lr": lr, "p_value": p, "effect": c.effect, "command": c.command})
    chosen = min(candidates, key=lambda c: c.bic)
    needed = [row["name"] for row in table[1:] if row["p_value"] < NESTED_P]
    if chosen is base:
        reason = (f"'{base.name}' kept: no richer structure lowers the information criterion"
                  + (f" (tried: {', '.join(c.name for c in candidates[1:])})"
                     if len(candidates) > 1 else ""))
    else:
        row = table[list(candidates).index(chosen)]
        reason = (f"'{chosen.name}' chosen over '{base.name}': BIC lower by "
                  f"{base.bic - chosen.bic:.1f}, likelihood ratio {row['lr']:.1f} on "
                  f"{chosen.n_params - base.n_params} more parameter(s)"
                  + (f" ({chosen.effect})" if chosen.effect else ""))
    return {"chosen": chosen.name, "base": base.name, "table": table, "needed": needed,
            "reason": reason}


@dataclass(frozen=True)
class Adequacy:
    """Adequacy verdict of one fit, carried in ``Estimate.diagnostics["adequacy"]``.

    Attributes
    ----------
    whiteness : dict
        :func:`ljung_box` of the prewhitened residuals.
    cross : dict or None
        :func:`input_cross_correlation`, where the record has an input.
    structures : dict or None
        :func:`compare_structures`, where nested structures were fitted.
    covariance : str
        ``"prewhitened"`` (the noise model explains the residuals) or ``"sandwich"``
        (they do not: Newey–West widened error bars).
    notes : tuple of str
        Plain-words findings (the effect the residuals show and what fits it).
    """

    whiteness: dict[str, Any]
    cross: dict[str, Any] | None = None
    structures: dict[str, Any] | None = None
    covariance: str = "prewhitened"
    notes: tuple[str, ...] = field(default=())

    @property
    def adequate(self) -> bool:
        """True: white, input-uncorrelated residuals and no richer structure needed."""
        ok = bool(self.whiteness.get("white", True))
        if self.cross is not None:
            ok = ok and bool(self.cross.get("uncorrelated", True))
        if self.structures is not None:
            ok = ok and self.structures["chosen"] == self.structures["base"]
        return ok

    def to_dict(self) -> dict[str, Any]:
        """Return the JSON form (the ACF as a short list)."""
        white = {k: v for k, v in self.whiteness.items() if k != "acf"}
        return {"adequate": self.adequate, "whiteness": white, "cross": self.cross,
                "structures": self.structures, "covariance": self.covariance,
                "notes": list(self.notes)}
