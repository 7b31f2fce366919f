"""Tests of the static friction maps, de Marchi (1998) Eqs. (2.1)–(2.14), (2.155)."""

import functools

import numpy as np
import pytest

from driveid.errors import ParameterError
from driveid.models.friction import (
    STATIC_MAPS,
    BoPavelescuParams,
    CoulombViscousParams,
    HessSoomParams,
    LorentzianParams,
    asymmetric_friction,
    bo_pavelescu_friction,
    coulomb_viscous_friction,
    hess_soom_friction,
    hess_soom_from_lorentzian,
    lorentzian_friction,
    modified_stribeck_parameter,
)
from driveid.models.friction_memory import (
    ArmstrongRisingParams,
    KatoRisingParams,
    PreslidingParams,
    RisingStribeckParams,
    lag_signal,
    lagged_friction,
    presliding_friction,
    presliding_stiffness,
    rising_gaussian_friction,
    rising_lorentzian_friction,
    rising_static_friction_armstrong,
    rising_static_friction_kato,
)

# Figure 2.1 parameters of the thesis.
LOR = LorentzianParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0)
V = np.concatenate([-np.logspace(-3, 1, 40)[::-1], [0.0], np.logspace(-3, 1, 40)])
# Floating-point round-off of a few operations on O(10) values.
RTOL = 1e-12


# --- Coulomb + viscous (2.155) -----------------------------------------------------------


def test_coulomb_viscous_closed_form_and_sign_convention():
    p = CoulombViscousParams(fk_mean=2.0, fk_delta=0.5, c_mean=1.0, c_delta=0.25)
    v = np.array([-2.0, -0.1, 0.0, 0.1, 2.0])
    s = np.sign(v)
    expected = np.where(v == 0, 0.0, 2.0 * s + 0.5 + (1.0 + 0.25 * s) * v)
    np.testing.assert_allclose(coulomb_viscous_friction(v, p), expected, rtol=RTOL)
    # Friction resists motion in both directions.
    f = coulomb_viscous_friction(v, p)
    assert np.all(f * v >= 0.0)


def test_coulomb_viscous_delta_zero_is_odd():
    p = CoulombViscousParams(fk_mean=2.0, fk_delta=0.0, c_mean=1.0, c_delta=0.0)
    np.testing.assert_allclose(
        coulomb_viscous_friction(V, p), -coulomb_viscous_friction(-V, p), rtol=RTOL
    )


def test_coulomb_viscous_equals_two_one_sided_maps():
    # Independent route: (2.3) with mu_s = mu_k is Coulomb + viscous on each side.
    p = CoulombViscousParams.from_sides(fk_plus=3.0, fk_minus=1.0, c_plus=0.7, c_minus=0.2)
    plus = LorentzianParams(mu_k=3.0, mu_s=3.0, nu=0.7, v_s=1.0)
    minus = LorentzianParams(mu_k=1.0, mu_s=1.0, nu=0.2, v_s=1.0)
    np.testing.assert_allclose(
        coulomb_viscous_friction(V, p),
        asymmetric_friction(V, lorentzian_friction, plus=plus, minus=minus),
        rtol=RTOL,
        atol=1e-15,
    )


# --- Stribeck maps (2.1)–(2.5) -----------------------------------------------------------


@pytest.mark.parametrize(
    ("fn", "params"),
    [
        (lorentzian_friction, LOR),
        (bo_pavelescu_friction, BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=1.3)),
        (
            hess_soom_friction,
            HessSoomParams(mu_s=4.0, c1=2.0, c2=0.5, eta=1.0, W=3.0, E=10.0, l=1.0),
        ),
    ],
)
def test_asymmetric_with_equal_sides_is_symmetric_map(fn, params):
    sym = fn(V, params)
    np.testing.assert_array_equal(asymmetric_friction(V, fn, plus=params, minus=params), sym)
    np.testing.assert_allclose(sym, -fn(-V, params), rtol=RTOL)
    assert fn(np.array([0.0]), params)[0] == 0.0


def test_lorentzian_landmarks():
    # Thesis footnote 49: at v = v_s the Stribeck part is the mean of mu_s and mu_k.
    f = lorentzian_friction(np.array([LOR.v_s, 1e-9]), LOR)
    assert f[0] == pytest.approx(0.5 * (LOR.mu_s + LOR.mu_k) + LOR.nu * LOR.v_s, rel=RTOL)
    # v -> 0+: static friction (error O(v) from the viscous term, 1e-9 here).
    assert f[1] == pytest.approx(LOR.mu_s, abs=1e-8)


def test_hess_soom_with_eq_2_4_equals_lorentzian_without_kinetic_level():
    lor0 = LorentzianParams(mu_k=0.0, mu_s=4.0, nu=0.5, v_s=0.3)
    for eta, W, E, l in [(1.0, 1.0, 10.0, 1.0), (0.02, 50.0, 2e9, 0.01), (3.0, 0.5, 7.0, 2.0)]:
        hs = hess_soom_from_lorentzian(lor0, eta=eta, W=W, E=E, l=l)
        np.testing.assert_allclose(
            hess_soom_friction(V, hs), lorentzian_friction(V, lor0), rtol=1e-10
        )  # c1, c2 pass through products of widely scaled numbers: allow 1e-10.


def test_modified_stribeck_parameter_closed_form():
    assert modified_stribeck_parameter(3.0, eta=2.0, W=4.0, E=9.0) == pytest.approx(1.0)


def test_gaussian_bo_pavelescu_agrees_with_lorentzian_to_first_order():
    # e^{-y} - 1/(1+y) = -y^2/2 + O(y^3) with y = (v/v_s)^2: the thesis's "first-order
    # approximation" statement under (2.5).
    bp = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=2.0)
    v = np.array([1e-2, 2e-2, 4e-2])
    y = v**2
    diff = bo_pavelescu_friction(v, bp) - lorentzian_friction(v, LOR)
    np.testing.assert_allclose(diff / y**2, -0.5 * (LOR.mu_s - LOR.mu_k), rtol=1e-2)
    # rtol 1e-2: the O(y^3) remainder relative to y^2 is at most ~y = 1.6e-3 here.


# --- Rising friction (2.6)–(2.11) --------------------------------------------------------


def test_rising_maps_collapse_with_eq_2_11():
    rp = RisingStribeckParams(mu_k=1.0, nu=0.5, v_s=1.0)
    rise = LOR.mu_s - LOR.mu_k  # (2.11)
    np.testing.assert_allclose(
        rising_lorentzian_friction(V, rise, rp), lorentzian_friction(V, LOR), rtol=RTOL
    )
    bp2 = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=2.0)
    np.testing.assert_allclose(
        rising_gaussian_friction(V, rise, rp), bo_pavelescu_friction(V, bp2), rtol=RTOL
    )
    # ... but only for delta = 2, since (2.10) fixes the exponent.
    bp1 = BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=1.0)
    assert not np.allclose(rising_gaussian_friction(V, rise, rp), bo_pavelescu_friction(V, bp1))


def test_kato_and_armstrong_rising_limits_and_initial_slope():
    kato = KatoRisingParams(mu_k=1.0, mu_inf=4.0, gamma=1.0, kappa=1.0)
    arm = ArmstrongRisingParams(mu_inf=4.0, gamma=1.0)
    t = np.array([0.0, 1e3 * 1e3])
    np.testing.assert_allclose(rising_static_friction_kato(t, kato), [1.0, 4.0], rtol=RTOL)
    # (2.7) approaches mu_inf like gamma/t: 1e-6 relative at t = 1e6 s.
    np.testing.assert_allclose(rising_static_friction_armstrong(t, 1.0, arm), [1.0, 4.0], rtol=1e-5)
    np.testing.assert_allclose(
        rising_static_friction_armstrong(t, 1.0, arm, form="exponential"), [1.0, 4.0], rtol=1e-5
    )
    # (2.7) is a first-order approximation of (2.6) with kappa = 1, mu_start = mu_k.
    h = 1e-6
    slope_kato = (rising_static_friction_kato(h, kato) - 1.0) / h
    slope_arm = (rising_static_friction_armstrong(h, 1.0, arm) - 1.0) / h
    expected = (kato.mu_inf - kato.mu_k) / kato.gamma
    # Forward difference error ~ h * curvature = 3e-6 relative.
    assert slope_kato == pytest.approx(expected, rel=1e-5)
    assert slope_arm == pytest.approx(expected, rel=1e-5)


# --- Frictional memory (2.12) ------------------------------------------------------------


def test_lag_integer_and_fractional_shift_are_exact_where_interpolation_is():
    dt = 0.01
    t = np.arange(200) * dt
    ramp = 2.0 * t + 1.0
    lagged = lag_signal(ramp, dt, 0.033)
    # Linear interpolation is exact on a ramp; before t = lag the first value is held.
    np.testing.assert_allclose(lagged[4:], 2.0 * (t[4:] - 0.033) + 1.0, rtol=RTOL)
    np.testing.assert_array_equal(lagged[:3], ramp[0])
    np.testing.assert_array_equal(lag_signal(ramp, dt, 5 * dt)[5:], ramp[:-5])


def test_lagged_friction_on_sinusoid_matches_closed_form():
    dt, lag, w = 1e-3, 0.2, 2.0
    t = np.arange(6000) * dt
    v = 3.0 * np.sin(w * t)
    fmap = functools.partial(lorentzian_friction, params=LOR)
    got = lagged_friction(v, dt, lag=lag, friction=fmap)
    truth = fmap(3.0 * np.sin(w * (t - lag)))
    ok = (t >= lag) & (np.abs(3.0 * np.sin(w * (t - lag))) > 0.05)  # away from the sgn jump
    # Interpolation error <= dt^2/8 * max|v''| = 1.5e-6 m/s, times max|dF/dv| <= 6.5.
    np.testing.assert_allclose(got[ok], truth[ok], atol=1e-5)


# --- Presliding (2.13)–(2.14) ------------------------------------------------------------


def test_presliding_spring_and_breakaway():
    p = PreslidingParams(k_s=1e4, fs_plus=4.0, fs_minus=2.0)
    x = np.array([-1e-3, -1e-4, 0.0, 2e-4, 1e-3])
    np.testing.assert_allclose(presliding_friction(x, p), [-2.0, -1.0, 0.0, 2.0, 4.0], rtol=RTOL)
    k = presliding_stiffness(fs_plus=4.0, fs_minus=-2.0, x_plus=4e-4, x_minus=-2e-4)
    assert k == pytest.approx(1e4, rel=RTOL)


def test_static_map_registry_is_callable():
    examples = {
        "coulomb_viscous": dict(fk_mean=1.0, fk_delta=0.0, c_mean=0.1, c_delta=0.0),
        "lorentzian": dict(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0),
        "bo_pavelescu": dict(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=2.0),
        "hess_soom": dict(mu_s=4.0, c1=1.0, c2=0.5, eta=1.0, W=1.0, E=10.0, l=1.0),
    }
    assert set(STATIC_MAPS) == set(examples)
    for name, (fn, cls) in STATIC_MAPS.items():
        f = fn(V, cls(**examples[name]))
        assert f.shape == V.shape and np.all(f * V >= 0.0)


# --- Error paths -------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("factory", "match"),
    [
        (lambda: LorentzianParams(mu_k=-1.0, mu_s=4.0, nu=0.5, v_s=1.0), "mu_k must be >= 0"),
        (lambda: LorentzianParams(mu_k=2.0, mu_s=1.0, nu=0.5, v_s=1.0), "mu_s must be >= mu_k"),
        (lambda: LorentzianParams(mu_k=1.0, mu_s=4.0, nu=-0.5, v_s=1.0), "nu must be >= 0"),
        (lambda: LorentzianParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=0.0), "v_s must be > 0"),
        (lambda: LorentzianParams(mu_k=1.0, mu_s=np.nan, nu=0.5, v_s=1.0), "mu_s must be finite"),
        (
            lambda: BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=0.0),
            r"delta must be > 0.*got delta=0.0",
        ),
        (
            lambda: BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=1.0, delta=-1.0),
            r"delta must be > 0.*got delta=-1.0",
        ),
        (
            lambda: BoPavelescuParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=-1.0, delta=2.0),
            "v_s must be > 0",
        ),
        (
            lambda: CoulombViscousParams(fk_mean=-1.0, fk_delta=0.0, c_mean=0.0, c_delta=0.0),
            "fk_mean must be >= 0",
        ),
        (
            lambda: CoulombViscousParams(fk_mean=1.0, fk_delta=1.5, c_mean=0.0, c_delta=0.0),
            "fk_delta must be within",
        ),
        (
            lambda: CoulombViscousParams(fk_mean=1.0, fk_delta=0.0, c_mean=1.0, c_delta=-2.0),
            "c_delta must be within",
        ),
        (
            lambda: CoulombViscousParams(fk_mean="a", fk_delta=0.0, c_mean=1.0, c_delta=0.0),
            "fk_mean must be a real number",
        ),
        (
            lambda: HessSoomParams(mu_s=4.0, c1=1.0, c2=0.5, eta=1.0, W=-1.0, E=10.0, l=1.0),
            "W must be > 0",
        ),
        (
            lambda: hess_soom_from_lorentzian(LOR, eta=1.0, W=1.0, E=1.0, l=1.0),
            "mu_k must be 0",
        ),
        (lambda: KatoRisingParams(mu_k=1.0, mu_inf=4.0, gamma=1.0, kappa=0.0), "kappa must be"),
        (lambda: ArmstrongRisingParams(mu_inf=4.0, gamma=-1.0), "gamma must be > 0"),
        (
            lambda: rising_static_friction_kato(
                -1.0, KatoRisingParams(mu_k=1.0, mu_inf=4.0, gamma=1.0, kappa=1.0)
            ),
            "t_dwell must be finite and >= 0",
        ),
        (
            lambda: rising_static_friction_armstrong(
                1.0, 1.0, ArmstrongRisingParams(mu_inf=4.0, gamma=1.0), form="cubic"
            ),
            "form must be",
        ),
        (
            lambda: rising_lorentzian_friction(
                1.0, -1.0, RisingStribeckParams(mu_k=1.0, nu=0.0, v_s=1.0)
            ),
            "mu_rise must be >= 0",
        ),
        (lambda: lag_signal([1.0, 2.0], 0.0, 0.1), "dt must be > 0"),
        (lambda: lag_signal([1.0, 2.0], 0.1, -0.1), "lag must be >= 0"),
        (lambda: lag_signal([[1.0, 2.0]], 0.1, 0.1), "one-dimensional"),
        (lambda: PreslidingParams(k_s=0.0, fs_plus=1.0, fs_minus=1.0), "k_s must be > 0"),
        (
            lambda: presliding_stiffness(fs_plus=1.0, fs_minus=-1.0, x_plus=-1.0, x_minus=1.0),
            "x_plus must be > x_minus",
        ),
        (
            lambda: presliding_stiffness(fs_plus=-1.0, fs_minus=1.0, x_plus=1.0, x_minus=-1.0),
            "k_s must be > 0",
        ),
        (lambda: modified_stribeck_parameter(1.0, eta=0.0, W=1.0, E=1.0), "eta must be > 0"),
    ],
)
def test_bad_parameters_raise(factory, match):
    with pytest.raises(ParameterError, match=match):
        factory()


def test_parameter_error_message_ends_with_value():
    with pytest.raises(ParameterError, match=r"; got v_s=-2\.0$"):
        LorentzianParams(mu_k=1.0, mu_s=4.0, nu=0.5, v_s=-2.0)


def test_params_are_frozen_and_keyword_only():
    with pytest.raises(TypeError):
        LorentzianParams(1.0, 4.0, 0.5, 1.0)  # positional
    with pytest.raises(AttributeError):
        LOR.mu_k = 2.0  # frozen
