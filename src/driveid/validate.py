r"""Model validation: simulate an identified model on a record and judge the residuals.

Like MATLAB's ``compare``/``resid``: :func:`compare` simulates the identified model with the
record's input and initial state, and reports

* the fit percentage (normalised root-mean-square error)
  ``fit = 100·(1 - ‖y - ŷ‖/‖y - mean(y)‖)`` [%];
* the residual rms [m or rad] (for a held-out record: the prediction error);
* the residual autocorrelation ``r_k`` for lags 1..m and its whiteness: the Ljung–Box
  statistic ``Q = n(n+2) Σ r_k²/(n-k)`` against χ²(m), and the fraction of ``r_k`` outside
  the ``±1.96/√n`` band.

Supported estimates (dispatch on the parameters, then on ``Estimate.method``):

* free decays with ``omega0``, ``zeta_plus``, ``zeta_minus``, ``theta_k_mean``,
  ``theta_k_delta`` (``logdec-lsq``, ``logdec-thesis-*``, ``output-error``): simulated by
  :func:`driveid.sim.simulate_free_decay` (de Marchi 1998, Eqs. 2.139-2.143, 2.156; static
  friction taken equal to kinetic, since a free decay does not identify it); a fit whose
  structure is ``+ quadratic damping`` with its equivalent linearisation per half cycle,
  ``ζ_k = ζ± + q A_k`` (``zeta_quad``), as it was fitted. The initial state is the
  estimate's own release for a record it was fitted to (``index=``), else (held-out
  records) the release position and time fitted with the model parameters fixed, from the
  first peak and from the velocity zero half a period before it (a mid-swing start);
* PHO campaigns (``pho-campaign``, ``pho-output-error``): the delayed PD loop of the record's
  ``meta["P"]``, ``meta["D"]`` around the identified J, C, K and friction, released at rest
  from ``meta["x0"]`` (Eq. 2.180);
* forced response and forced PHO: the record's ``u`` drives the linear J, C, K (plus the
  delayed loop), initial state fitted by linear least squares (Eq. 2.176);
* IDIM (``idim-ls-*``) and Coulomb + viscous friction maps: the record's ``u`` drives the
  identified inertia and friction (``K = 0``; a friction map's inertia is given or fitted
  by output error), x0 the mean residual and v0 fitted from the first samples' slope.

The drive models are built in :mod:`driveid._validate_models` and simulated by
:func:`driveid.sim.simulate_drive`.

Residuals of an encoder record are rounding errors; they are close to white while the
signal moves many counts per sample and correlated on slow stretches. The whiteness test
uses every sample; read it with the fit percentage.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.optimize import least_squares
from scipy.stats import chi2

from driveid._validate_models import FREE_DECAY, drive_model, kind_of, simulate_model
from driveid.errors import IdentificationError
from driveid.identify.core._noise import NoiseModel
from driveid.identify.core.estimate import Estimate
from driveid.identify.free_decay._free_response import (
    kinetic_stop_count,
    response,
    second_mode,
)
from driveid.io.record import Record
from driveid.sim import OscillatorParams, simulate_free_decay

__all__ = ["Comparison", "compare", "fit_percent", "simulate", "whiteness"]

_FREE_DECAY = FREE_DECAY
#: Ljung–Box p-value below which residuals are called not white [-].
WHITE_P = 0.01


@dataclass(frozen=True)
class Comparison:
    """A record against the simulated response of an identified model.

    Attributes
    ----------
    t, y, y_hat : ndarray
        Times [s], measured and simulated positions [m or rad] of the compared samples.
    fit : float
        ``100·(1 - ‖y - ŷ‖/‖y - mean y‖)`` [%]; 100 is perfect.
    residual_rms : float
        Root-mean-square of ``y - ŷ`` [m or rad].
    whiteness : dict
        ``test`` ("ljung-box"), ``lags``, ``statistic``, ``p_value``, ``white`` (p >= 0.01),
        ``band_fraction`` (share of lags outside ±1.96/√n), ``acf`` (lags 1..m); for a
        position fit with a coloured noise model (free decay, PHO) on one of its own
        records also ``prewhitened``: the same test on ``A(q)`` applied to the residual,
        with the model's name. Residuals white once prewhitened are coloured as the fit
        expected and draw no warning.
    held_out : bool
        True when the initial state was fitted here (the record was not in the estimate).
    warnings : tuple of str
        Reasons to distrust the model on this record.
    unit : str
        Unit of ``y`` (``"rad"`` or ``"m"``), shown on the figure's axes.
    model : dict
        What was simulated: ``kind`` (``"free-decay"``, ``"pho"``, ``"forced"``, ``"idim"``,
        ``"friction-map"``), the parameters in SI units and the initial state ``x0``
        [m or rad], ``v0`` [m/s or rad/s] with how it was obtained.
    """

    t: np.ndarray
    y: np.ndarray
    y_hat: np.ndarray
    fit: float
    residual_rms: float
    whiteness: Mapping[str, Any]
    held_out: bool
    warnings: tuple[str, ...] = field(default=())
    unit: str = "rad"
    model: Mapping[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Return a JSON-ready summary (no time series): fit [%], residual_rms, whiteness.

        ``prediction_error`` is the residual rms of a held-out record, else None.
        """
        w = dict(self.whiteness)
        w["acf"] = [float(a) for a in w["acf"]]
        if "prewhitened" in w:
            w["prewhitened"] = {**w["prewhitened"],
                                "acf": [float(a) for a in w["prewhitened"]["acf"]]}
        return {"fit": self.fit, "residual_rms": self.residual_rms,
                "prediction_error": self.residual_rms if self.held_out else None,
                "whiteness": w,
                "held_out": self.held_out, "n": int(self.t.size),
                "warnings": list(self.warnings), "model": dict(self.model)}

    def plot(self, ax: Any = None) -> Any:
        """Overlay measured and simulated response, residuals and their autocorrelation.

        Parameters
        ----------
        ax : sequence of 3 matplotlib Axes, optional
            Where to draw; a new figure when omitted.

        Returns
        -------
        matplotlib.figure.Figure
            The figure.
        """
        import matplotlib.pyplot as plt

        if ax is None:
            fig, ax = plt.subplots(3, 1, figsize=(8, 7), constrained_layout=True)
        else:
            fig = ax[0].figure
        ax[0].plot(self.t, self.y, "k.", ms=2, label="measured")
        ax[0].plot(self.t, self.y_hat, "C1-", lw=1, label=f"model (fit {self.fit:.2f} %)")
        ax[0].set_ylabel(f"position x [{self.unit}]")
        ax[0].legend(loc="upper right")
        ax[1].plot(self.t, self.y - self.y_hat, "C0-", lw=0.5)
        ax[1].set_ylabel(f"residual [{self.unit}]")
        ax[1].set_xlabel("t [s]")
        acf = np.asarray(self.whiteness["acf"])
        band = 1.96 / math.sqrt(max(self.t.size, 1))
        ax[2].bar(np.arange(1, acf.size + 1), acf, color="C0")
        ax[2].axhline(band, color="k", ls="--", lw=0.8)
        ax[2].axhline(-band, color="k", ls="--", lw=0.8)
        ax[2].set_xlabel("lag [samples]")
        ax[2].set_ylabel("residual autocorrelation [-]")
        ax[2].set_title(f"Ljung–Box p = {self.whiteness['p_value']:.3g}")
        return fig


def fit_percent(y: np.ndarray, residual: np.ndarray) -> float:
    """Return ``100·(1 - ‖residual‖/‖y - mean y‖)`` [%] (NaN for a constant ``y``).

    Parameters
    ----------
    y : ndarray
        Measured values [any unit].
    residual : ndarray
        ``y`` minus the simulated values [same unit].

    Returns
    -------
    float
        The normalised root-mean-square fit; 100 is perfect.
    """
    spread = float(np.linalg.norm(y - np.mean(y)))
    return 100.0 * (1.0 - float(np.linalg.norm(residual)) / spread) if spread > 0 else math.nan


def whiteness(residual: np.ndarray, lags: int = 20) -> dict[str, Any]:
    """Ljung–Box whiteness test and ±1.96/√n band count of a residual sequence.

    Parameters
    ----------
    residual : ndarray, shape (n,)
        Residuals [any unit], in time order.
    lags : int
        Number of autocorrelation lags m [-]; capped at n/5.

    Returns
    -------
    dict
        ``test``, ``lags``, ``statistic`` (Q), ``p_value`` (χ²(m) upper tail), ``white``
        (p >= 0.01), ``band_fraction``, ``acf`` (ndarray, lags 1..m).

    Examples
    --------
    >>> w = whiteness(np.random.default_rng(0).normal(size=2000))
    >>> w["white"]
    True
    """
    e = np.asarray(residual, float) - float(np.mean(residual))
    n = e.size
    m = int(max(1, min(lags, n // 5)))
    denom = float(e @ e)
    if denom == 0.0:
        acf = np.zeros(m)
    else:
        acf = np.array([float(e[k:] @ e[:-k]) / denom for k in range(1, m + 1)])
    q = float(n * (n + 2) * np.sum(acf**2 / (n - np.arange(1, m + 1))))
    p = float(chi2.sf(q, m))
    band = 1.96 / math.sqrt(n)
    return {"test": "ljung-box", "lags": m, "statistic": q, "p_value": p,
            "white": bool(p >= WHITE_P), "band_fraction": float(np.mean(np.abs(acf) > band)),
            "acf": acf}


def _refuse_divergence(y, y_hat, model) -> None:
    """Refuse a simulation that ran away from the record (a fit % of -1e98 before).

    A model whose damping or viscous friction is negative (an edited result, or a fit far
    off) grows without bound; the comparison would say nothing but that.
    """
    scale = float(np.ptp(y)) + float(np.max(np.abs(y))) + 1e-300
    worst = float(np.max(np.abs(y_hat))) if y_hat.size else 0.0
    if math.isfinite(worst) and worst <= 1e6 * scale:
        return
    negative = [k for k in ("c_mean", "Fv", "Fv_plus", "Fv_minus", "zeta_plus", "zeta_minus")
                if isinstance(model.get(k), (int, float)) and model[k] < 0]
    cause = (f"its {', '.join(negative)} < 0 (negative damping) makes it grow without bound"
             if negative else "it is unstable over this record")
    raise IdentificationError(
        f"the identified model's response runs away from the record (it reaches "
        f"{worst:.3g} against at most {scale:.3g} measured): {cause}; check the result's "
        "values, or identify the record again")


def _prewhitened(resid, estimate, held_out, lags):
    """Whiteness of the residual through the fit's AR noise model ``A(q)``, or None.

    Only for a position fit (free decay, PHO) on one of its own records: its noise model
    describes the position residual at that record's sample rate (an IDIM or friction-map
    model is of the force; a held-out record may have another rate).
    """
    info = estimate.diagnostics.get("noise_model")
    if held_out or not isinstance(info, Mapping) or not info.get("ar") \
            or kind_of(estimate) not in ("free-decay", "pho"):
        return None
    noise = NoiseModel(tuple(float(a) for a in info["ar"]))
    if resid.size <= 5 * (noise.order + 1):
        return None
    w = whiteness(noise.whiten(resid), lags)
    return {**w, "noise_model": info.get("kind", f"AR({noise.order})")}


def _base(estimate: Estimate) -> list[float]:
    kind_of(estimate)  # refuses, in one line, what no model here can simulate
    base = [estimate.value(n) for n in _FREE_DECAY]
    omega0 = base[0]
    # K = ω0² must be a float (an edited result with ω0 = 1e308 overflowed: exit 70)
    if not (math.isfinite(omega0) and 0.0 < omega0 < 1e150):
        raise IdentificationError(
            f"the estimate's omega0 = {omega0:.6g} rad/s cannot be simulated (it must be "
            "positive, and its square a number); check the result file")
    return base


def _params(base: list[float]) -> OscillatorParams:
    """Oscillator with J = 1 and the same ω0, ζ± and θk (the position response is equal)."""
    omega0, zp, zm, tkm, tkd = base
    K = omega0**2
    return OscillatorParams(J=1.0, K=K, c_mean=omega0 * (zp + zm), c_delta=omega0 * (zp - zm),
                            fk_mean=max(K * tkm, 0.0), fk_delta=K * tkd)


def _fit_release(t, y, base, zeta_amp=0.0):
    """Release position and time of a held-out record with the model parameters fixed."""
    from driveid.signal.peaks import find_oscillation_peaks

    pk = find_oscillation_peaks(Record(t=t, x=y, max_jitter=None).resampled_uniform(
        purpose="the start values of the release"))
    x0, t0 = float(pk.x[0]), float(pk.t[0])

    def residual(q):
        n, _ = kinetic_stop_count(base, q[0], q[1], float(t[-1]), zeta_amp=zeta_amp)
        return response(t, base, q[0], q[1], max(n, 1), jacobian=False,
                        zeta_amp=zeta_amp)[0] - y

    # a record that starts mid-swing was released before its first sample: the velocity
    # zero half a period before the first peak is tried beside the peak itself
    sols = [least_squares(residual, start, x_scale=[max(abs(x0), 1e-9), 1.0 / base[0]])
            for start in ([x0, t0], [-x0, t0 - math.pi / base[0]])]
    best = min(sols, key=lambda sol: sol.cost)
    return float(best.x[0]), float(best.x[1])


def _simulate_free_decay(record, estimate, index):
    base = _base(estimate)
    # the "+ quadratic damping" structure: its equivalent linearisation, as fitted
    quad = estimate.value("zeta_quad") if "zeta_quad" in estimate.params else 0.0
    t = np.asarray(record.t, float)
    x_ref = float(estimate.data_used.get("x_ref", 0.0) or 0.0)
    releases = estimate.data_used.get("release_x")
    drift = 0.0
    if index is not None and releases is not None:
        if not 0 <= index < len(releases):
            raise IdentificationError(
                f"index {index} is out of range: the estimate was fitted to {len(releases)} "
                "records")
        x_r = float(releases[index]) - x_ref
        t_r = float(estimate.data_used["release_t"][index])
        drift = float((estimate.data_used.get("drift") or [0.0] * len(releases))[index])
        held_out = False
    else:
        x_r, t_r = _fit_release(t, np.asarray(record.x, float) - x_ref, base, quad)
        held_out = True
    y_hat = np.full(t.size, x_r)
    after = t >= t_r
    if np.any(after) and quad:
        local = t[after] - t_r
        n_half = (estimate.data_used["n_half"][index] if not held_out
                  and "n_half" in estimate.data_used
                  else kinetic_stop_count(base, x_r, 0.0, float(local[-1]), zeta_amp=quad)[0])
        y_hat[after] = response(local, base, x_r, 0.0, max(int(n_half), 1), jacobian=False,
                                zeta_amp=quad)[0]
    elif np.any(after):
        local = t[after] - t_r
        sim = simulate_free_decay(_params(base), x0=x_r, duration=float(local[-1]) + 1e-9,
                                  t=local)
        y_hat[after] = sim.record.x
    extra = {"zeta_quad": quad, "structure": "+ quadratic damping (equivalent "
             "linearisation per half cycle, as fitted)"} if quad else {}
    mode = estimate.data_used.get("second_mode")
    if mode and np.any(after):
        y_hat, extra = _with_second_mode(t, y_hat, x_ref, t_r, mode, index, held_out,
                                         np.asarray(record.x, float), drift, extra)
    summary = {"kind": "free-decay", **dict(zip(_FREE_DECAY, base, strict=True)), **extra,
               "x0": x_r + x_ref, "v0": 0.0, "t_release": t_r,
               "initial_state": "fitted release (held out)" if held_out
               else "the estimate's release"}
    return y_hat + x_ref + drift * (t - t[0]), held_out, summary


def _with_second_mode(t, y_hat, x_ref, t_r, mode, index, held_out, y, drift, extra):
    """Add a fitted second mode (``+ second mode``); a held-out record's own amplitudes.

    The mode's frequency and decay are the estimate's; its amplitude and phase depend on
    how the release excited it, so a held-out record gets them by linear least squares.
    """
    try:  # a hand-edited result: one line, not an internal error
        omega, sigma = float(mode["omega"]), float(mode["sigma"])
        if not held_out:
            a, b = float(mode["a"][index]), float(mode["b"][index])
    except (TypeError, ValueError, KeyError, IndexError):
        raise IdentificationError(
            "the result's data_used.second_mode must hold the numbers omega, sigma and one a "
            "and b per record, as identify logdec --json writes them; got "
            f"{str(mode)[:80]}") from None
    if not (math.isfinite(omega) and math.isfinite(sigma)):
        raise IdentificationError(f"the result's second mode is not finite (omega {omega}, "
                                  f"sigma {sigma}); identify the record again")
    if held_out:
        cols = np.column_stack([second_mode(t, t_r, omega, sigma, 1.0, 0.0),
                                second_mode(t, t_r, omega, sigma, 0.0, 1.0)])
        target = y - (y_hat + x_ref + drift * (t - t[0]))
        a, b = np.linalg.lstsq(cols, target, rcond=None)[0]
    extra = {**extra, "f2": omega / (2 * math.pi), "sigma2": sigma,
             "structure": "+ second mode" + (" (its amplitude and phase fitted to this "
                                              "record)" if held_out else "")}
    return y_hat + second_mode(t, t_r, omega, sigma, float(a), float(b)), extra


def _simulate(record, estimate, index, inertia):
    """Return the simulated position, held-out flag and model summary (see :func:`simulate`)."""
    if not isinstance(record, Record):
        raise IdentificationError(f"record must be a Record; got {type(record).__name__}")
    if kind_of(estimate) == "free-decay":
        return _simulate_free_decay(record, estimate, index)
    model = drive_model(estimate, record, index=index, inertia=inertia)
    y_hat, state = simulate_model(model, record)
    return y_hat, index is None, {**model.summary, **state}


def simulate(record: Record, estimate: Estimate, *, index: int | None = None,
             inertia: float | None = None) -> tuple[np.ndarray, bool]:
    """Return the identified model's simulated position at the record's sample times.

    Parameters
    ----------
    record : Record
        The measured record: its times, its input ``u`` (forced, IDIM, friction map), its
        gains ``meta["P"]``, ``meta["D"]`` (PHO) and its initial state.
    estimate : Estimate
        A supported estimate (see module docstring).
    index : int, optional
        Which of the estimate's records this is (a free decay uses its fitted release,
        drift and ``x_ref``; forced PHO its gains); None: a held-out record.
    inertia : float, optional
        Inertia of a friction-map model [kg·m² or kg]; regressed from the record if None.

    Returns
    -------
    y_hat : ndarray, shape (n,)
        Simulated position [m or rad].
    held_out : bool
        True for a record the estimate was not computed from (``index`` None).

    Raises
    ------
    IdentificationError
        An estimate that cannot be simulated (the message names what is missing), or
        ``index`` out of range.
    RecordError
        A record without the input ``u`` its model needs.
    """
    y_hat, held_out, _ = _simulate(record, estimate, index, inertia)
    return y_hat, held_out


def compare(record: Record, estimate: Estimate, *, index: int | None = None,
            lags: int = 20, inertia: float | None = None) -> Comparison:
    """Compare a record with the simulated response of an identified model.

    Parameters
    ----------
    record : Record
        Measured record (free decay, PHO run, forced run, or any run with its force ``u``).
    estimate : Estimate
        Free-decay, PHO, forced-response, IDIM or friction-map estimate (module docstring).
    index : int, optional
        Position of ``record`` among the estimate's records (its fitted initial state is
        used); None for a held-out record.
    lags : int
        Autocorrelation lags of the whiteness test [-].
    inertia : float, optional
        Inertia of a friction-map model [kg·m² or kg]; regressed from the record if None.

    Returns
    -------
    Comparison
        Fit [%], residual rms, whiteness, the series, what was simulated, and warnings.

    Raises
    ------
    IdentificationError
        An estimate that cannot be simulated; the message names what is missing.
    RecordError
        A record without the input ``u`` its model needs.

    Examples
    --------
    >>> from driveid.identify.free_decay.output_error import estimate_output_error
    >>> from driveid.sim import measure
    >>> p = OscillatorParams(J=1.0, K=16.0, c_mean=0.3, c_delta=0.1, fk_mean=0.07,
    ...                      fk_delta=0.03)
    >>> rec = measure(simulate_free_decay(p, x0=1.0, duration=20, fs=100).record,
    ...               noise_std=0.002, rng=0)
    >>> c = compare(rec, estimate_output_error(rec, mass=1.0), index=0)
    >>> c.fit > 99, c.whiteness["white"]
    (True, True)
    """
    y_hat, held_out, model = _simulate(record, estimate, index, inertia)
    if "noise_model" in estimate.diagnostics:  # the fit's own AR noise model (issue 24)
        model = {**model, "noise_model": estimate.diagnostics["noise_model"]}
    y = np.asarray(record.x, float)
    resid = y - y_hat
    _refuse_divergence(y, y_hat, model)
    fit = fit_percent(y, resid)
    white = whiteness(resid, lags)
    prewhitened = _prewhitened(resid, estimate, held_out, lags)
    if prewhitened is not None:
        white = {**white, "prewhitened": prewhitened}
    warnings = []
    if not white["white"] and prewhitened is not None and prewhitened["white"]:
        pass  # coloured as the fit's noise model expects: not a model error
    elif not white["white"]:
        message = (
            f"residuals are not white (Ljung–Box p = {white['p_value']:.2g} over "
            f"{white['lags']} lags, {100 * white['band_fraction']:.0f} % of lags outside "
            "±1.96/√n): the model misses an effect of this record (presliding, backlash, a "
            "wrong stiffness, a drift, a second mode, unmodelled forcing) or the noise is "
            "coloured (encoder rounding)")
        at_rest = float(np.mean(np.diff(y) == 0.0)) if y.size > 1 else 0.0
        if at_rest > 0.2:
            # a quantised record at rest repeats one count: its rounding error is constant
            message += (f"; {100 * at_rest:.0f} % of the samples repeat the previous one (at "
                        "rest), where encoder rounding is a constant residual the test "
                        "cannot tell from a model error: validate the moving part "
                        "(FILE@T0:T1)")
        warnings.append(message)
    if math.isfinite(fit) and fit < 90.0:
        warnings.append(f"fit is only {fit:.1f} %: the model does not describe this record")
    return Comparison(t=np.asarray(record.t, float), y=y, y_hat=y_hat, fit=fit,
                      residual_rms=float(math.sqrt(np.mean(resid**2))), whiteness=white,
                      held_out=held_out, warnings=tuple(warnings),
                      unit=record.units.get("x", "rad"), model=model)
