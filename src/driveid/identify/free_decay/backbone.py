r"""Amplitude-dependent stiffness (the backbone) from instantaneous frequency and amplitude.

The Hilbert (:func:`driveid.identify.free_decay.hilbert.estimate_hilbert`) and wavelet
(:func:`~driveid.identify.free_decay.wavelet.estimate_wavelet`) methods give, along a free
decay (or a forced response), the instantaneous amplitude :math:`A(t)` and undamped natural
frequency :math:`\omega_0(t)` (de Marchi 1998, Eqs. (2.214), (2.222a) corrected, (2.248)). Plotted
against each other they are the *backbone* :math:`\omega_0(A)`, and with the inertia
:math:`J` the effective (secant, first-harmonic) stiffness

.. math:: K_{eff}(A) = J\,\omega_0(A)^2 .

A linear spring gives a constant backbone; a hardening (cubic) spring
:math:`J\ddot x + Kx + k_3x^3 = 0` gives, by first-order harmonic balance (the
describing-function view of the thesis's §2.2.5),

.. math:: \omega_0^2(A) = \omega_n^2\Big(1 + \tfrac34\,\varepsilon A^2\Big),
          \qquad \varepsilon = k_3/K,

and a dead-zone spring of half-width ``b`` (backlash with a stiff spring beyond it: force
``K (x - b sgn x)`` for ``|x| > b``, 0 inside) has the exact free-vibration period, for a
peak displacement :math:`A > b`,

.. math:: T(A) = \frac{2\pi}{\omega_n}\Big(1 + \frac{2b}{\pi (A-b)}\Big),

four quarter-periods of the spring part (a harmonic motion about ``±b`` of amplitude
``A - b``) plus two flights across the gap ``2b`` at the constant speed
:math:`\omega_n (A - b)` (energy: :math:`\tfrac12 J v^2 = \tfrac12 K (A-b)^2`). So
:math:`K_{eff}(A) < K`, falling towards 0 as ``A -> b``: the spring is soft at small
amplitude, and the backbone *rises* with amplitude.

Method (:func:`compute_backbone`): the instantaneous series are averaged over blocks of
``block_periods`` periods (the Savitzky-Golay derivative and the one-period boxcar of the
Hilbert method correlate samples over about two periods, so block means are nearly
independent). The block values :math:`(A_k^2, \omega_{0,k}^2)` are fitted by ordinary least
squares, weighted by :math:`A_k^2` (additive noise of std ``s`` on ``x`` puts noise of
std ``~ s/A`` on the instantaneous frequency), with

.. math:: \omega_0^2(A) = \omega_{00}^2 + q\,A^2, \qquad
          K_{eff}(A) = K_0 + K_2 A^2 \;(K_0 = J\omega_{00}^2,\ K_2 = Jq),

standard errors from the residual scatter (the covariance of the fit). The verdict tests
:math:`H_0: q = 0` with Student's *t* on ``n_blocks - 2`` degrees of freedom (two-sided
p-value). "hardening" (``K_eff`` rises with amplitude, e.g. a cubic spring or a dead
zone) or "softening" (falls) needs both ``p < alpha`` and a relative change of the fitted
``K_eff`` over the amplitude range of at least ``min_change``: without noise the
instantaneous methods leave systematic ripple of ~1e-4 relative that is "significant" but
not a stiffness. The quadratic law is exact to first order for a cubic spring only; for a
dead zone it is a monotone trend test, and the binned curve is the result to read.

The binned curve: blocks are grouped into ``n_bins`` bins of equal count by amplitude;
each bin reports its mean amplitude, :math:`\omega_0 = \sqrt{\overline{\omega_0^2}}`,
``K_eff`` (with ``J``), and standard errors from the scatter of the block values: the
block noise is estimated from second differences of :math:`\omega_{0,k}^2` in amplitude
order (they cancel a locally linear trend, so the backbone's own slope does not count as
noise; its curvature does, a small conservative floor), scaled as ``1/A``.
``relative_stiffness`` is ``K_eff`` over that of the largest-amplitude bin (needs no ``J``).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.2.5,
       §2.2.8-§2.2.11.
.. [2] M. Feldman, *Hilbert Transform Applications in Mechanical Vibration*, Wiley, 2011,
       ch. 7 (backbone and damping curves). doi:10.1002/9781119991656
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import stdtr

from driveid.errors import IdentificationError, ParameterError
from driveid.identify.core.estimate import Parameter

__all__ = ["Backbone", "compute_backbone", "backbone_of", "backbone_entries", "MIN_BLOCKS"]

#: Fewest independent blocks for a backbone fit (two parameters and two residual dof) [-].
MIN_BLOCKS = 4


@dataclass(frozen=True)
class Backbone:
    """Binned backbone curve, its quadratic fit and the hardening/softening verdict.

    Attributes
    ----------
    amplitude : ndarray, shape (m,)
        Mean instantaneous amplitude of each bin [m or rad], increasing.
    omega0 : ndarray, shape (m,)
        Undamped natural frequency of each bin [rad/s].
    omega0_stderr : ndarray, shape (m,)
        Its standard error [rad/s] (``nan`` for a bin of one block).
    t : ndarray, shape (m,)
        Mean time of each bin's blocks [s].
    n_blocks : ndarray of int, shape (m,)
        Blocks in each bin [-].
    stiffness : ndarray, shape (m,)
        ``K_eff = J omega0²`` [N/m or N·m/rad]; ``J omega0²`` per unit inertia [rad²/s²]
        without ``mass``.
    stiffness_stderr : ndarray, shape (m,)
        Its standard error [same].
    relative_stiffness : ndarray, shape (m,)
        ``K_eff`` over that of the largest-amplitude bin [-].
    K0, K2 : Parameter
        Fit ``K_eff(A) = K0 + K2 A²``: ``K0`` [N/m or N·m/rad], ``K2`` [N/m³ or
        N·m/rad³] (per unit inertia without ``mass``).
    change : float
        Relative change of the fitted ``K_eff`` from the smallest to the largest bin
        amplitude, ``K_eff(A_max)/K_eff(A_min) - 1`` [-].
    p_value : float
        Two-sided p-value of ``K2 = 0`` [-].
    verdict : str
        ``"hardening"``, ``"softening"`` or ``"constant"``.
    mass_normalised : bool
        True when no inertia was given (stiffness per unit inertia).
    settings : dict
        ``alpha``, ``min_change``, ``block_periods``, ``n_blocks_total``.
    """

    amplitude: np.ndarray
    omega0: np.ndarray
    omega0_stderr: np.ndarray
    t: np.ndarray
    n_blocks: np.ndarray
    stiffness: np.ndarray
    stiffness_stderr: np.ndarray
    relative_stiffness: np.ndarray
    K0: Parameter
    K2: Parameter
    change: float
    p_value: float
    verdict: str
    mass_normalised: bool
    settings: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        """Return the curve (arrays) and the fit (scalars) as plain values.

        Returns
        -------
        dict
            ``amplitude``, ``omega0``, ``omega0_stderr``, ``t``, ``n_blocks``,
            ``stiffness``, ``stiffness_stderr``, ``relative_stiffness`` (arrays) and
            ``fit`` (see :meth:`summary`).
        """
        arrays = ("amplitude", "omega0", "omega0_stderr", "t", "n_blocks", "stiffness",
                  "stiffness_stderr", "relative_stiffness")
        return {**{k: getattr(self, k) for k in arrays}, "fit": self.summary()}

    def summary(self) -> dict[str, Any]:
        """Return the fit and verdict: at most 10 scalars, short enough for ``--json``.

        Returns
        -------
        dict
            ``K0``, ``K0_stderr``, ``K2``, ``K2_stderr``, ``unit_K0``, ``unit_K2``,
            ``change``, ``p_value``, ``verdict``, ``mass_normalised``.
        """
        return {"K0": self.K0.value, "K0_stderr": self.K0.stderr, "unit_K0": self.K0.unit,
                "K2": self.K2.value, "K2_stderr": self.K2.stderr, "unit_K2": self.K2.unit,
                "change": self.change, "p_value": self.p_value, "verdict": self.verdict,
                "mass_normalised": self.mass_normalised}


def _block_means(t: np.ndarray, amplitude: np.ndarray, omega0: np.ndarray,
                 n_block: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Means of t, A and omega0² over consecutive whole blocks of ``n_block`` samples."""
    m = t.size // n_block
    cut = m * n_block
    shape = (m, n_block)
    return (t[:cut].reshape(shape).mean(axis=1), amplitude[:cut].reshape(shape).mean(axis=1),
            (omega0[:cut] ** 2).reshape(shape).mean(axis=1))


def compute_backbone(
    t: np.ndarray,
    amplitude: np.ndarray,
    omega0: np.ndarray,
    *,
    omega: float | None = None,
    mass: float | None = None,
    units: tuple[str, str] = ("rad", "N·m"),
    n_bins: int = 10,
    block_periods: float = 2.0,
    alpha: float = 0.01,
    min_change: float = 5e-3,
) -> Backbone:
    r"""Backbone ``omega0(A)``, ``K_eff(A) = J omega0(A)²``, its fit and verdict.

    Parameters
    ----------
    t : ndarray, shape (n,)
        Uniform sample times of the instantaneous series [s].
    amplitude : ndarray, shape (n,)
        Instantaneous amplitude [m or rad]; > 0.
    omega0 : ndarray, shape (n,)
        Instantaneous undamped natural frequency [rad/s].
    omega : float, optional
        Oscillation frequency that sets the block length [rad/s]; > 0; by default the
        median of ``omega0``.
    mass : float, optional
        Inertia J [kg·m² or kg]; without it the stiffness is per unit inertia [rad²/s²].
    units : tuple of str
        Units of ``x`` and of the force ``u`` (for the stiffness units).
    n_bins : int
        Most bins of the curve [-]; fewer when there are fewer than ``2 n_bins`` blocks.
    block_periods : float
        Length of the averaging blocks [periods]; > 0.
    alpha : float
        Significance level of the verdict [-], in (0, 1).
    min_change : float
        Least relative change of ``K_eff`` over the amplitude range reported as hardening
        or softening [-]; >= 0.

    Returns
    -------
    Backbone
        The binned curve with standard errors, the fit ``K0 + K2 A²`` and the verdict.

    Raises
    ------
    ParameterError
        Arrays of different lengths or non-positive options.
    IdentificationError
        Fewer than :data:`MIN_BLOCKS` blocks, or an amplitude that does not vary.

    Notes
    -----
    See the module docstring for the closed forms and the test.

    Examples
    --------
    >>> t = np.arange(20000) / 1000.0
    >>> amp = np.exp(-0.1 * t)
    >>> bb = compute_backbone(t, amp, 10.0 * np.sqrt(1 + 0.2 * amp**2), omega=10.0, mass=2.0)
    >>> bb.verdict, round(bb.K0.value, 3), round(bb.K2.value / bb.K0.value, 3)
    ('hardening', 200.0, 0.2)
    """
    t, amplitude, omega0 = (np.asarray(v, dtype=float) for v in (t, amplitude, omega0))
    if not (t.ndim == 1 and t.shape == amplitude.shape == omega0.shape):
        raise ParameterError(
            "t, amplitude and omega0 must be 1-D arrays of one length; got shapes "
            f"{t.shape}, {amplitude.shape}, {omega0.shape}")
    if omega is None and omega0.size:
        omega = float(np.median(omega0))
    for name, value in (("omega", omega), ("block_periods", block_periods)):
        if not (math.isfinite(value) and value > 0):
            raise ParameterError(f"{name} must be positive and finite; got {value!r}")
    if not 0 < alpha < 1:
        raise ParameterError(f"alpha must be in (0, 1); got {alpha!r}")
    if not (math.isfinite(min_change) and min_change >= 0):
        raise ParameterError(f"min_change must be >= 0; got {min_change!r}")
    if int(n_bins) != n_bins or n_bins < 1:
        raise ParameterError(f"n_bins must be a positive integer; got {n_bins!r}")
    if mass is not None and not (math.isfinite(mass) and mass > 0):
        raise ParameterError(f"mass must be a positive inertia [kg·m² or kg] or None; got {mass!r}")
    if t.size < 2:
        raise IdentificationError(
            f"the backbone needs at least {MIN_BLOCKS} blocks of {block_periods:g} periods; "
            f"record a longer response; got {t.size} sample(s)")
    fs = (t.size - 1) / (t[-1] - t[0])
    n_block = max(int(round(block_periods * 2 * math.pi / omega * fs)), 1)
    tb, ab, w2 = _block_means(t, amplitude, omega0, n_block)
    if tb.size < MIN_BLOCKS:
        raise IdentificationError(
            f"the backbone needs at least {MIN_BLOCKS} blocks of {block_periods:g} periods "
            f"in the valid window; record a longer response; got {tb.size}")
    a2 = ab**2
    if not np.ptp(a2) > 1e-9 * np.max(a2):
        raise IdentificationError(
            "the backbone needs an amplitude that varies over the record (a free decay or a "
            f"sweep); got a constant amplitude {float(ab[0]):.4g}")
    J = 1.0 if mass is None else float(mass)
    # weighted LS of omega0² on (1, A²), weights A²: additive noise of std s on x puts a
    # phase (frequency) noise of std ~ s/A on the instantaneous series; the weighted
    # residual scatter gives the covariance
    design = np.column_stack([np.ones_like(a2), a2])
    sw = ab / ab.max()
    coef, *_ = np.linalg.lstsq(design * sw[:, None], w2 * sw, rcond=None)
    resid = (w2 - design @ coef) * sw
    dof = tb.size - 2
    s2 = float(resid @ resid) / dof
    cov = np.linalg.inv((design * sw[:, None]).T @ (design * sw[:, None])) * s2
    se = np.sqrt(np.maximum(np.diag(cov), 0.0))
    if se[1] > 0:
        p_value = float(2 * stdtr(dof, -abs(coef[1]) / se[1]))  # Student's t, two-sided
    else:
        p_value = 0.0 if coef[1] != 0 else 1.0
    lo, hi = float(ab.min()), float(ab.max())
    k_lo, k_hi = coef[0] + coef[1] * lo**2, coef[0] + coef[1] * hi**2
    change = float(k_hi / k_lo - 1) if k_lo > 0 else math.inf
    verdict = "constant"
    if p_value < alpha and abs(change) >= min_change:
        verdict = "hardening" if coef[1] > 0 else "softening"
    xu, uu = units
    ku = f"{uu}/{xu}" if mass is not None else "rad²/s²"
    k2u = f"{uu}/{xu}³" if mass is not None else f"rad²/(s²·{xu}²)"
    # bins of equal block count by amplitude
    m = max(min(int(n_bins), tb.size // 2), 1)
    order = np.argsort(ab)
    groups = np.array_split(order, m)
    counts = np.array([g.size for g in groups])
    amp_bin = np.array([ab[g].mean() for g in groups])
    w2_bin = np.array([w2[g].mean() for g in groups])
    # block noise from second differences along the amplitude order, which cancel a
    # locally linear trend (var d2 = 6 var for independent blocks); scaled by A_k for the
    # noise ~ 1/A, so each block's std is s0 / A_k
    ws, as_ = w2[order], ab[order]
    if tb.size >= 3:
        d2 = (ws[:-2] - 2 * ws[1:-1] + ws[2:]) * as_[1:-1]
        s0 = math.sqrt(float(np.mean(d2**2)) / 6.0)
    else:
        s0 = math.nan
    w2_err = np.array([s0 * math.sqrt(float(np.sum(ab[g] ** -2.0))) / g.size for g in groups])
    omega_bin = np.sqrt(np.maximum(w2_bin, 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        omega_err = w2_err / (2 * omega_bin)
    return Backbone(
        amplitude=amp_bin, omega0=omega_bin, omega0_stderr=omega_err,
        t=np.array([tb[g].mean() for g in groups]), n_blocks=counts,
        stiffness=J * w2_bin, stiffness_stderr=J * w2_err,
        relative_stiffness=w2_bin / w2_bin[-1],
        K0=Parameter(float(J * coef[0]), float(J * se[0]), ku),
        K2=Parameter(float(J * coef[1]), float(J * se[1]), k2u),
        change=change, p_value=p_value, verdict=verdict, mass_normalised=mass is None,
        settings={"alpha": alpha, "min_change": min_change, "block_periods": block_periods,
                  "n_blocks_total": int(tb.size)},
    )


def backbone_of(estimate: Any, *, mode: int = 0, mass: float | None = None,
                **options: Any) -> Backbone:
    """Backbone of a Hilbert or wavelet estimate, from its instantaneous series.

    Parameters
    ----------
    estimate : Estimate
        Result of :func:`~driveid.identify.free_decay.hilbert.estimate_hilbert` or
        :func:`~driveid.identify.free_decay.wavelet.estimate_wavelet`.
    mode : int
        Mode index for a several-mode wavelet estimate [-] (0 = lowest frequency).
    mass : float, optional
        Inertia J [kg·m² or kg]; without it the stiffness is per unit inertia [rad²/s²].
    **options
        Passed to :func:`compute_backbone` (``n_bins``, ``block_periods``, ``alpha``,
        ``min_change``, ``units``).

    Returns
    -------
    Backbone
        See :func:`compute_backbone`.

    Raises
    ------
    ParameterError
        An estimate without instantaneous series, or a mode out of range.
    """
    data = estimate.data_used
    if "modes" in data:
        modes = data["modes"]
        if not 0 <= mode < len(modes):
            raise ParameterError(f"mode must be in 0..{len(modes) - 1}; got {mode!r}")
        src = modes[mode]
        t, amp, w0 = src["t"], src["amplitude"], src["omega0"]
    elif all(k in data for k in ("t", "amplitude", "omega0")):
        t, amp, w0 = data["t"], data["amplitude"], data["omega0"]
    else:
        raise ParameterError(
            f"the {estimate.method} estimate has no instantaneous series (t, amplitude, "
            "omega0); pass a Hilbert or wavelet estimate")
    return compute_backbone(t, amp, w0, mass=mass, **options)


def backbone_entries(t: np.ndarray, amplitude: np.ndarray, omega0: np.ndarray, *,
                     mass: float | None,
                     units: tuple[str, str]) -> tuple[dict[str, Any] | None, dict[str, Any]]:
    """Return the backbone as the Hilbert and wavelet estimates carry it (never raises).

    Parameters
    ----------
    t, amplitude, omega0 : ndarray, shape (n,)
        Instantaneous series over the valid window [s], [m or rad], [rad/s].
    mass : float or None
        Inertia J [kg·m² or kg]; None for per-unit-inertia stiffness.
    units : tuple of str
        Units of ``x`` and ``u``.

    Returns
    -------
    curve : dict or None
        :meth:`Backbone.to_dict` (for ``data_used["backbone"]``), None when the window is
        too short or the amplitude constant.
    summary : dict
        :meth:`Backbone.summary`, or ``{"verdict": "undetermined", "reason": ...}``
        (for ``data_used["backbone_fit"]``, short enough for ``--json``).
    """
    try:
        bb = compute_backbone(t, amplitude, omega0, mass=mass, units=units)
    except IdentificationError as exc:
        return None, {"verdict": "undetermined", "reason": str(exc)}
    return bb.to_dict(), bb.summary()
