r"""Cramér–Rao bounds of free-decay parameters, and experiment planning from them.

For a record ``y_i = x(t_i; q) + n_i`` with white Gaussian noise of standard deviation
``σ_n``, the Fisher information is ``F = JᵀJ/σ_n²`` with ``J = ∂x/∂q`` the Jacobian of the
exact piecewise free response (the same one :func:`driveid.identify.free_decay.output_error.
estimate_output_error` fits; de Marchi 1998, Eqs. 2.139-2.143, 2.156, 2.168). Any unbiased
estimator's covariance is at least ``F⁻¹``; the physical parameters follow by the delta
method (thesis 2.145, 2.150). Nuisance unknowns (release position and time, and a drift
when asked) are part of ``q`` and widen the bound, as they do the fit.

The body is assumed to stop where the kinetic friction first allows it (static = kinetic
friction) unless ``n_half`` is given. Encoder quantisation with step ``q`` behaves like
noise of standard deviation ``q/√12`` only where the signal moves many steps per sample;
treat the bound as a guide there.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from scipy.signal import lfilter

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.free_decay._free_response import GLOBAL_NAMES, kinetic_stop_count, response
from driveid.identify.free_decay.output_error import _physical_jacobian, physical_parameters

__all__ = ["drive_crlb", "free_decay_crlb", "regression_crlb", "required_duration"]

_PHYSICAL = ("J", "K", "c_mean", "c_delta", "fk_mean", "fk_delta")


def _get(params: Any, name: str) -> float:
    if isinstance(params, Mapping):
        return float(params.get(name, 0.0))
    return float(getattr(params, name, 0.0))


def _base(params: Any) -> np.ndarray:
    J, K = _get(params, "J"), _get(params, "K")
    if not (J > 0 and K > 0):
        raise ParameterError(f"the bound needs J > 0 and K > 0; got J={J!r}, K={K!r}")
    omega0 = math.sqrt(K / J)
    crit = 2.0 * math.sqrt(J * K)
    cm, cd = _get(params, "c_mean"), _get(params, "c_delta")
    zp, zm = (cm + cd) / crit, (cm - cd) / crit
    if not (abs(zp) < 1 and abs(zm) < 1):
        raise ParameterError(f"the free-decay model is underdamped: need |ζ±| < 1, got "
                             f"zeta_plus={zp:.4g}, zeta_minus={zm:.4g}")
    return np.array([omega0, zp, zm, _get(params, "fk_mean") / K, _get(params, "fk_delta") / K])


def free_decay_crlb(
    params: Any,
    *,
    fs: float,
    duration: float,
    x0: float,
    noise_std: float,
    known: str = "J",
    n_half: int | None = None,
    drift: bool = False,
    noise_ar: Sequence[float] | None = None,
) -> dict[str, float]:
    """Cramér–Rao standard deviations of the free-decay parameters for one record design.

    Parameters
    ----------
    params : mapping or object
        The system: ``J`` [kg or kg·m²], ``K`` [N/m or N·m/rad], ``c_mean``, ``c_delta``
        [N·s/m or N·m·s/rad], ``fk_mean``, ``fk_delta`` [N or N·m] (attributes, e.g. an
        ``OscillatorParams``, or keys; missing ones are 0).
    fs : float
        Sampling rate [Hz]; > 0.
    duration : float
        Record length from the release [s]; > 0.
    x0 : float
        Release position, at rest [m or rad].
    noise_std : float
        Standard deviation of white position noise [m or rad]; > 0.
    known : {"J", "K"}
        The parameter given to the estimator (the other is estimated).
    n_half : int, optional
        Half cycles before the stop [-]; default: where kinetic friction stops the body.
    drift : bool
        Include a linear drift as a nuisance unknown.
    noise_ar : sequence of float, optional
        Coloured noise: AR coefficients ``a_1 … a_p`` [-] of ``e_t = Σ a_j e_{t-j} + w_t``
        (a long AR fit approximates any smooth spectrum); ``noise_std`` is then the
        standard deviation of ``e`` itself. The bound is ``σ_w² (J_wᵀ J_w)⁻¹`` with the
        prewhitened Jacobian ``J_w = A(q) J`` (Whittle; the first p samples conditioned on).

    Returns
    -------
    dict
        Bound standard deviation per parameter, in its unit: ``omega0``, ``zeta_plus``,
        ``zeta_minus``, ``theta_k_mean``, ``theta_k_delta``, the unknown of ``J``/``K``,
        ``c_mean``, ``c_delta``, ``fk_mean``, ``fk_delta``.

    Raises
    ------
    ParameterError
        Non-positive ``fs``, ``duration`` or ``noise_std``, a bad ``known``, or a system
        that is not an underdamped oscillator.

    Examples
    --------
    >>> p = {"J": 1.0, "K": 16.0, "c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07,
    ...      "fk_delta": 0.03}
    >>> sd = free_decay_crlb(p, fs=1000, duration=30, x0=10, noise_std=0.01)
    >>> 1e-4 < sd["fk_mean"] / 0.07 < 1e-2
    True
    """
    for name, value in (("fs", fs), ("duration", duration), ("noise_std", noise_std)):
        if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be a positive number; got {value!r}")
    if known not in ("J", "K"):
        raise ParameterError(f"known must be 'J' or 'K' (the given parameter); got {known!r}")
    base = _base(params)
    t = np.arange(int(math.floor(duration * fs + 1e-9)) + 1) / fs
    if n_half is None:
        n_half, _ = kinetic_stop_count(base, float(x0), 0.0, float(t[-1]))
    _, jac, _ = response(t, base, float(x0), 0.0, max(int(n_half), 1))
    if drift:
        jac = np.column_stack([jac, t])
    fisher = _fisher(jac, noise_std, noise_ar)
    try:
        cov = np.linalg.inv(fisher)
    except np.linalg.LinAlgError:
        raise IdentificationError(
            "the Fisher information is singular: the record cannot separate the parameters "
            "(too short, or no motion in one direction)") from None
    mass = _get(params, "J") if known == "J" else None
    stiffness = _get(params, "K") if known == "K" else None
    free = [n for n in _PHYSICAL if n != known]
    G = _physical_jacobian(base, mass, stiffness, free)
    cov_phys = G @ cov[:5, :5] @ G.T
    out = {n: float(math.sqrt(max(cov[i, i], 0.0))) for i, n in enumerate(GLOBAL_NAMES)}
    out.update({n: float(math.sqrt(max(cov_phys[i, i], 0.0))) for i, n in enumerate(free)})
    return out


def _fisher(jac: np.ndarray, noise_std: float, noise_ar: Sequence[float] | None) -> np.ndarray:
    """Fisher information ``J_wᵀJ_w/σ_w²`` of one record under stationary AR noise."""
    if noise_ar is None or not len(noise_ar):
        return jac.T @ jac / noise_std**2
    a = np.concatenate([[1.0], -np.asarray(noise_ar, float)])
    if np.max(np.abs(np.roots(a))) >= 1.0:
        raise ParameterError("noise_ar must describe a stationary AR process (all poles "
                             "inside the unit circle)")
    # σ_w² = γ₀ / Σ h_k² with h the impulse response of 1/A(q)
    pulse = np.zeros(200_000)
    pulse[0] = 1.0
    h = lfilter([1.0], a, pulse)
    sigma_w2 = noise_std**2 / float(h @ h)
    jw = lfilter(a, [1.0], jac, axis=0)[a.size - 1:]
    return jw.T @ jw / sigma_w2


def regression_crlb(
    jacobians: Sequence[np.ndarray],
    *,
    noise_std: float,
    noise_ar: Sequence[float] | None = None,
) -> np.ndarray:
    r"""Cramér–Rao covariance of parameters that enter records through known sensitivities.

    For independent records ``y_r = f_r(q) + e_r`` with stationary Gaussian noise ``e_r``
    (white, or AR with coefficients ``noise_ar``), any unbiased estimator of ``q`` has a
    covariance of at least ``F⁻¹``, ``F = Σ_r J_rᵀ Σ⁻¹ J_r`` with ``J_r = ∂f_r/∂q`` at the
    truth. This covers the linear inverse model (``J_r`` the regressor matrix: inertia,
    friction and offset columns of the noise-free motion) as well as any nonlinear model
    through its Jacobian (a steady sine response, a friction map).

    Parameters
    ----------
    jacobians : sequence of ndarray, each shape (n_r, p)
        Sensitivity of each record's samples to the ``p`` parameters [record unit per
        parameter unit]; every record has ``n_r > p`` samples, and more than the AR order.
    noise_std : float
        Standard deviation of the noise on every record [record unit]; > 0.
    noise_ar : sequence of float, optional
        AR coefficients ``a_1 … a_p`` [-] of ``e_t = Σ a_j e_{t-j} + w_t``; ``noise_std``
        is the standard deviation of ``e`` itself. Whittle's form, as in
        :func:`free_decay_crlb`: each record prewhitened by ``A(q)``, its first p samples
        conditioned on.

    Returns
    -------
    ndarray, shape (p, p)
        The bound covariance ``F⁻¹`` [parameter units squared]; the square roots of its
        diagonal are the bound standard deviations.

    Raises
    ------
    ParameterError
        A non-positive ``noise_std``, Jacobians of different widths or too few rows, or a
        non-stationary ``noise_ar``.
    IdentificationError
        If the Fisher information is singular (the records cannot separate the parameters).

    Notes
    -----
    With white noise this is the ordinary least-squares covariance ``σ²(JᵀJ)⁻¹``, which is
    what the thesis's inverse-model and sine-fit error bars (2.179) estimate; with coloured
    noise it is the generalised least-squares covariance, which no unbiased estimator beats.

    Examples
    --------
    >>> ones = np.ones((1001, 1))            # the mean of 1001 samples
    >>> float(regression_crlb([ones], noise_std=2.0)[0, 0])  # σ²/n
    0.003996003996003996
    """
    if not (isinstance(noise_std, (int, float)) and math.isfinite(noise_std)
            and noise_std > 0):
        raise ParameterError(f"noise_std must be a positive number; got {noise_std!r}")
    mats = [np.atleast_2d(np.asarray(j, float)) for j in jacobians]
    if not mats:
        raise ParameterError("regression_crlb needs at least one record's Jacobian; got none")
    p = mats[0].shape[1]
    order = 0 if noise_ar is None else len(noise_ar)
    for j in mats:
        if j.ndim != 2 or j.shape[1] != p or j.shape[0] <= max(p, order):
            raise ParameterError(
                f"every Jacobian must be (n_r, {p}) with n_r > {max(p, order)} (parameters "
                f"and AR order); got shape {j.shape}")
    fisher = sum(_fisher(j, float(noise_std), noise_ar) for j in mats)
    try:
        return np.linalg.inv(fisher)
    except np.linalg.LinAlgError:
        raise IdentificationError(
            "the Fisher information is singular: the records cannot separate the "
            "parameters") from None


def required_duration(
    params: Any,
    *,
    fs: float,
    x0: float,
    noise_std: float,
    parameter: str = "fk_mean",
    relative: float = 0.01,
    known: str = "J",
    max_duration: float = 3600.0,
) -> float:
    """Shortest record whose Cramér–Rao bound gives ``parameter`` within ``relative``.

    Answers "how long must I record to get f̄k within 1 %?" (one standard deviation).

    Parameters
    ----------
    params : mapping or object
        The (expected) system, as for :func:`free_decay_crlb`.
    fs : float
        Sampling rate [Hz].
    x0 : float
        Release position [m or rad].
    noise_std : float
        Position noise standard deviation [m or rad].
    parameter : str
        Name of the parameter (a key of :func:`free_decay_crlb`'s result).
    relative : float
        Target bound standard deviation relative to the parameter's value [-]; > 0.
    known : {"J", "K"}
        The given parameter.
    max_duration : float
        Longest duration considered [s].

    Returns
    -------
    float
        Duration from the release [s], to 1 % of itself.

    Raises
    ------
    ParameterError
        A parameter whose value is 0 (a relative target is meaningless), or a bad name.
    IdentificationError
        If even ``max_duration`` does not reach the target (the motion stops first:
        record from a larger ``x0`` or with less noise).

    Examples
    --------
    >>> p = {"J": 1.0, "K": 16.0, "c_mean": 0.3, "c_delta": 0.1, "fk_mean": 0.07,
    ...      "fk_delta": 0.03}
    >>> d = required_duration(p, fs=100, x0=1.0, noise_std=0.001, relative=0.01)
    >>> round(d, 1)  # seconds of decay for f̄k within 1 % (one sd) at 1 mrad noise
    8.5
    """
    if not relative > 0:
        raise ParameterError(f"relative must be > 0; got {relative!r}")
    base = _base(params)
    J, K = _get(params, "J"), _get(params, "K")
    values = dict(zip(GLOBAL_NAMES, base, strict=True))
    values.update(physical_parameters(base, J if known == "J" else None,
                                      K if known == "K" else None))
    if parameter not in values or parameter == known:
        raise ParameterError(f"parameter must be an estimated one of {sorted(values)} other "
                             f"than the known {known!r}; got {parameter!r}")
    target = relative * abs(values[parameter])
    if target == 0:
        raise ParameterError(f"{parameter} is 0: a relative precision is meaningless; "
                             "use free_decay_crlb for its absolute bound")

    def bound(d):
        return free_decay_crlb(params, fs=fs, duration=d, x0=x0, noise_std=noise_std,
                               known=known)[parameter]

    lo = hi = 2.0 * 2 * math.pi / base[0]  # two periods
    while bound(hi) > target:
        lo, hi = hi, 2 * hi
        if hi > max_duration:
            raise IdentificationError(
                f"{parameter} does not reach {relative:.3g} relative precision within "
                f"{max_duration} s (the motion stops first); record from a larger x0, "
                "with less noise or a faster sampling rate")
    if lo == hi:
        return float(hi)
    while hi - lo > 0.01 * hi:
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if bound(mid) <= target else (mid, hi)
    return float(hi)


def drive_crlb(
    params: Any,
    record: Any,
    names: Sequence[str],
    *,
    noise_std: Mapping[str, float] | float,
    x0=None,
    v0=None,
    input_body: int | None = None,
) -> dict[str, float]:
    r"""Cramér–Rao standard deviations of a whole-drive fit for one record design.

    Parameters
    ----------
    params : DriveParams
        The true drive (structure and values).
    record : DriveRecord
        The design: sample times [s], input ``u`` [N·m or N] (open loop) and the measured
        channel names (``x1``, ``v2`` …; their values are not used).
    names : sequence of str
        Estimated parameters, named as in the TOML (``body1.J``, ``link1.k`` …); the
        initial state counts only where listed (``body1.x0``).
    noise_std : float or mapping of str to float
        Standard deviation of white noise on every channel, or per channel [rad, rad/s or
        m, m/s].
    x0, v0 : array_like, shape (n_bodies,), optional
        True initial positions [rad or m] and velocities [rad/s or m/s] (default 0).
    input_body : int, optional
        0-based body ``u`` acts on (default: the feedback body, else 0; unused under
        feedback).

    Returns
    -------
    dict of str to float
        Bound standard deviation of each parameter, ``sqrt(diag((JᵀWJ)⁻¹))`` with ``J`` the
        central-difference Jacobian of the simulated channels at the truth
        (:mod:`driveid.identify.drive._drive_model`) and ``W = diag(1/σ_c²)``.

    Raises
    ------
    ParameterError
        A bad name or a non-positive noise level.

    Examples
    --------
    >>> from driveid.sim import BodyParams, DriveParams
    >>> from driveid.identify.drive.drive_fit import DriveRecord
    >>> drive = DriveParams(bodies=(BodyParams(J=0.01, c_mean=0.002, fk_mean=0.05),))
    >>> t = np.arange(2001) / 1000.0
    >>> rec = DriveRecord(t=t, channels={"x1": 0 * t}, u=0.2 * np.sin(9.4 * t))
    >>> sd = drive_crlb(drive, rec, ["body1.J"], noise_std=1e-4, x0=[0.0], v0=[0.0])
    >>> 0 < sd["body1.J"] / 0.01 < 1e-2
    True
    """
    from driveid.identify.drive._drive_model import DriveProblem, check_names, get_value

    names = check_names(params, list(names))
    nb = params.n_bodies
    x0 = np.zeros(nb) if x0 is None else np.broadcast_to(np.asarray(x0, float), (nb,))
    v0 = np.zeros(nb) if v0 is None else np.broadcast_to(np.asarray(v0, float), (nb,))
    values = np.array([get_value(params, x0, v0, n) for n in names])
    scale = np.where(values != 0, np.abs(values), 1.0)
    if input_body is None:
        input_body = params.feedback.body if params.feedback is not None else 0
    problem = DriveProblem(params, x0, v0, names, scale, record,
                           None if params.feedback is not None else input_body)
    _, jac = problem.value_and_jacobian(values / scale)
    rows = []
    for c, channel in enumerate(problem.channels):
        sd = noise_std if not isinstance(noise_std, Mapping) else noise_std.get(channel)
        if sd is None or not (math.isfinite(sd) and sd > 0):
            raise ParameterError(f"noise_std must be positive for channel {channel}; got "
                                 f"{sd!r}")
        rows.append(jac[c] / sd)
    jw = np.vstack(rows)
    _, s, vt = np.linalg.svd(jw, full_matrices=False)
    cov = (vt.T / np.maximum(s, 1e-300) ** 2) @ vt
    sd = np.sqrt(np.diag(cov)) * scale
    return dict(zip(names, (float(v) for v in sd), strict=True))
