r"""Elastic compliance: modal summation and torsional shafts (de Marchi 1998, §2.1.3, §2.1.4.2).

* Modal summation (Eqs. 2.74–2.88): generalised and mass-normalised mass and stiffness.
* Rayleigh (proportional) damping and modal damping ratios (Eqs. 2.89–2.96).
* Participation factors and load distribution (Eqs. 2.96–2.100); peak deflection (2.101).
* Torsion of prismatic shafts (Eqs. 2.111–2.117): circular and rectangular sections with
  St Venant's torsion constant, series and approximation.
* Torsional wave speed (Eqs. 2.118–2.125) and fixed-free / fixed-fixed modes (2.126–2.132).

Units are SI: lengths [m], moduli [Pa], density [kg/m³], frequencies [rad/s].

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.3–2.1.4.
.. [2] S. P. Timoshenko and J. N. Goodier, *Theory of Elasticity*, 3rd ed., McGraw-Hill,
       1970, §109, Eqs. (7.104)–(7.107) (the thesis's [272]).
.. [3] W. T. Thomson, *Theory of Vibration with Applications*, §6.10, §9.3 (the thesis's [346]).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from driveid.errors import ParameterError

__all__ = [
    "ModalModel",
    "CircularShaft",
    "RectangularShaft",
    "modal_analysis",
    "modal_force",
    "participation_factors",
    "rayleigh_damping_matrix",
    "rayleigh_modal_damping",
    "rayleigh_coefficients",
    "modal_frequency_response",
    "modal_free_response",
    "peak_deflection",
    "shear_modulus",
    "circular_polar_moment",
    "rectangular_polar_moment",
    "rectangular_torsion_constant",
    "rectangular_torsion_constant_approx",
    "torsional_stiffness",
    "torsional_wave_speed",
    "shaft_natural_frequencies",
    "shaft_mode_shape",
]

_BOUNDARIES = ("fixed-free", "fixed-fixed")


def _positive(name: str, value, unit: str) -> np.ndarray:
    a = np.asarray(value, dtype=float)
    bad = ~(a > 0.0) | ~np.isfinite(a)
    if np.any(bad):
        raise ParameterError(
            f"{name} must be positive and finite [{unit}]; got {float(a[bad].ravel()[0])!r}"
        )
    return a


def _out(a):
    return float(a) if np.ndim(a) == 0 else a


def _square(name: str, a, n: int | None = None) -> np.ndarray:
    a = np.asarray(a, dtype=float)
    if a.ndim != 2 or a.shape[0] != a.shape[1] or (n is not None and a.shape[0] != n):
        want = f"({n}, {n})" if n is not None else "square (n, n)"
        raise ParameterError(f"{name} must be a {want} matrix; got shape {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be finite; got a matrix with NaN or inf")
    if not np.allclose(a, a.T, rtol=1e-12, atol=0.0):
        raise ParameterError(f"{name} must be symmetric; got max |{name} - {name}.T| = "
                             f"{float(np.max(np.abs(a - a.T)))!r}")
    return a


# --------------------------------------------------------------------------- modal summation
@dataclass(frozen=True)
class ModalModel:
    """Undamped modes of ``M x'' + K x = f`` (Eqs. 2.75–2.84).

    Attributes
    ----------
    omega : ndarray, shape (n,)
        Undamped natural frequencies [rad/s], ascending.
    modes : ndarray, shape (n, n)
        Modal matrix (2.76): column ``i`` is mode ``i``, scaled so that its largest
        component is +1 [-].
    generalised_mass : ndarray, shape (n,)
        ``m_ii = modes[:, i] @ M @ modes[:, i]`` [kg] (2.78).
    generalised_stiffness : ndarray, shape (n,)
        ``k_ii = modes[:, i] @ K @ modes[:, i]`` [N/m] (2.80).
    modes_normalised : ndarray, shape (n, n)
        Mass-normalised modal matrix ``Λ̃`` (2.82), ``Λ̃ᵀ M Λ̃ = I`` [kg^-1/2].
    """

    omega: np.ndarray
    modes: np.ndarray
    generalised_mass: np.ndarray
    generalised_stiffness: np.ndarray
    modes_normalised: np.ndarray


def modal_analysis(M, K) -> ModalModel:
    r"""Modes, generalised and mass-normalised mass and stiffness (Eqs. 2.75–2.84).

    Parameters
    ----------
    M : array_like, shape (n, n)
        Symmetric positive-definite mass matrix [kg or kg·m²].
    K : array_like, shape (n, n)
        Symmetric positive-semidefinite stiffness matrix [N/m or N·m/rad].

    Returns
    -------
    ModalModel
        Frequencies [rad/s] and mode shapes.

    Raises
    ------
    ParameterError
        If the matrices are not square, symmetric, finite, or ``M`` is not positive definite.

    Notes
    -----
    Erratum: (2.81) prints ``ω̃_i = ω_i/m_ii``; for (2.83) ``Λ̃ᵀMΛ̃ = I`` the divisor must
    be ``sqrt(m_ii)`` (``(ω_i/m_ii)ᵀ M (ω_i/m_ii) = 1/m_ii``). Also (2.85) prints ``M, C,
    K`` where the generalised matrices ``ωᵀMω, ωᵀCω, ωᵀKω`` (2.77, 2.79) are meant.

    Examples
    --------
    >>> mm = modal_analysis(np.eye(2), [[2.0, -1.0], [-1.0, 2.0]])
    >>> np.round(mm.omega**2, 12)
    array([1., 3.])
    """
    M = _square("M", M)
    K = _square("K", K, M.shape[0])
    try:
        w2, vecs = scipy.linalg.eigh(K, M)
    except np.linalg.LinAlgError as exc:
        raise ParameterError(f"M must be positive definite; eigh failed: {exc}") from exc
    w2 = np.clip(w2, 0.0, None)  # rigid-body modes may come out as -1e-16
    idx = np.argmax(np.abs(vecs), axis=0)
    modes = vecs / vecs[idx, np.arange(vecs.shape[1])]
    m_ii = np.einsum("ji,jk,ki->i", modes, M, modes)
    k_ii = np.einsum("ji,jk,ki->i", modes, K, modes)
    return ModalModel(omega=np.sqrt(w2), modes=modes, generalised_mass=m_ii,
                      generalised_stiffness=k_ii, modes_normalised=modes / np.sqrt(m_ii))


def modal_force(model: ModalModel, f) -> np.ndarray:
    """Mass-normalised modal forces ``f̃ = Λ̃ᵀ f`` (Eqs. 2.88, 2.95).

    Parameters
    ----------
    model : ModalModel
        From :func:`modal_analysis`.
    f : array_like, shape (n,) or (n, m)
        Physical forces on the DOFs [N], one column per time sample.

    Returns
    -------
    ndarray, shape (n,) or (n, m)
        Modal forces [N·kg^-1/2].
    """
    return model.modes_normalised.T @ np.asarray(f, dtype=float)


def participation_factors(model: ModalModel, load_distribution=None) -> np.ndarray:
    """Modal participation factors for a distributed load (Eqs. 2.96, 2.99–2.100).

    Parameters
    ----------
    model : ModalModel
        From :func:`modal_analysis`.
    load_distribution : array_like, shape (n,), optional
        Share ``γ_j`` of the net force acting on DOF ``j`` [-], each in [0, 1] (2.98);
        default all ones, which gives the plain sum (2.96).

    Returns
    -------
    ndarray, shape (n,)
        ``Σ_j Λ̃_ji γ_j`` for each mode ``i`` [kg^-1/2]; ``f̃_i(t) = f(t)`` times this (2.100).

    Raises
    ------
    ParameterError
        If a share is outside [0, 1] or the length is wrong.

    Notes
    -----
    Erratum: (2.99)–(2.100) print ``Σ_j ω̃_ji γ_i(x)``; the share must carry the DOF index
    ``j`` (``f̃ = Λ̃ᵀ γ f`` from (2.88) and (2.97)), otherwise it would factor out of the sum.
    (2.98) demands ``0 < γ_i < 1``; the endpoints are allowed here (unloaded DOFs, a
    point load).
    """
    n = model.omega.size
    g = np.ones(n) if load_distribution is None else np.asarray(load_distribution, float)
    if g.shape != (n,):
        raise ParameterError(f"load_distribution must have shape ({n},); got {g.shape}")
    bad = ~((g >= 0.0) & (g <= 1.0))
    if np.any(bad):
        raise ParameterError(
            f"load_distribution shares must be in [0, 1] (2.98); got {float(g[bad][0])!r}")
    return model.modes_normalised.T @ g


def rayleigh_damping_matrix(M, K, alpha: float, beta: float) -> np.ndarray:
    """Proportional damping matrix ``C = alpha*M + beta*K`` (Eq. 2.89).

    Parameters
    ----------
    M : array_like, shape (n, n)
        Mass matrix [kg].
    K : array_like, shape (n, n)
        Stiffness matrix [N/m].
    alpha : float
        Mass-proportional coefficient [1/s].
    beta : float
        Stiffness-proportional coefficient [s].

    Returns
    -------
    ndarray, shape (n, n)
        Damping matrix [N·s/m].
    """
    M = _square("M", M)
    K = _square("K", K, M.shape[0])
    return float(alpha) * M + float(beta) * K


def rayleigh_modal_damping(omega, alpha: float, beta: float):
    """Modal damping ratios of Rayleigh damping, ``(alpha/omega + beta*omega)/2`` (Eq. 2.93).

    Parameters
    ----------
    omega : float or ndarray
        Undamped natural frequencies [rad/s], > 0.
    alpha : float
        Mass-proportional coefficient [1/s].
    beta : float
        Stiffness-proportional coefficient [s].

    Returns
    -------
    float or ndarray
        Damping ratios ``zeta_i`` [-].

    Examples
    --------
    >>> rayleigh_modal_damping(10.0, 0.2, 0.002)
    0.02
    """
    w = _positive("omega", omega, "rad/s")
    return _out((alpha / w + beta * w) / 2.0)


def rayleigh_coefficients(omega_pair, zeta_pair):
    """Rayleigh ``(alpha, beta)`` giving two modal damping ratios (inverse of Eq. 2.93).

    Parameters
    ----------
    omega_pair : sequence of 2 floats
        Two distinct natural frequencies [rad/s], > 0.
    zeta_pair : sequence of 2 floats
        Their damping ratios [-].

    Returns
    -------
    alpha : float
        [1/s].
    beta : float
        [s].

    Examples
    --------
    >>> a, b = rayleigh_coefficients((10.0, 100.0), (0.02, 0.02))
    >>> round(rayleigh_modal_damping(100.0, a, b), 12)
    0.02
    """
    w = _positive("omega_pair", omega_pair, "rad/s")
    z = np.asarray(zeta_pair, dtype=float)
    if w.shape != (2,) or z.shape != (2,) or w[0] == w[1]:
        raise ParameterError(
            f"omega_pair and zeta_pair must hold 2 values with distinct frequencies; "
            f"got {w.tolist()!r}, {z.tolist()!r}")
    a = np.array([[1 / w[0], w[0]], [1 / w[1], w[1]]]) / 2.0
    alpha, beta = np.linalg.solve(a, z)
    return float(alpha), float(beta)


def _zetas(model: ModalModel, zeta) -> np.ndarray:
    z = np.broadcast_to(np.asarray(zeta, dtype=float), model.omega.shape)
    bad = ~((z >= 0.0) & (z < 1.0))
    if np.any(bad):
        raise ParameterError(f"zeta must be in [0, 1) for every mode; got {float(z[bad][0])!r}")
    return z


def modal_frequency_response(model: ModalModel, zeta, omega, force, n_modes=None) -> np.ndarray:
    """Steady-state response to harmonic forcing by modal summation (Eqs. 2.86–2.94).

    Parameters
    ----------
    model : ModalModel
        From :func:`modal_analysis`.
    zeta : float or array_like, shape (n,)
        Modal damping ratios [-], in [0, 1) (e.g. :func:`rayleigh_modal_damping`).
    omega : array_like, shape (m,)
        Forcing frequencies [rad/s].
    force : array_like, shape (n,)
        Complex force amplitude on each DOF [N].
    n_modes : int, optional
        Truncate the sum to the lowest ``n_modes`` modes (default all).

    Returns
    -------
    ndarray, shape (m, n)
        Complex displacement amplitudes [m].
    """
    z = _zetas(model, zeta)
    w = np.atleast_1d(np.asarray(omega, dtype=float))
    k = model.omega.size if n_modes is None else int(n_modes)
    L = model.modes_normalised[:, :k]
    wi, zi = model.omega[:k], z[:k]
    fm = L.T @ np.asarray(force, dtype=complex)
    h = 1.0 / (wi**2 - w[:, None] ** 2 + 2j * zi * wi * w[:, None])
    return (h * fm) @ L.T


def modal_free_response(model: ModalModel, zeta, t, x0, v0) -> np.ndarray:
    """Free vibration by summation of the uncoupled modal equations (Eq. 2.94, f̃ = 0).

    Parameters
    ----------
    model : ModalModel
        From :func:`modal_analysis`.
    zeta : float or array_like, shape (n,)
        Modal damping ratios [-], in [0, 1).
    t : array_like, shape (m,)
        Times [s].
    x0 : array_like, shape (n,)
        Initial displacements [m].
    v0 : array_like, shape (n,)
        Initial velocities [m/s].

    Returns
    -------
    ndarray, shape (m, n)
        Displacements [m].
    """
    z = _zetas(model, zeta)
    t = np.asarray(t, dtype=float)[:, None]
    L = model.modes_normalised
    u0 = np.linalg.solve(L, np.asarray(x0, float))
    du0 = np.linalg.solve(L, np.asarray(v0, float))
    w = model.omega
    wd = w * np.sqrt(1.0 - z**2)
    rigid = wd == 0.0
    wd_safe = np.where(rigid, 1.0, wd)
    osc = np.exp(-z * w * t) * (u0 * np.cos(wd * t)
                                + (du0 + z * w * u0) / wd_safe * np.sin(wd * t))
    u = np.where(rigid, u0 + du0 * t, osc)
    return u @ L.T


def peak_deflection(mode_values, modal_peaks):
    """Estimate the peak deflection at one point from truncated modes (Eq. 2.101).

    Parameters
    ----------
    mode_values : array_like, shape (n,)
        Mode-shape values ``ω_j(x_i)`` at the point, fundamental first [-].
    modal_peaks : array_like, shape (n,)
        Peak modal amplitudes ``max|u_j(t)|`` [m].

    Returns
    -------
    float
        ``|ω_1 u_1| + sqrt(Σ_{j>=2} (ω_j u_j)²)`` [m].

    Examples
    --------
    >>> peak_deflection([1.0, 0.5, 0.5], [2.0, 6.0, 8.0])
    7.0
    """
    a = np.asarray(mode_values, dtype=float) * np.asarray(modal_peaks, dtype=float)
    if a.ndim != 1 or a.size < 1:
        raise ParameterError(f"mode_values and modal_peaks must be 1-D, non-empty; got {a.shape}")
    return float(abs(a[0]) + np.sqrt(np.sum(a[1:] ** 2)))


# --------------------------------------------------------------------------- torsion
def shear_modulus(E, poisson):
    """Shear modulus ``G = E/(2(1 + sigma))`` (Eq. 2.113).

    Parameters
    ----------
    E : float or ndarray
        Young's modulus [Pa], > 0.
    poisson : float or ndarray
        Poisson's ratio [-], in (-1, 0.5].

    Returns
    -------
    float or ndarray
        Shear modulus [Pa].

    Examples
    --------
    >>> shear_modulus(200e9, 0.25)
    80000000000.0
    """
    E = _positive("E", E, "Pa")
    s = np.asarray(poisson, dtype=float)
    bad = ~((s > -1.0) & (s <= 0.5))
    if np.any(bad):
        raise ParameterError(f"poisson must be in (-1, 0.5]; got {float(s[bad].ravel()[0])!r}")
    return _out(E / (2.0 * (1.0 + s)))


def circular_polar_moment(diameter):
    """Polar second moment of a solid circular section, ``pi d^4/32`` (Eq. 2.112).

    Parameters
    ----------
    diameter : float or ndarray
        Diameter [m], > 0.

    Returns
    -------
    float or ndarray
        ``I_p`` [m^4]; also St Venant's torsion constant of the circle.
    """
    d = _positive("diameter", diameter, "m")
    return _out(np.pi * d**4 / 32.0)


def rectangular_polar_moment(a, b):
    """Polar second moment of a rectangle, ``ab(a² + b²)/12`` (Eq. 2.123).

    Parameters
    ----------
    a, b : float or ndarray
        Side lengths [m], > 0.

    Returns
    -------
    float or ndarray
        ``I_p`` [m^4] about the centroid.
    """
    a = _positive("a", a, "m")
    b = _positive("b", b, "m")
    return _out(a * b * (a**2 + b**2) / 12.0)


def _sides(a, b):
    a = _positive("a", a, "m")
    b = _positive("b", b, "m")
    if np.any(a > b):
        raise ParameterError(
            "a must be the shorter side (a <= b) [m]; swap the arguments; "
            f"got a={float(np.max(a))!r} > b")
    return a, b


def rectangular_torsion_constant(a, b, *, n_terms: int = 50):
    r"""St Venant's torsion constant of a rectangle, series form (Eq. 2.114, corrected).

    Parameters
    ----------
    a : float or ndarray
        Shorter side [m], > 0.
    b : float or ndarray
        Longer side [m], >= a.
    n_terms : int, optional
        Odd terms ``n = 1, 3, ..., 2*n_terms - 1`` kept; the dropped tail is below
        ``0.03 a⁴/(2 n_terms)⁴``.

    Returns
    -------
    float or ndarray
        ``K_p`` [m^4]; the torque is ``G K_p Δθ/l`` (2.111).

    Notes
    -----
    .. math:: K_p = a^3\left[\frac{b}{3} - a\,\frac{4^3}{\pi^5}
              \sum_{n=1,3,5,\dots} n^{-5}\tanh\frac{n\pi b}{2a}\right]

    Erratum: (2.114) prints the coefficient ``4³π⁵/3`` and the terms ``3⁻⁵ tanh ρ``; from
    Timoshenko–Goodier (7.104), ``K = (a³b/3)[1 - (192/π⁵)(a/b)Σ n⁻⁵ tanh(nπb/2a)]`` the
    coefficient is ``64/π⁵`` and the n-th term is ``n⁻⁵ tanh(nρ)``. Only with these does
    the series reduce to (2.115): ``3·(64/π⁵)·Σ n⁻⁵ = 0.6303`` ≈ 0.630.

    Examples
    --------
    >>> round(rectangular_torsion_constant(1.0, 1.0), 4)  # square: 0.1406 a^4
    0.1406
    """
    a, b = _sides(a, b)
    n = 2 * np.arange(int(n_terms))[:, None] + 1.0
    rho = np.pi * np.atleast_1d(b) / (2.0 * np.atleast_1d(a))
    s = np.sum(np.tanh(n * rho) / n**5, axis=0).reshape(np.shape(b * a))
    return _out(a**3 * (b / 3.0 - a * 64.0 / np.pi**5 * s))


def rectangular_torsion_constant_approx(a, b):
    """St Venant's torsion constant of a rectangle, ``a³(b - 0.630a)/3`` (Eqs. 2.115, 2.117).

    Parameters
    ----------
    a : float or ndarray
        Shorter side [m], > 0.
    b : float or ndarray
        Longer side [m], >= a; accurate to four significant figures for ``b >= 3a``.

    Returns
    -------
    float or ndarray
        ``K_p`` [m^4].
    """
    a, b = _sides(a, b)
    return _out(a**3 * (b - 0.630 * a) / 3.0)


def torsional_stiffness(G, K_p, length):
    """Torsional stiffness of a prismatic shaft, ``k_t = K_p G/l`` (Eqs. 2.111, 2.116).

    Parameters
    ----------
    G : float or ndarray
        Shear modulus [Pa], > 0.
    K_p : float or ndarray
        St Venant's torsion constant [m^4], > 0.
    length : float or ndarray
        Shaft length [m], > 0.

    Returns
    -------
    float or ndarray
        Stiffness [N·m/rad].
    """
    return _out(_positive("G", G, "Pa") * _positive("K_p", K_p, "m^4")
                / _positive("length", length, "m"))


def torsional_wave_speed(G, rho, K_p, I_p):
    """Torsional wave speed ``alpha = sqrt(K_p G/(rho I_p))`` (Eqs. 2.121–2.122).

    Parameters
    ----------
    G : float or ndarray
        Shear modulus [Pa], > 0.
    rho : float or ndarray
        Density [kg/m³], > 0.
    K_p : float or ndarray
        St Venant's torsion constant [m^4], > 0.
    I_p : float or ndarray
        Polar second moment of the section [m^4], > 0.

    Returns
    -------
    float or ndarray
        ``alpha`` [m/s]; ``sqrt(G/rho)`` for a circular section (``K_p = I_p``).

    Notes
    -----
    Erratum: (2.118) prints ``dθ/dx = dτ/(K_p G)``; generalising (2.111) to a slice ``dx``
    gives ``dθ/dx = τ/(K_p G)``, which is what (2.119) then uses.
    For a rectangle with (2.117) and (2.123), ``alpha² = (G/rho)·4a²(b - 0.630a)/(b(a²+b²))``
    (2.124); at ``b = 6.25a`` this is ``0.2996² G/rho``, the thesis's ``0.3² G/rho``
    (2.125): the wave, and so every mode frequency, is ``0.30`` times that of a circular
    rod. The thesis's remark after (2.132) that the bar has "thrice the flexibility" holds
    for frequencies (1/0.30 ≈ 3.3); stiffness per unit inertia is 0.09 times, about 11
    times more flexible.
    """
    return _out(np.sqrt(_positive("G", G, "Pa") * _positive("K_p", K_p, "m^4")
                        / (_positive("rho", rho, "kg/m^3") * _positive("I_p", I_p, "m^4"))))


def _boundary(boundary: str) -> str:
    if boundary not in _BOUNDARIES:
        raise ParameterError(f"boundary must be one of {_BOUNDARIES}; got {boundary!r}")
    return boundary


def shaft_natural_frequencies(alpha: float, length: float, n_modes: int,
                              boundary: str = "fixed-free") -> np.ndarray:
    """Undamped torsional natural frequencies of a uniform shaft (Eqs. 2.130–2.132).

    Parameters
    ----------
    alpha : float
        Torsional wave speed [m/s], > 0 (:func:`torsional_wave_speed`).
    length : float
        Shaft length [m], > 0.
    n_modes : int
        Number of modes, >= 1.
    boundary : {"fixed-free", "fixed-fixed"}
        ``fixed-free``: ``(2n-1)π α/(2l)`` (2.132), the conservative estimate;
        ``fixed-fixed``: ``nπ α/l``, the liberal estimate.

    Returns
    -------
    ndarray, shape (n_modes,)
        Frequencies [rad/s].

    Notes
    -----
    The thesis says fixed-fixed modes are at "double the frequency" of fixed-free ones;
    that holds for the fundamental only (ratio ``2n/(2n-1)``: 2, 4/3, 6/5, ...).

    Examples
    --------
    >>> shaft_natural_frequencies(2.0, np.pi, 2, "fixed-fixed")
    array([2., 4.])
    """
    a = float(_positive("alpha", alpha, "m/s"))
    ell = float(_positive("length", length, "m"))
    if int(n_modes) < 1:
        raise ParameterError(f"n_modes must be >= 1; got {n_modes!r}")
    n = np.arange(1, int(n_modes) + 1)
    k = (2 * n - 1) / 2.0 if _boundary(boundary) == "fixed-free" else n.astype(float)
    return k * np.pi * a / ell


def shaft_mode_shape(x, mode: int, length: float, boundary: str = "fixed-free"):
    """Mode shape ``phi(x) = sin(omega x/alpha)`` of a uniform shaft (Eqs. 2.130a, 2.131).

    Parameters
    ----------
    x : float or ndarray
        Position along the shaft from the fixed end [m], in [0, length].
    mode : int
        Mode number, >= 1.
    length : float
        Shaft length [m], > 0.
    boundary : {"fixed-free", "fixed-fixed"}
        Boundary conditions.

    Returns
    -------
    float or ndarray
        Mode shape, unit amplitude [-].
    """
    if int(mode) < 1:
        raise ParameterError(f"mode must be >= 1; got {mode!r}")
    ell = float(_positive("length", length, "m"))
    w = shaft_natural_frequencies(1.0, ell, int(mode), boundary)[-1]
    return _out(np.sin(w * np.asarray(x, dtype=float)))


# --------------------------------------------------------------------------- shafts
@dataclass(frozen=True, kw_only=True)
class CircularShaft:
    """Solid circular prismatic shaft in torsion (Eqs. 2.111–2.113, 2.122).

    Parameters
    ----------
    diameter : float
        Diameter [m], > 0.
    length : float
        Length [m], > 0.
    G : float
        Shear modulus [Pa], > 0.
    rho : float
        Density [kg/m³], > 0.
    """

    diameter: float
    length: float
    G: float
    rho: float

    def __post_init__(self):
        for name, unit in (("diameter", "m"), ("length", "m"), ("G", "Pa"), ("rho", "kg/m^3")):
            _positive(name, getattr(self, name), unit)

    @property
    def torsion_constant(self) -> float:
        """``K_p = I_p = pi d^4/32`` [m^4]."""
        return circular_polar_moment(self.diameter)

    @property
    def stiffness(self) -> float:
        """Torsional stiffness ``G K_p/l`` [N·m/rad]."""
        return torsional_stiffness(self.G, self.torsion_constant, self.length)

    @property
    def wave_speed(self) -> float:
        """Torsional wave speed ``sqrt(G/rho)`` [m/s]."""
        return torsional_wave_speed(self.G, self.rho, self.torsion_constant,
                                    self.torsion_constant)

    def natural_frequencies(self, n_modes: int, boundary: str = "fixed-free") -> np.ndarray:
        """Return the first ``n_modes`` torsional frequencies [rad/s] for ``boundary``."""
        return shaft_natural_frequencies(self.wave_speed, self.length, n_modes, boundary)


@dataclass(frozen=True, kw_only=True)
class RectangularShaft:
    """Rectangular prismatic bar in torsion (Eqs. 2.114–2.117, 2.122–2.124).

    Parameters
    ----------
    a : float
        Shorter side [m], > 0.
    b : float
        Longer side [m], >= a.
    length : float
        Length [m], > 0.
    G : float
        Shear modulus [Pa], > 0.
    rho : float
        Density [kg/m³], > 0.
    exact : bool
        Use the series (2.114) for ``K_p`` (default) rather than the approximation (2.117).
    """

    a: float
    b: float
    length: float
    G: float
    rho: float
    exact: bool = True

    def __post_init__(self):
        _sides(self.a, self.b)
        for name, unit in (("length", "m"), ("G", "Pa"), ("rho", "kg/m^3")):
            _positive(name, getattr(self, name), unit)

    @property
    def torsion_constant(self) -> float:
        """St Venant's ``K_p`` [m^4]."""
        if self.exact:
            return rectangular_torsion_constant(self.a, self.b)
        return rectangular_torsion_constant_approx(self.a, self.b)

    @property
    def polar_moment(self) -> float:
        """``I_p = ab(a²+b²)/12`` [m^4] (2.123)."""
        return rectangular_polar_moment(self.a, self.b)

    @property
    def stiffness(self) -> float:
        """Torsional stiffness ``G K_p/l`` [N·m/rad] (2.116)."""
        return torsional_stiffness(self.G, self.torsion_constant, self.length)

    @property
    def wave_speed(self) -> float:
        """Torsional wave speed [m/s] (2.122)."""
        return torsional_wave_speed(self.G, self.rho, self.torsion_constant, self.polar_moment)

    def natural_frequencies(self, n_modes: int, boundary: str = "fixed-free") -> np.ndarray:
        """Return the first ``n_modes`` torsional frequencies [rad/s] for ``boundary``."""
        return shaft_natural_frequencies(self.wave_speed, self.length, n_modes, boundary)
