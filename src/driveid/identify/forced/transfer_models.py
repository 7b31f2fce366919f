r"""Linear drive structures for :func:`driveid.identify.forced.transfer.estimate_transfer`.

Two structures map a parameter vector to a continuous state-space model ``(A, B, C)`` from
the command ``u`` to the measured output (speed, or position):

* ``"tf"`` — a strictly proper transfer function of order n in pole form,

  .. math::

     G(s) = \frac{b_m s^m + \dots + b_0}
                 {\prod_i (s^2 + 2\zeta_i\omega_{0,i} s + \omega_{0,i}^2)\prod_j (s + \sigma_j)},
     \qquad m = n - r,

  so that each resonance ``omega0_i``, ``zeta_i`` is a parameter of the fit itself and its
  standard error comes straight from the covariance (the delta method with an identity
  Jacobian); ``sigma_j`` are real poles (a free drive's rigid-body pole ``sigma ≈ 0``);
* ``"two-mass"`` — the compliant two-inertia drive (motor J_m, load J_l, shaft k, c; viscous
  losses c_m, c_l to the frame; torque ``gain·u`` on the motor)

  .. math::

     J_m \dot\omega_m = g u - k(\theta_m-\theta_l) - c(\omega_m-\omega_l) - c_m\omega_m,\quad
     J_l \dot\omega_l = k(\theta_m-\theta_l) + c(\omega_m-\omega_l) - c_l\omega_l,

  the lumped drive of de Marchi (1998) §2.3 (two bodies and a shaft, without backlash or
  Coulomb friction), measured at the motor or at the load.

Each model is simulated exactly for a zero-order-hold input: ``[[A, B], [0, 0]]·Δt`` through
the matrix exponential gives ``A_d, B_d``, and the discrete transfer function runs in
:func:`scipy.signal.lfilter` (the filter's state ``zi`` carries the unknown initial state).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic compliance
       nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.3.
.. [2] G. F. Franklin, J. D. Powell, M. Workman, *Digital Control of Dynamic Systems*, 3rd
       ed., Addison-Wesley, 1998, §4.3 (zero-order-hold equivalent by the matrix exponential).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass

import numpy as np
from scipy.linalg import expm
from scipy.signal import lfilter

from driveid.errors import IdentificationError, ParameterError

__all__ = ["TWO_MASS_PARAMETERS", "TWO_MASS_DEFAULT_FIXED", "LinearModel", "zoh_filter",
           "simulate", "tf_model", "two_mass_model", "arx_start", "resonances"]

#: Parameters of the two-mass structure, in order.
TWO_MASS_PARAMETERS = ("gain", "J_m", "J_l", "k", "c", "c_m", "c_l")
#: Values held unless freed: a torque command (gain 1) and no viscous loss at the load.
TWO_MASS_DEFAULT_FIXED: Mapping[str, float] = {"gain": 1.0, "c_l": 0.0}


@dataclass(frozen=True)
class LinearModel:
    """A parametrised linear structure: names, units, start, bounds and ``(A, B, C)``.

    Attributes
    ----------
    structure : str
        ``"tf"`` or ``"two-mass"``.
    names : tuple of str
        Free parameters, in the order of the fit vector.
    units : dict
        Parameter name -> SI unit (also of the fixed ones).
    start : ndarray, shape (p,)
        Start values [SI].
    scale : ndarray, shape (p,)
        Typical magnitudes [SI]; the fit works on ``theta / scale``.
    lower, upper : ndarray, shape (p,)
        Bounds [SI].
    state_space : callable
        ``theta [SI] -> (A, B, C)`` continuous-time, shapes (n, n), (n, 1), (1, n).
    fixed : dict
        Given parameters [SI].
    """

    structure: str
    names: tuple[str, ...]
    units: dict[str, str]
    start: np.ndarray
    scale: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    state_space: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]
    fixed: dict[str, float]

    def with_start(self, start: np.ndarray) -> LinearModel:
        """Return the same structure with other start values.

        Parameters
        ----------
        start : ndarray, shape (p,)
            Start values [SI].

        Returns
        -------
        LinearModel
            A copy; the scale follows the new start where it is non-zero.
        """
        start = np.clip(np.asarray(start, float), self.lower, self.upper)
        scale = np.where(np.abs(start) > 0, np.abs(start), self.scale)
        return LinearModel(self.structure, self.names, self.units, start, scale, self.lower,
                           self.upper, self.state_space, self.fixed)


def zoh_filter(A: np.ndarray, B: np.ndarray, C: np.ndarray, dt: float
               ) -> tuple[np.ndarray, np.ndarray]:
    """Return the exact zero-order-hold discrete transfer function of ``(A, B, C)``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        State matrix [1/s].
    B : ndarray, shape (n, 1)
        Input matrix [state unit/(s·input unit)].
    C : ndarray, shape (1, n)
        Output matrix [output unit/state unit].
    dt : float
        Sampling interval [s].

    Returns
    -------
    tuple of ndarray
        ``(num, den)``, shapes (n + 1,), for :func:`scipy.signal.lfilter`; ``den[0] = 1``.

    Examples
    --------
    >>> num, den = zoh_filter(np.array([[-2.0]]), np.array([[2.0]]), np.array([[1.0]]), 0.1)
    >>> round(float(num[1]), 6), round(float(-den[1]), 6)  # 1 - e^{-0.2}, e^{-0.2}
    (0.181269, 0.818731)
    """
    n = A.shape[0]
    block = np.zeros((n + 1, n + 1))
    block[:n, :n] = A
    block[:n, n:] = B
    E = expm(block * dt)
    Ad, Bd = E[:n, :n], E[:n, n:]
    # SISO with D = 0: den = det(zI - Ad), num = det(zI - Ad + Bd C) - den (as ss2tf, without
    # its checks, which cost ten times the rest on small systems)
    den = np.real(np.poly(Ad))
    num = np.real(np.poly(Ad - Bd @ C)) - den
    return num, den


def simulate(model: LinearModel, theta: np.ndarray, u: np.ndarray, dt: float,
             zi: np.ndarray | None = None, absolute: bool = False) -> np.ndarray:
    """Output of ``model`` at ``theta`` for the held input ``u``, from the filter state ``zi``.

    Parameters
    ----------
    model : LinearModel
        The structure.
    theta : ndarray, shape (p,)
        Free parameters [SI].
    u : ndarray, shape (N,)
        Command samples, held between samples [input unit].
    dt : float
        Sampling interval [s].
    zi : ndarray, shape (n,), optional
        Initial state of the discrete filter [output unit]; zero (at rest) if omitted.
    absolute : bool
        Pass the output through ``|·|`` (a speed-magnitude sensor).

    Returns
    -------
    ndarray, shape (N,)
        The model output [output unit].
    """
    A, B, C = model.state_space(theta)
    num, den = zoh_filter(A, B, C, dt)
    if zi is None:
        y = lfilter(num, den, u)
    else:
        y, _ = lfilter(num, den, u, zi=zi)
    return np.abs(y) if absolute else y


def _poly_from_poles(pairs: np.ndarray, reals: np.ndarray) -> np.ndarray:
    den = np.ones(1)
    for w, z in pairs:
        den = np.polymul(den, [1.0, 2.0 * z * w, w * w])
    for s in reals:
        den = np.polymul(den, [1.0, s])
    return den


def _companion(num: np.ndarray, den: np.ndarray):
    """Return the controllable canonical form of a strictly proper ``num/den`` (den monic)."""
    n = den.size - 1
    A = np.zeros((n, n))
    A[0, :] = -den[1:]
    A[1:, :-1] = np.eye(n - 1)
    B = np.zeros((n, 1))
    B[0, 0] = 1.0
    C = np.zeros((1, n))
    C[0, n - num.size:] = num
    return A, B, C


def tf_model(n_pairs: int, n_real: int, n_num: int, *, start: np.ndarray | None = None,
             units: Mapping[str, str]) -> LinearModel:
    """Return the pole-form transfer-function structure.

    Parameters
    ----------
    n_pairs : int
        Complex pole pairs (resonances) [-].
    n_real : int
        Real poles [-].
    n_num : int
        Numerator coefficients ``b_0 … b_{n_num-1}`` [-], ``1 <= n_num <= 2 n_pairs + n_real``
        (``n_num = n - relative degree + 1``).
    start : ndarray, optional
        Start values in the order ``omega0_i, zeta_i`` (per pair), ``sigma_j``, ``b_k``.
    units : mapping
        ``"u"`` and ``"y"``: units of input and output.

    Returns
    -------
    LinearModel
        ``structure="tf"``.
    """
    n = 2 * n_pairs + n_real
    if not 1 <= n_num <= n:
        raise ParameterError(
            f"the numerator has {n_num} coefficient(s) for order {n}; need 1..{n} (a strictly "
            "proper model: lower --relative-degree or raise --order)")
    names: list[str] = []
    unit: dict[str, str] = {}
    for i in range(1, n_pairs + 1):
        names += [f"omega0_{i}", f"zeta_{i}"]
        unit[f"omega0_{i}"], unit[f"zeta_{i}"] = "rad/s", "-"
    for j in range(1, n_real + 1):
        names.append(f"sigma_{j}")
        unit[f"sigma_{j}"] = "1/s"
    for k in range(n_num):
        names.append(f"b_{k}")
        power = "/s" if n - k == 1 else f"/s^{n - k}"
        unit[f"b_{k}"] = f"({units['y']})/({units['u']}){power}"
    p = len(names)
    lower = np.full(p, -np.inf)
    upper = np.full(p, np.inf)
    for i in range(n_pairs):
        lower[2 * i], lower[2 * i + 1] = 1e-9, 0.0
    start = np.ones(p) if start is None else np.asarray(start, float)

    def state_space(theta: np.ndarray):
        pairs = np.asarray(theta[:2 * n_pairs]).reshape(n_pairs, 2)
        den = _poly_from_poles(pairs, theta[2 * n_pairs:n])
        return _companion(np.asarray(theta[n:], float)[::-1], den)

    scale = np.where(np.abs(start) > 0, np.abs(start), 1.0)
    return LinearModel("tf", tuple(names), unit, start, scale, lower, upper, state_space, {})


def _two_mass_ss(values: Mapping[str, float], side: str, quantity: str):
    g, Jm, Jl, k, c, cm, cl = (values[n] for n in TWO_MASS_PARAMETERS)
    # states: θm, θl, ωm, ωl; the speed outputs drop the absolute angle (θm - θl suffices)
    A = np.array([[0.0, 0.0, 1.0, 0.0],
                  [0.0, 0.0, 0.0, 1.0],
                  [-k / Jm, k / Jm, -(c + cm) / Jm, c / Jm],
                  [k / Jl, -k / Jl, c / Jl, -(c + cl) / Jl]])
    B = np.array([[0.0], [0.0], [g / Jm], [0.0]])
    index = {("motor", "position"): 0, ("load", "position"): 1,
             ("motor", "speed"): 2, ("load", "speed"): 3}[(side, quantity)]
    if quantity == "speed":
        T = np.array([[1.0, -1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]])
        A = T @ A @ np.linalg.pinv(T)
        B = T @ B
        C = np.zeros((1, 3))
        C[0, index - 1] = 1.0
        return A, B, C
    C = np.zeros((1, 4))
    C[0, index] = 1.0
    return A, B, C


def two_mass_model(*, side: str, quantity: str, fixed: Mapping[str, float],
                   start: Mapping[str, float], units: Mapping[str, str]) -> LinearModel:
    """Return the two-inertia grey box measured at the motor or the load.

    Parameters
    ----------
    side : {"motor", "load"}
        Where the output is measured.
    quantity : {"speed", "position"}
        What is measured [rad/s or rad].
    fixed : mapping
        Given parameters (names of :data:`TWO_MASS_PARAMETERS`) [SI].
    start : mapping
        Start values of every parameter [SI].
    units : mapping
        ``"u"``: unit of the command (the gain is in N·m per that unit).

    Returns
    -------
    LinearModel
        ``structure="two-mass"``.

    Raises
    ------
    ParameterError
        Unknown names, a given value outside its range (inertias and stiffness > 0,
        dampings >= 0, gain non-zero), or a free gain with no mechanical parameter given
        (the scale of the inertias is then not identifiable).
    """
    unknown = set(fixed) - set(TWO_MASS_PARAMETERS)
    if unknown:
        raise ParameterError(
            f"unknown two-mass parameter(s) {sorted(unknown)}; use "
            f"{', '.join(TWO_MASS_PARAMETERS)}")
    for name, value in fixed.items():  # issue 28: --fix J_m=-1 was fitted without a word
        positive, value = name in ("J_m", "J_l", "k"), float(value)
        ok = math.isfinite(value) and (value > 0 if positive else
                                       value != 0 if name == "gain" else value >= 0)
        if not ok:
            rule = ("> 0 (an inertia or stiffness)" if positive else
                    "finite and non-zero (a zero gain moves nothing)" if name == "gain" else
                    ">= 0 (a damping)")
            raise ParameterError(
                f"two-mass parameter {name} must be {rule}; got {name} = {value!r}: check the "
                f"value and its SI unit (--fix {name}=VALUE)")
    if "gain" not in fixed and not {"J_m", "J_l", "k"} & set(fixed):
        raise ParameterError(
            "a free gain with free J_m, J_l and k is not identifiable (only ratios such as "
            "gain/J_m are); give one of them, e.g. --fix J_m=2e-4, or --fix gain=1 for a torque "
            "command")
    names = tuple(n for n in TWO_MASS_PARAMETERS if n not in fixed)
    gain_unit = "N·m" if units["u"] in ("N·m", "") else f"N·m/({units['u']})"
    unit = {"gain": gain_unit, "J_m": "kg·m²", "J_l": "kg·m²", "k": "N·m/rad",
            "c": "N·m·s/rad", "c_m": "N·m·s/rad", "c_l": "N·m·s/rad"}
    fixed = {k: float(v) for k, v in fixed.items()}
    s = np.array([float(start[n]) for n in names])
    lower = np.array([1e-12 if n in ("J_m", "J_l", "k", "gain") else 0.0 for n in names])
    upper = np.full(len(names), np.inf)

    def state_space(theta: np.ndarray):
        values = dict(fixed)
        values.update(zip(names, (float(v) for v in theta), strict=True))
        return _two_mass_ss(values, side, quantity)

    scale = np.where(np.abs(s) > 0, np.abs(s), 1.0)
    return LinearModel("two-mass", names, unit, s, scale, lower, upper, state_space, fixed)


def arx_start(u: np.ndarray, y: np.ndarray, dt: float, order: int, relative_degree: int,
              iterations: int = 8) -> tuple[int, int, np.ndarray]:
    """Start values of the pole-form structure by Steiglitz–McBride iterations.

    An ARX fit of order ``order`` is refined by refitting on data prefiltered by ``1/A(q)``
    (which tends to the output-error estimate); its discrete poles ``z`` map to ``s = ln z/Δt``
    and, with the denominator held, the numerator follows by linear least squares on
    simulated basis responses.

    Parameters
    ----------
    u : ndarray, shape (N,)
        Command [input unit].
    y : ndarray, shape (N,)
        Output [output unit].
    dt : float
        Sampling interval [s].
    order : int
        Number of poles n [-].
    relative_degree : int
        ``n - m`` for numerator degree m [-], 1..n.
    iterations : int
        Steiglitz–McBride iterations [-].

    Returns
    -------
    tuple
        ``(n_pairs, n_real, start)`` for :func:`tf_model`.

    Raises
    ------
    IdentificationError
        If the regression is singular (no excitation).
    """
    n = order
    N = y.size
    a = np.zeros(n)
    yf, uf = y, u
    best = None
    for _ in range(iterations + 1):
        rows = np.column_stack([-yf[n - i - 1:N - i - 1] for i in range(n)]
                               + [uf[n - i - 1:N - i - 1] for i in range(n)])
        target = yf[n:]
        sol, *_ = np.linalg.lstsq(rows, target, rcond=None)
        if not np.all(np.isfinite(sol)):
            break
        a = sol[:n]
        roots = np.roots(np.concatenate([[1.0], a]))
        # reflect unstable roots so that the prefilter stays bounded
        roots = np.where(np.abs(roots) > 1.0, 1.0 / np.conj(roots), roots)
        den = np.real(np.poly(roots))
        best = roots
        yf, uf = lfilter([1.0], den, y), lfilter([1.0], den, u)
    if best is None:
        raise IdentificationError(
            "the command does not excite the output (singular regression); use a broadband "
            "command (PRBS, multisine, chirp) of a larger amplitude")
    s = np.log(best.astype(complex)) / dt
    pairs = sorted(((abs(p), -p.real / abs(p)) for p in s
                    if p.imag > 1e-9 * abs(p) and abs(p.imag) < 0.999 * math.pi / dt),
                   key=lambda wz: wz[0])
    reals = [-(np.log(abs(z)) / dt) for z, p in zip(best, s, strict=True)
             if not (abs(p.imag) > 1e-9 * abs(p) and abs(p.imag) < 0.999 * math.pi / dt)]
    # a real pole at z < 0 has no continuous counterpart: keep its decay rate
    n_pairs = len(pairs)
    reals = reals[: n - 2 * n_pairs]
    while len(reals) < n - 2 * n_pairs:
        reals.append(1.0 / (10 * dt))
    pole_part = [v for wz in pairs for v in (wz[0], min(max(wz[1], 1e-3), 5.0))] + list(reals)
    n_num = n - relative_degree + 1
    base = tf_model(n_pairs, len(reals), n_num, units={"u": "", "y": ""})
    basis = []
    for k in range(n_num):
        theta = np.array(pole_part + [1.0 if j == k else 0.0 for j in range(n_num)])
        basis.append(simulate(base, theta, u, dt))
    B = np.column_stack(basis)
    b, *_ = np.linalg.lstsq(B, y, rcond=None)
    return n_pairs, len(reals), np.array(pole_part + list(b))


def resonances(A: np.ndarray) -> list[tuple[float, float]]:
    """Complex pole pairs of ``A`` as ``(omega0, zeta)``, sorted by ``omega0``.

    Parameters
    ----------
    A : ndarray, shape (n, n)
        Continuous state matrix [1/s].

    Returns
    -------
    list of tuple
        ``(omega0 [rad/s], zeta [-])`` per pair with positive imaginary part.

    Examples
    --------
    >>> A = np.array([[0.0, 1.0], [-100.0, -2.0]])
    >>> [(round(w, 6), round(z, 6)) for w, z in resonances(A)]
    [(10.0, 0.1)]
    """
    poles = np.linalg.eigvals(A)
    out = [(float(abs(p)), float(-p.real / abs(p))) for p in poles
           if p.imag > 1e-9 * max(abs(p), 1e-300)]
    return sorted(out)
