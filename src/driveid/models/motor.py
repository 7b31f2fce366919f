r"""Drive motor transfer functions (de Marchi 1998, §2.1.4.1, Eqs. 2.102–2.109).

* Two-phase AC motor, ``θ/v_c = k_m/(s(t_m s + 1))`` (2.102) with ``t_m = J_m/(ν_m - p)``
  (2.103), and its large-inertia limit ``k_m/(t_m s²)`` (2.104).
* Armature DC servomotor (2.105), its reduced form for ``L_m ≈ 0``, ``k_EMF ≈ k_m``
  (2.106), with an amplifier of gain ``k_a`` (2.107–2.108), and the direction-split model
  with separate friction for positive, zero and negative speed (2.109).

All functions return :class:`scipy.signal.TransferFunction` objects (rad per input unit).

The motor friction ``μ_m(s)`` (torque per unit speed, ``τ = μ_m(s)·sθ``) is given either as
a viscous coefficient [N·m·s/rad] or as a pair ``(num, den)`` of polynomial coefficients in
``s`` (highest power first) for a first-order dynamic friction; e.g. a presliding spring of
stiffness ``σ0`` [N·m/rad] is ``([σ0], [1, 0])`` (``μ = σ0/s``).

References
----------
.. [1] J. A. de Marchi, "Modeling of dynamic friction, impact backlash and elastic
       compliance nonlinearities in machine tools", PhD thesis, RPI, 1998, §2.1.4.1.
.. [2] R. C. Dorf, *Modern Control Systems*, Addison-Wesley, Table 2.5 (the thesis's [91]).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.signal import TransferFunction

from driveid.errors import ParameterError

__all__ = [
    "ACMotorParams",
    "DCMotorParams",
    "MotorAmplifier",
    "ac_motor_tf",
    "dc_motor_tf",
    "dc_motor_tf_split",
]


def _real(obj, name: str, unit: str, *, lower: float | None = 0.0, strict: bool = True) -> float:
    v = float(getattr(obj, name))
    if not np.isfinite(v):
        raise ParameterError(f"{name} must be finite [{unit}]; got {v!r}")
    if lower is not None and (v <= lower if strict else v < lower):
        rule = "positive" if strict else "non-negative"
        raise ParameterError(f"{name} must be {rule} [{unit}]; got {v!r}")
    return v


@dataclass(frozen=True, kw_only=True)
class ACMotorParams:
    """Two-phase AC motor (Eqs. 2.102–2.103).

    Parameters
    ----------
    k_m : float
        Motor constant [rad/(V·s)], > 0: steady speed per control volt.
    J_m : float
        Rotor inertia [kg·m²], > 0.
    nu_m : float
        Shaft viscous friction [N·m·s/rad], >= 0.
    p : float
        Slope of the linearised torque–speed curve ``dτ/dω`` [N·m·s/rad], usually negative;
        ``nu_m - p`` must be positive.
    """

    k_m: float
    J_m: float
    nu_m: float
    p: float

    def __post_init__(self):
        _real(self, "k_m", "rad/(V·s)")
        _real(self, "J_m", "kg·m²")
        _real(self, "nu_m", "N·m·s/rad", strict=False)
        _real(self, "p", "N·m·s/rad", lower=None)
        if not self.nu_m - self.p > 0.0:
            raise ParameterError(
                "nu_m - p must be positive [N·m·s/rad] for a stable motor (p is the usually "
                f"negative torque-speed slope); got {self.nu_m - self.p!r}")

    @property
    def time_constant(self) -> float:
        """Motor time constant ``t_m = J_m/(nu_m - p)`` [s] (2.103)."""
        return self.J_m / (self.nu_m - self.p)


@dataclass(frozen=True, kw_only=True)
class DCMotorParams:
    """Armature-controlled DC servomotor (Eq. 2.105).

    Parameters
    ----------
    k_m : float
        Torque constant [N·m/A], > 0.
    J_m : float
        Rotor inertia [kg·m²] (the thesis writes N·m·s²), > 0.
    R_m : float
        Armature resistance [Ω], > 0.
    L_m : float
        Armature inductance [H], >= 0.
    k_emf : float
        Back-EMF constant [V·s/rad], > 0; ≈ ``k_m`` in SI units.
    nu_m : float
        Viscous friction [N·m·s/rad], >= 0; the default ``μ_m(s)``.
    """

    k_m: float
    J_m: float
    R_m: float
    L_m: float
    k_emf: float
    nu_m: float

    def __post_init__(self):
        _real(self, "k_m", "N·m/A")
        _real(self, "J_m", "kg·m²")
        _real(self, "R_m", "Ω")
        _real(self, "L_m", "H", strict=False)
        _real(self, "k_emf", "V·s/rad")
        _real(self, "nu_m", "N·m·s/rad", strict=False)


def ac_motor_tf(params: ACMotorParams, *, large_inertia: bool = False) -> TransferFunction:
    """Transfer function from control voltage to motor angle of a two-phase AC motor.

    Parameters
    ----------
    params : ACMotorParams
        Motor constant [rad/(V·s)], inertia [kg·m²], friction and slope [N·m·s/rad].
    large_inertia : bool, optional
        False: ``k_m/(s(t_m s + 1))`` (2.102). True: ``k_m/(t_m s²)`` (2.104), its
        asymptote for ``ω t_m >> 1``.

    Returns
    -------
    scipy.signal.TransferFunction
        ``θ_m(s)/v_c(s)`` [rad/V].

    Examples
    --------
    >>> tf = ac_motor_tf(ACMotorParams(k_m=2.0, J_m=0.1, nu_m=0.05, p=-0.05))
    >>> tf.den.tolist()
    [1.0, 1.0, 0.0]
    """
    tm = params.time_constant
    if large_inertia:
        return TransferFunction([params.k_m], [tm, 0.0, 0.0])
    return TransferFunction([params.k_m], [tm, 1.0, 0.0])


def _friction_poly(friction, default: float):
    if friction is None:
        friction = default
    if np.isscalar(friction) or (isinstance(friction, np.ndarray) and friction.ndim == 0):
        v = float(friction)
        if not (np.isfinite(v) and v >= 0.0):
            raise ParameterError(
                f"friction must be a non-negative viscous coefficient [N·m·s/rad] or a "
                f"(num, den) pair of polynomials in s; got {v!r}")
        return np.array([v]), np.array([1.0])
    try:
        num, den = friction
    except (TypeError, ValueError) as exc:
        raise ParameterError(
            "friction must be a number [N·m·s/rad] or a (num, den) pair of polynomial "
            f"coefficients in s; got {friction!r}") from exc
    num = np.atleast_1d(np.asarray(num, dtype=float))
    den = np.atleast_1d(np.asarray(den, dtype=float))
    if not (np.all(np.isfinite(num)) and np.all(np.isfinite(den)) and np.any(den != 0)):
        raise ParameterError(
            f"friction (num, den) must be finite with a non-zero denominator; got {friction!r}")
    return num, den


def _dc_poly(params: DCMotorParams, friction, reduced: bool, gain: float):
    fn, fd = _friction_poly(friction, params.nu_m)
    J, R = params.J_m, params.R_m
    # Multiply numerator and denominator by den(μ) so that μ(s) = fn/fd stays polynomial.
    mech = np.polyadd(np.polymul([J, 0.0], fd), fn)  # (J s + μ) fd
    if reduced:
        elec = np.array([R])
        coupling = params.k_m**2
    else:
        elec = np.array([params.L_m, R])
        coupling = params.k_m * params.k_emf
    num = gain * params.k_m * np.polymul(elec, fd)
    den = np.polymul([1.0, 0.0], np.polyadd(np.polymul(mech, elec), coupling * fd))
    # Exact leading zeros (L_m = 0) would make scipy warn about bad coefficients.
    return np.trim_zeros(num, "f"), np.trim_zeros(den, "f")


def _gain(amplifier_gain) -> float:
    if amplifier_gain is None:
        return 1.0
    g = float(amplifier_gain)
    if not (np.isfinite(g) and g > 0.0):
        raise ParameterError(f"amplifier_gain k_a must be positive [A/V]; got {g!r}")
    return g


def dc_motor_tf(params: DCMotorParams, *, friction=None, reduced: bool = False,
                amplifier_gain: float | None = None) -> TransferFunction:
    r"""Transfer function of the armature DC servomotor (Eqs. 2.105–2.108).

    Parameters
    ----------
    params : DCMotorParams
        Motor constants (see its docstring for units).
    friction : float or (array_like, array_like), optional
        Motor friction ``μ_m(s)`` [N·m·s/rad], a viscous coefficient or ``(num, den)`` in
        ``s``; default ``params.nu_m``.
    reduced : bool, optional
        False: full form (2.105). True: ``L_m = 0`` and ``k_EMF = k_m`` (2.106).
    amplifier_gain : float, optional
        Amplifier constant ``k_a`` [A/V], > 0. If given, the input is the control voltage
        ``v_c`` (2.107, 2.108) instead of the current ``i_a``.

    Returns
    -------
    scipy.signal.TransferFunction
        ``θ_m/i_a`` [rad/A], or ``θ_m/v_c`` [rad/V] with an amplifier.

    Notes
    -----
    .. math:: \frac{\theta_m}{i_a} = \frac{k_m(L_m s + R_m)}
              {s[(J_m s + \mu_m(s))(L_m s + R_m) + k_m k_{EMF}]}   (2.105)

    (2.105) is the armature-*voltage* transfer function ``k_m/(s[(Js+μ)(Ls+R) + k_m
    k_EMF])`` times ``(L_m s + R_m)``, i.e. its input is the locked-rotor current
    ``v_a/(L_m s + R_m)``; with an ideal current loop that rejects the back-EMF the
    result would instead be ``k_m/(s(J_m s + μ_m))``. Implemented as printed; checked
    against the state equations of the motor in ``tests/models/test_motor.py``.
    The text after (2.106) calls its input ``v_c``; it is ``i_a`` there (misprint).

    Examples
    --------
    >>> p = DCMotorParams(k_m=0.1, J_m=1e-4, R_m=1.0, L_m=0.0, k_emf=0.1, nu_m=0.0)
    >>> tf = dc_motor_tf(p, reduced=True)  # 1000/(s(s + 100)), normalised by scipy
    >>> tf.num.round(9).tolist(), tf.den.round(9).tolist()
    ([1000.0], [1.0, 100.0, 0.0])
    """
    num, den = _dc_poly(params, friction, reduced, _gain(amplifier_gain))
    return TransferFunction(num, den)


def dc_motor_tf_split(params: DCMotorParams, *, friction_plus, friction_zero, friction_minus,
                      amplifier_gain: float | None = None) -> dict[str, TransferFunction]:
    r"""Direction-split reduced DC motor model (Eq. 2.109, corrected middle branch).

    Parameters
    ----------
    params : DCMotorParams
        Motor constants; ``L_m`` and ``k_emf`` are not used (reduced form).
    friction_plus : float or (array_like, array_like)
        Dynamic friction ``μ_m^+(s)`` for ``θ_m' > 0`` [N·m·s/rad].
    friction_zero : float or (array_like, array_like)
        Presliding friction ``μ_m^0(s)`` at rest [N·m·s/rad], e.g. ``([σ0], [1, 0])`` for a
        presliding spring ``σ0`` [N·m/rad].
    friction_minus : float or (array_like, array_like)
        Dynamic friction ``μ_m^-(s)`` for ``θ_m' < 0`` [N·m·s/rad].
    amplifier_gain : float, optional
        Amplifier constant ``k_a`` [A/V]; default 1 (input ``i_a``).

    Returns
    -------
    dict of str to scipy.signal.TransferFunction
        Keys ``"plus"``, ``"zero"``, ``"minus"``: ``θ_m/v_c`` [rad/V] (or [rad/A]) for each
        speed domain, each ``k_a k_m R_m/(s[(J_m s + μ)R_m + k_m²])``.

    Notes
    -----
    Erratum: (2.109) prints the rest branch as ``k_a k_m R_m/(s μ_m^0(s))``, whose units
    differ from the other branches by Ω (``μ R_m`` vs ``μ``) and which drops the inertia;
    the rest branch here has the same form as the others with ``μ_m^0``.
    """
    gain = _gain(amplifier_gain)
    out = {}
    for key, fr in (("plus", friction_plus), ("zero", friction_zero), ("minus", friction_minus)):
        num, den = _dc_poly(params, fr, True, gain)
        out[key] = TransferFunction(num, den)
    return out


_MOTOR_MODES = ("voltage", "current")


@dataclass(frozen=True, kw_only=True)
class MotorAmplifier:
    r"""DC motor armature and amplifier driving the motor body (Eqs. 2.105–2.108).

    The command ``u`` of the drive (PD output plus the external command of the motor body)
    enters the amplifier; the motor torque ``k_m i`` [N·m] acts on the motor body. The rotor
    inertia and friction belong to that body, not to this object.

    Parameters
    ----------
    k_m : float
        Torque constant [N·m/A], > 0.
    k_emf : float
        Back-EMF constant [V·s/rad], >= 0 (≈ ``k_m`` in SI units); used in voltage mode.
    R_m : float
        Armature resistance [Ω], > 0.
    L_m : float
        Armature inductance [H], >= 0; 0 makes the current quasi-static
        (``i = (V - k_emf ω)/R_m``, the reduced form 2.106).
    k_a : float
        Amplifier gain, > 0: [V per command unit] in voltage mode, [A per command unit] in
        current mode (the thesis's ``k_a``, 2.107–2.108).
    mode : {"voltage", "current"}, optional
        ``"voltage"``: ``V = k_a u`` and ``L_m di/dt = V - R_m i - k_emf ω`` (2.105).
        ``"current"``: a current loop of bandwidth ``current_bandwidth`` tracks ``k_a u``,
        ``di/dt = ω_c (k_a u - i)``; the loop rejects the back-EMF. Default ``"voltage"``.
    current_bandwidth : float, optional
        Current-loop bandwidth ``ω_c`` [rad/s], > 0, or ``inf`` for an ideal loop
        (``i = k_a u``); current mode only. Default ``inf``.
    voltage_limit : float, optional
        Amplifier output saturation ``|V| <= voltage_limit`` [V], > 0; default ``inf``.
    current_limit : float, optional
        Armature current saturation ``|i| <= current_limit`` [A], > 0; default ``inf``. In
        voltage mode with ``L_m = 0`` and in ideal current mode the current is clipped; with a
        current state it is the commanded current (current mode) or the integrated current
        (voltage mode, as an anti-windup clamp) that is limited.

    Notes
    -----
    The motor body is the drive's feedback body, or body 0 without feedback. With
    ``L_m = 0``, voltage mode and viscous friction ``c`` on a motor body of inertia ``J``, a
    constant command ``u`` gives ``ω_ss = k_m k_a u/(R_m c + k_m k_emf)`` with time constant
    ``J R_m/(R_m c + k_m k_emf)``.

    Relation to the thesis: the input ``i_a`` of (2.105) is the locked-rotor current
    ``V/(L_m s + R_m)`` (see :func:`dc_motor_tf`), so voltage mode is (2.105) with
    ``V = (L_m s + R_m) i_a``; for ``L_m = 0`` the thesis's (2.107)/(2.108) with its
    amplifier constant ``k_a`` [A/V] is voltage mode with gain ``k_a R_m`` [V/V]. Current
    mode is the physical current loop, which rejects the back-EMF: ``θ/u → k_m k_a/(s(J s +
    μ))`` as ``ω_c → ∞``.

    Examples
    --------
    >>> m = MotorAmplifier(k_m=0.1, k_emf=0.1, R_m=1.0, L_m=0.0, k_a=2.0)
    >>> m.mode, m.quasi_static
    ('voltage', True)
    """

    k_m: float
    k_emf: float
    R_m: float
    L_m: float
    k_a: float
    mode: str = "voltage"
    current_bandwidth: float = float("inf")
    voltage_limit: float = float("inf")
    current_limit: float = float("inf")

    def __post_init__(self):
        _real(self, "k_m", "N·m/A")
        _real(self, "k_emf", "V·s/rad", strict=False)
        _real(self, "R_m", "Ω")
        _real(self, "L_m", "H", strict=False)
        _real(self, "k_a", "V or A per command unit")
        if self.mode not in _MOTOR_MODES:
            raise ParameterError(
                f"mode must be 'voltage' or 'current'; got {self.mode!r}")
        for name, unit in (("current_bandwidth", "rad/s"), ("voltage_limit", "V"),
                           ("current_limit", "A")):
            v = float(getattr(self, name))
            if np.isnan(v) or not v > 0.0:
                raise ParameterError(
                    f"{name} must be positive [{unit}] (inf for none); got {v!r}")

    @property
    def quasi_static(self) -> bool:
        """True when the armature current has no state of its own (algebraic current)."""
        if self.mode == "voltage":
            return self.L_m == 0.0
        return not np.isfinite(self.current_bandwidth)
