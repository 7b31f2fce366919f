"""Tests of the dynamic friction models, de Marchi (1998) Eqs. (2.15)–(2.26)."""

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from driveid.errors import ParameterError
from driveid.models.dynamic_friction import (
    ArmstrongParams,
    CanudasParams,
    DahlParams,
    LuGreParams,
    armstrong_friction,
    canudas_friction,
    canudas_jacobian,
    canudas_state_derivative,
    canudas_steady_friction,
    dahl_friction,
    dahl_jacobian,
    dahl_state_derivative,
    lugre_friction,
    lugre_jacobian,
    lugre_passivity_bound,
    lugre_state_derivative,
    lugre_steady_friction,
    lugre_stribeck,
)
from driveid.models.friction import (
    BoPavelescuParams,
    bo_pavelescu_friction,
)
from driveid.models.friction_memory import (
    RisingStribeckParams,
    rising_lorentzian_friction,
)


def _lugre(**kw):
    base = dict(sigma0=1e5, sigma1=0.5, sigma2=0.4, fc=1.0, fs=1.5, vs=0.01)
    base.update(kw)
    return LuGreParams(**base)


# --- LuGre -------------------------------------------------------------------------------


@pytest.mark.parametrize("v", [-0.5, -0.012, -1e-3, 2e-3, 0.01, 0.3])
def test_lugre_radau_reaches_its_stribeck_map(v):
    p = _lugre(sigma1=300.0, check_passivity=False)  # stiff bristle damping on purpose
    g = lugre_stribeck(v, p)
    tau = g / (p.sigma0 * abs(v))  # relaxation time of z at constant v
    sol = solve_ivp(
        lambda t, z: lugre_state_derivative(z, v, p),
        (0.0, 40.0 * tau),
        [0.0],
        method="Radau",
        jac=lambda t, z: np.atleast_2d(lugre_jacobian(z, v, p)),
        rtol=1e-10,
        atol=1e-14,
        dense_output=True,
    )
    assert sol.success
    t = np.linspace(0.0, 40.0 * tau, 50)
    z_true = (g / p.sigma0) * np.sign(v) * (1.0 - np.exp(-t / tau))  # closed form, z(0) = 0
    # rtol 1e-10 of the solver on z of size g/sigma0 ~ 1e-5: 1e-12 absolute is generous.
    np.testing.assert_allclose(sol.sol(t)[0], z_true, atol=1e-12 * max(1.0, g) + 1e-15)
    f_end = lugre_friction(sol.y[0, -1], v, p)
    # exp(-40) transient left plus solver tolerance: 1e-9 relative.
    assert f_end == pytest.approx(lugre_steady_friction(v, p), rel=1e-9)
    # The thesis: at steady velocity LuGre is the (2.5) map with delta = 2.
    bp = BoPavelescuParams(mu_k=p.fc, mu_s=p.fs, nu=p.sigma2, v_s=p.vs, delta=2.0)
    assert lugre_steady_friction(v, p) == pytest.approx(bo_pavelescu_friction(v, bp), rel=1e-14)


def test_lugre_reduces_to_dahl_as_stated_in_2_1_1_6():
    # Thesis after (2.26): nu_s = nu = 0, gamma = 1, g = mu_k/k_s (no Stribeck) gives Dahl.
    lug = _lugre(sigma1=0.0, sigma2=0.0, fc=2.0, fs=2.0)
    dahl = DahlParams(k_s=lug.sigma0, mu_k=lug.fc, gamma=1.0, nu=0.0)
    rng = np.random.default_rng(7)
    z = rng.uniform(-2.0, 2.0, 200) * lug.fc / lug.sigma0
    v = rng.normal(0.0, 0.05, 200)
    # d(sigma0 z)/dt from LuGre equals df/dt of Dahl at f = sigma0 z.
    np.testing.assert_allclose(
        lug.sigma0 * lugre_state_derivative(z, v, lug),
        dahl_state_derivative(lug.sigma0 * z, v, dahl),
        rtol=1e-12,
        atol=1e-12,
    )
    # Whole trajectories under a sinusoidal displacement (hysteresis loop).
    w, amp = 2 * np.pi, 5e-5

    def vel(t):
        return amp * w * np.cos(w * t)

    t_eval = np.linspace(0.0, 2.0, 400)
    opts = dict(method="Radau", rtol=1e-10, atol=1e-14, t_eval=t_eval, max_step=1e-3)
    sl = solve_ivp(lambda t, z: lugre_state_derivative(z, vel(t), lug), (0, 2), [0.0], **opts)
    sd = solve_ivp(lambda t, f: dahl_state_derivative(f, vel(t), dahl), (0, 2), [0.0], **opts)
    # Forces of order 2 N, two solvers at rtol 1e-10: agree to 1e-7 N.
    np.testing.assert_allclose(
        lugre_friction(sl.y[0], vel(t_eval), lug),
        dahl_friction(sd.y[0], vel(t_eval), dahl),
        atol=1e-7,
    )


def _energy_after_step(p, v, c):
    """Energy F*v integrated over c relaxation times after a step from sigma0 z = fs."""
    lam = p.sigma0 * abs(v) / lugre_stribeck(v, p)
    t = np.linspace(0.0, c / lam, 20001)
    z_ss = lugre_stribeck(v, p) / p.sigma0 * np.sign(v)
    z = z_ss + (p.fs / p.sigma0 * np.sign(v) - z_ss) * np.exp(-lam * t)  # closed form
    return np.trapezoid(lugre_friction(z, v, p) * v, t)


def test_lugre_passivity_bound_is_sharp():
    bound = lugre_passivity_bound(sigma2=0.4, fc=1.0, fs=1.5)
    assert bound == pytest.approx(0.8)
    storage0 = 1.5**2 / (2 * 1e5)  # sigma0 z0^2 / 2 at sigma0 z0 = fs
    # 5 x the bound: a fast velocity step returns more energy than was ever stored.
    active = _lugre(sigma1=5 * bound, check_passivity=False)
    assert _energy_after_step(active, 1e3, 1.0) < -10 * storage0
    # Even 1.2 x the bound is active (measured -6.7e-5 J against V(z0) = 1.1e-5 J).
    slightly = _lugre(sigma1=1.2 * bound, check_passivity=False)
    assert _energy_after_step(slightly, 1e3, 0.2) < -storage0
    # At the bound: supplied energy never falls below -V(z0), over a range of windows.
    passive = _lugre(sigma1=bound)
    for v in (1e-3, 0.05, 1e3):
        for c in (0.1, 1.0, 5.0):
            assert _energy_after_step(passive, v, c) >= -storage0 * (1 + 1e-6)


def test_lugre_dissipation_inequality_on_random_input():
    p = _lugre(sigma1=0.8)  # exactly at the bound
    rng = np.random.default_rng(3)
    freqs, amps, phases = (
        rng.uniform(0.5, 5, 4),
        rng.uniform(0.002, 0.05, 4),
        rng.uniform(0, 2 * np.pi, 4),
    )

    def vel(t):
        return np.sum(amps * np.sin(freqs * t + phases))

    def rhs(t, y):
        v = vel(t)
        return [lugre_state_derivative(y[0], v, p), lugre_friction(y[0], v, p) * v]

    def jac(t, y):
        v, a = vel(t), lugre_jacobian(y[0], vel(t), p)
        return [[a, 0.0], [v * (p.sigma0 + p.sigma1 * a), 0.0]]

    sol = solve_ivp(
        rhs, (0.0, 5.0), [0.0, 0.0], method="Radau", jac=jac, rtol=1e-9, atol=1e-13, max_step=5e-3
    )
    z, energy = sol.y
    storage = 0.5 * p.sigma0 * z**2
    # Dissipation inequality E(t) >= V(t) - V(0), V(0) = 0; slack for solver error 1e-9 J.
    assert np.all(energy - storage >= -1e-9)


def test_lugre_jacobian_matches_finite_difference():
    p = _lugre()
    z = np.linspace(-1.4e-5, 1.4e-5, 7)
    v = np.array([-0.3, -0.01, -1e-4, 0.0, 1e-4, 0.02, 0.5])
    h = 1e-12
    fd = (lugre_state_derivative(z + h, v, p) - lugre_state_derivative(z - h, v, p)) / (2 * h)
    # dz/dt is linear in z: central difference exact up to round-off (~1e-4/1e-12 * eps).
    np.testing.assert_allclose(lugre_jacobian(z, v, p), fd, rtol=1e-4, atol=1e-6)


# --- Dahl --------------------------------------------------------------------------------


@pytest.mark.parametrize("gamma", [0.5, 1.0, 2.0])
def test_dahl_jacobian_matches_finite_difference(gamma):
    p = DahlParams(k_s=1e3, mu_k=2.0, gamma=gamma, nu=0.1)
    f = np.array([-1.5, -0.3, 0.4, 1.2])
    v = np.array([0.2, -0.05, 0.1, -0.3])
    h = 1e-7
    fd = (dahl_state_derivative(f + h, v, p) - dahl_state_derivative(f - h, v, p)) / (2 * h)
    # Central difference error O(h^2 * third derivative) ~ 1e-11 relative; round-off
    # eps*|df/dt|/h ~ 1e-6 absolute dominates.
    np.testing.assert_allclose(dahl_jacobian(f, v, p), fd, rtol=1e-6, atol=1e-5)


def test_dahl_gamma2_equals_haessig_friedland_with_corrected_gamma_s():
    p = DahlParams(k_s=1e3, mu_k=2.0, gamma=2.0, nu=0.0)
    rng = np.random.default_rng(11)
    f = rng.uniform(-3.0, 3.0, 100)
    v = rng.normal(0.0, 1.0, 100)
    s = np.sign(v)
    u = 1.0 - s * f / p.mu_k
    rate = dahl_state_derivative(f, v, p)
    corrected = p.k_s * np.sign(u) / p.mu_k**2  # erratum of (2.18)
    printed = p.k_s * p.mu_k * np.sign(u)  # (2.18) as printed
    hf = v * (f - p.mu_k * s) ** 2  # (2.17) without gamma_s, f0 = mu_k
    np.testing.assert_allclose(rate, corrected * hf, rtol=1e-12, atol=1e-9)
    assert not np.allclose(rate, printed * hf)


def test_dahl_saturates_at_coulomb_level():
    p = DahlParams(k_s=1e4, mu_k=2.0, gamma=1.0, nu=0.3)
    sol = solve_ivp(
        lambda t, f: dahl_state_derivative(f, 0.1, p),
        (0, 0.1),
        [0.0],
        method="Radau",
        rtol=1e-10,
        atol=1e-12,
    )
    # Closed form f = mu_k (1 - exp(-k_s x/mu_k)), x = 0.01 m: exp(-50) is negligible.
    assert dahl_friction(sol.y[0, -1], 0.1, p) == pytest.approx(2.0 + 0.03, rel=1e-9)


# --- Canudas de Wit et al. (2.19)–(2.22) -------------------------------------------------

CAN = CanudasParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, memory=0.05, k_s=1e4, nu_s=1.0)


def test_canudas_memory_state_relaxes_to_gaussian_stribeck():
    v = 0.7
    sol = solve_ivp(
        lambda t, g: canudas_state_derivative(g, v, CAN),
        (0, 1.0),
        [0.0],
        method="Radau",
        jac=lambda t, g: np.atleast_2d(canudas_jacobian(g, v, CAN)),
        rtol=1e-10,
        atol=1e-12,
        dense_output=True,
    )
    t = np.linspace(0, 1.0, 30)
    g_ss = 1.0 - np.exp(-((v / CAN.v_s) ** 2))
    # Linear first-order ODE: closed form, solver rtol 1e-10.
    np.testing.assert_allclose(sol.sol(t)[0], g_ss * (1 - np.exp(-t / CAN.memory)), atol=1e-9)
    # Steady (2.19) is the Gaussian map (2.5) with delta = 2 (thesis below (2.20)).
    bp = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=2.0)
    assert canudas_friction(g_ss, v, CAN) == pytest.approx(bo_pavelescu_friction(v, bp), rel=1e-14)


def test_canudas_steady_form_2_21_matches_2_19_where_saturated_and_at_high_speed():
    v = np.array([-0.3, -0.05, 1e-3, 0.02, 0.4])
    g = 1.0 - np.exp(-((v / CAN.v_s) ** 2))
    steady_219 = canudas_friction(g, v, CAN)
    # Small |v|: the saturation is active and (2.21) equals (2.19) exactly (round-off).
    np.testing.assert_allclose(canudas_steady_friction(v, CAN), steady_219, rtol=1e-12)
    # High speed: the corrected first term gives mu_k sgn(v) + nu v, as (2.19) does.
    vh = np.array([-8.0, 8.0])
    np.testing.assert_allclose(
        canudas_steady_friction(vh, CAN), np.sign(vh) * 1.0 + 0.5 * vh, rtol=1e-12
    )  # 1 - g = e^-64: below round-off
    assert canudas_steady_friction(np.array([0.0]), CAN)[0] == 0.0


# --- Armstrong-Hélouvry (2.15) -----------------------------------------------------------

ARM = ArmstrongParams(
    mu_k=1.0, mu_s_a=1.0, mu_s_inf=3.0, nu=0.5, v_s=0.5, lag=0.0, gamma=2.0, k_s=1e4
)


def test_armstrong_sliding_without_stick_is_rising_lorentzian():
    v = np.linspace(-1.0, 1.0, 101)
    v = v[v != 0.0]
    f = armstrong_friction(v, np.zeros_like(v), 0.01, ARM)
    rp = RisingStribeckParams(mu_k=1.0, nu=0.5, v_s=0.5)
    # The first sample is never stuck: the rise starts at mu_s_a (t2 = 0).
    np.testing.assert_allclose(f, rising_lorentzian_friction(v, ARM.mu_s_a, rp), rtol=1e-14)


def test_armstrong_dwell_sets_rising_friction_and_presliding_spring():
    dt = 0.01
    n_stick = 150  # 1.5 s of stick
    v = np.concatenate([np.full(n_stick, 0.0), np.full(20, 0.2)])
    x = np.concatenate([np.linspace(0.0, 5e-4, n_stick), np.full(20, 5e-4)])
    f = armstrong_friction(v, x, dt, ARM)
    t2 = n_stick * dt
    rise = ARM.mu_s_a + (ARM.mu_s_inf - ARM.mu_s_a) * t2 / (ARM.gamma + t2)  # (2.7)
    expected = 1.0 + rise / (1.0 + (0.2 / 0.5) ** 2) + 0.5 * 0.2
    np.testing.assert_allclose(f[n_stick:], expected, rtol=1e-14)
    # Stuck: spring k_s x while below breakaway (x <= 1e-4 m -> 1 N), then saturated.
    small = x[:n_stick] * ARM.k_s < ARM.mu_k + ARM.mu_s_a
    np.testing.assert_allclose(f[:n_stick][small], ARM.k_s * x[:n_stick][small], rtol=1e-14)
    assert np.all(f[:n_stick] <= ARM.mu_k + ARM.mu_s_inf)


def test_armstrong_lag_acts_on_stribeck_velocity_only():
    p = ArmstrongParams(
        mu_k=1.0, mu_s_a=2.0, mu_s_inf=2.0, nu=0.5, v_s=0.5, lag=0.05, gamma=1.0, k_s=1e4
    )
    dt = 0.01
    v = np.concatenate([np.full(10, 0.1), np.full(20, 1.0)])
    f = armstrong_friction(v, np.zeros_like(v), dt, p)
    f_thesis = armstrong_friction(v, np.zeros_like(v), dt, p, form="thesis")
    # 3 samples after the step the lagged Stribeck velocity is still 0.1.
    expected = 1.0 + 2.0 / (1 + (0.1 / 0.5) ** 2) + 0.5 * 1.0
    assert f[12] == pytest.approx(expected, rel=1e-14)
    # Both forms agree once the lag has passed (steady velocity).
    np.testing.assert_allclose(f[-5:], f_thesis[-5:], rtol=1e-14)


# --- Error paths -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("factory", "match"),
    [
        (lambda: _lugre(sigma0=0.0), r"sigma0 must be finite and > 0"),
        (lambda: _lugre(sigma1=-1.0), r"sigma1 must be finite and >= 0"),
        (lambda: _lugre(sigma2=-0.1), r"sigma2 must be finite and >= 0"),
        (lambda: _lugre(fc=0.0), r"fc must be finite and > 0"),
        (lambda: _lugre(fc=2.0, fs=1.0), r"fs must be >= fc"),
        (lambda: _lugre(vs=0.0), r"vs must be finite and > 0.*got vs=0.0"),
        (lambda: _lugre(vs=-0.01), r"vs must be finite and > 0.*got vs=-0.01"),
        (lambda: _lugre(sigma1=0.81), r"sigma1 must be <= sigma2\*fc/\(fs - fc\)"),
        (lambda: _lugre(sigma1=1.0, sigma2=0.0), r"passive.*check_passivity=False"),
        (lambda: DahlParams(k_s=-1.0, mu_k=1.0, gamma=1.0, nu=0.0), "k_s must be"),
        (lambda: DahlParams(k_s=1.0, mu_k=-1.0, gamma=1.0, nu=0.0), "mu_k must be"),
        (lambda: DahlParams(k_s=1.0, mu_k=1.0, gamma=0.0, nu=0.0), "gamma must be"),
        (
            lambda: CanudasParams(
                mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, memory=0.0, k_s=1.0, nu_s=0.0
            ),
            "memory must be",
        ),
        (
            lambda: CanudasParams(
                mu_k=5.0, mu_s=4.0, nu=0.5, v_s=1.0, memory=1.0, k_s=1.0, nu_s=0.0
            ),
            "mu_s must be >= mu_k",
        ),
        (
            lambda: ArmstrongParams(
                mu_k=-1.0, mu_s_a=1.0, mu_s_inf=3.0, nu=0.5, v_s=0.5, lag=0.0, gamma=2.0, k_s=1e4
            ),
            "mu_k must be",
        ),
        (lambda: armstrong_friction([1.0, 2.0], [0.0], 0.1, ARM), "equal length"),
        (lambda: armstrong_friction([1.0], [0.0], 0.0, ARM), "dt must be"),
        (lambda: armstrong_friction([1.0], [0.0], 0.1, ARM, form="x"), "form must be"),
        (
            lambda: LuGreParams(sigma0="a", sigma1=0.0, sigma2=0.0, fc=1.0, fs=1.0, vs=1.0),
            "sigma0 must be a real number",
        ),
    ],
)
def test_bad_parameters_raise(factory, match):
    with pytest.raises(ParameterError, match=match):
        factory()


def test_passivity_opt_out_is_explicit():
    p = _lugre(sigma1=10.0, check_passivity=False)
    assert p.sigma1 == 10.0
    assert lugre_passivity_bound(sigma2=0.0, fc=1.0, fs=1.0) == np.inf


def test_lugre_friction_equals_substituted_form_2_25():
    p = _lugre()
    rng = np.random.default_rng(5)
    z = rng.uniform(-1.5e-5, 1.5e-5, 50)
    v = rng.normal(0.0, 0.05, 50)
    g_force = lugre_stribeck(v, p)
    zdot = lugre_state_derivative(z, v, p)
    f_225 = g_force * np.sign(v) + p.sigma2 * v + (p.sigma1 - g_force / np.abs(v)) * zdot
    # Algebraic identity; the 1/|v| factor amplifies round-off for small |v|: 1e-9 relative.
    np.testing.assert_allclose(lugre_friction(z, v, p), f_225, rtol=1e-9, atol=1e-12)
