"""Tests of driveid.models.compliance: modal summation, Rayleigh damping, shaft torsion."""

import numpy as np
import pytest
import scipy.linalg

from driveid.errors import ParameterError
from driveid.models import compliance as cp

# 3-DOF chain: wall - k1 - m1 - k2 - m2 - k3 - m3 (free end).
MASS = np.diag([2.0, 1.0, 0.5])
STIFF = np.array([[3000.0, -1000.0, 0.0], [-1000.0, 1800.0, -800.0], [0.0, -800.0, 800.0]])


def test_modal_matrices_are_diagonal_and_normalised():
    mm = cp.modal_analysis(MASS, STIFF)
    L = mm.modes_normalised
    np.testing.assert_allclose(L.T @ MASS @ L, np.eye(3), atol=1e-12)  # (2.83), rounding
    np.testing.assert_allclose(L.T @ STIFF @ L, np.diag(mm.omega**2), atol=1e-9)  # (2.84)
    g = mm.modes.T @ MASS @ mm.modes
    np.testing.assert_allclose(g, np.diag(mm.generalised_mass), atol=1e-12)  # (2.77)
    np.testing.assert_allclose(mm.generalised_stiffness / mm.generalised_mass, mm.omega**2,
                               rtol=1e-12)  # Rayleigh quotient of an exact mode
    # Erratum (2.81): dividing by m_ii instead of sqrt(m_ii) does not normalise.
    printed = mm.modes / mm.generalised_mass
    assert not np.allclose(np.diag(printed.T @ MASS @ printed), 1.0)
    a, b = 0.5, 2e-4
    C = cp.rayleigh_damping_matrix(MASS, STIFF, a, b)
    np.testing.assert_allclose(L.T @ C @ L, a * np.eye(3) + b * np.diag(mm.omega**2),
                               atol=1e-12)  # (2.90)


def test_rayleigh_zeta_matches_eigenvalues_of_full_system():
    mm = cp.modal_analysis(MASS, STIFF)
    alpha, beta = cp.rayleigh_coefficients((mm.omega[0], mm.omega[2]), (0.02, 0.05))
    zeta = cp.rayleigh_modal_damping(mm.omega, alpha, beta)
    C = cp.rayleigh_damping_matrix(MASS, STIFF, alpha, beta)
    lam = scipy.linalg.eigvals(STIFF, MASS)  # sanity: undamped
    np.testing.assert_allclose(np.sort(lam.real), mm.omega**2, rtol=1e-12)
    n = 3
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(MASS, STIFF), -np.linalg.solve(MASS, C)]])
    ev = np.linalg.eigvals(A)
    ev = ev[ev.imag > 0]
    ev = ev[np.argsort(np.abs(ev))]
    z_direct = -ev.real / np.abs(ev)
    print("zeta modal", zeta, "zeta from eigenvalues", z_direct)
    np.testing.assert_allclose(z_direct, zeta, rtol=1e-10)  # eigvals rounding
    np.testing.assert_allclose(np.abs(ev), mm.omega, rtol=1e-10)


def test_modal_frequency_response_matches_direct_solution():
    mm = cp.modal_analysis(MASS, STIFF)
    alpha, beta = 0.8, 3e-4
    C = cp.rayleigh_damping_matrix(MASS, STIFF, alpha, beta)
    zeta = cp.rayleigh_modal_damping(mm.omega, alpha, beta)
    w = np.linspace(1.0, 80.0, 300)
    f = np.array([0.0, 1.0, 0.3])
    h_modal = cp.modal_frequency_response(mm, zeta, w, f)
    h_direct = np.array([np.linalg.solve(STIFF - wi**2 * MASS + 1j * wi * C, f) for wi in w])
    err = np.max(np.abs(h_modal - h_direct)) / np.max(np.abs(h_direct))
    print(f"modal vs direct FRF: max error relative to peak {err:.1e}")
    assert err < 1e-10  # both exact; only rounding differs


def test_modal_free_response_matches_matrix_exponential():
    mm = cp.modal_analysis(MASS, STIFF)
    alpha, beta = 0.8, 3e-4
    C = cp.rayleigh_damping_matrix(MASS, STIFF, alpha, beta)
    zeta = cp.rayleigh_modal_damping(mm.omega, alpha, beta)
    x0, v0 = np.array([0.01, -0.02, 0.005]), np.array([0.0, 0.3, -0.1])
    t = np.linspace(0.0, 2.0, 41)
    x_modal = cp.modal_free_response(mm, zeta, t, x0, v0)
    n = 3
    A = np.block([[np.zeros((n, n)), np.eye(n)],
                  [-np.linalg.solve(MASS, STIFF), -np.linalg.solve(MASS, C)]])
    y0 = np.concatenate([x0, v0])
    x_direct = np.array([(scipy.linalg.expm(A * ti) @ y0)[:n] for ti in t])
    err = np.max(np.abs(x_modal - x_direct))
    print(f"modal vs expm free response: max error {err:.1e} m")
    assert err < 1e-12  # exact vs expm (Padé, ~1e-15 relative)


def test_participation_factors_and_modal_force():
    mm = cp.modal_analysis(MASS, STIFF)
    gamma = np.array([0.2, 0.3, 0.5])
    pf = cp.participation_factors(mm, gamma)
    np.testing.assert_allclose(cp.modal_force(mm, gamma * 7.0), 7.0 * pf, rtol=1e-14)  # (2.100)
    np.testing.assert_allclose(cp.participation_factors(mm), mm.modes_normalised.sum(axis=0))
    with pytest.raises(ParameterError, match=r"shares must be in \[0, 1\].*got 1.5"):
        cp.participation_factors(mm, [1.5, 0.0, 0.0])
    with pytest.raises(ParameterError, match=r"must have shape \(3,\)"):
        cp.participation_factors(mm, [0.5, 0.5])


def test_peak_deflection():
    # |1*2| + sqrt((0.5*6)^2 + (0.5*8)^2) = 2 + 5
    assert cp.peak_deflection([1.0, -0.5, 0.5], [2.0, 6.0, 8.0]) == pytest.approx(7.0)
    assert cp.peak_deflection([2.0], [1.5]) == 3.0


# Timoshenko & Goodier, Theory of Elasticity, Table 109 (k1 in K = k1 a^3 b).
TIMOSHENKO_K1 = {1.0: 0.141, 1.5: 0.196, 2.0: 0.229, 3.0: 0.263, 5.0: 0.291, 10.0: 0.312}


@pytest.mark.parametrize(("ratio", "k1"), sorted(TIMOSHENKO_K1.items()))
def test_torsion_series_matches_published_table(ratio, k1):
    k = cp.rectangular_torsion_constant(1.0, ratio) / ratio
    assert k == pytest.approx(k1, abs=5e-4)  # table printed to 3 decimals


@pytest.mark.parametrize("ratio", [3.0, 3.5, 4.0, 6.25, 10.0, 100.0])
def test_torsion_approx_agrees_with_series_to_four_figures(ratio):
    a = 0.004
    series = cp.rectangular_torsion_constant(a, ratio * a)
    approx = cp.rectangular_torsion_constant_approx(a, ratio * a)
    rel = abs(approx / series - 1)
    print(f"b/a={ratio}: series {series:.6e}, approx {approx:.6e}, rel diff {rel:.1e}")
    assert rel < 5e-4  # "four significant figures" (2.115)


def test_wave_speed_at_test_bed_ratio_is_about_0_3():
    # (2.124)-(2.125): alpha^2 = (G/rho) * K_p/I_p ~ 0.3^2 G/rho at b = 6.25 a.
    G, rho, a = 80e9, 7850.0, 0.004
    circ = np.sqrt(G / rho)
    for exact in (False, True):
        bar = cp.RectangularShaft(a=a, b=6.25 * a, length=0.3, G=G, rho=rho, exact=exact)
        ratio = bar.wave_speed / circ
        print(f"exact={exact}: alpha/sqrt(G/rho) = {ratio:.5f}")
        assert round(ratio, 1) == 0.3  # the thesis's "0.3^2"
        assert ratio < 1 / 3  # "just under a third the speed" of a circular rod
    formula = 4 * (6.25 - 0.630) / (6.25 * (1 + 6.25**2))  # (2.124) with a = 1
    assert (bar.wave_speed / circ) ** 2 == pytest.approx(formula, rel=5e-4)  # K_p series/approx
    shaft = cp.CircularShaft(diameter=0.02, length=0.3, G=G, rho=rho)
    assert shaft.wave_speed == pytest.approx(circ, rel=1e-15)  # K_p = I_p cancels (2.122)
    assert shaft.stiffness == pytest.approx(G * np.pi * 0.02**4 / 32 / 0.3, rel=1e-15)


def _fd_modes(boundary, n_modes, alpha, length, n=400):
    """Finite-difference eigenvalues of theta_tt = alpha^2 theta_xx (fixed at x = 0).

    Central differences on n cells; a free end x = l gets a half-cell lumped inertia,
    which keeps the matrix symmetric after scaling by M^-1/2.
    """
    h = length / n
    m = n - 1 if boundary == "fixed-fixed" else n
    d = 2.0 * np.ones(m)
    e = -np.ones(m - 1)
    if boundary == "fixed-free":
        d[-1] = 2.0  # stiffness 1 scaled by the inverse half inertia 2
        e[-1] *= np.sqrt(2.0)
    lam = scipy.linalg.eigh_tridiagonal(d * alpha**2 / h**2, e * alpha**2 / h**2,
                                        eigvals_only=True, select="i",
                                        select_range=(0, n_modes - 1))
    return np.sqrt(lam)


@pytest.mark.parametrize("boundary", ["fixed-free", "fixed-fixed"])
def test_shaft_modes_match_finite_differences(boundary):
    bar = cp.RectangularShaft(a=0.004, b=0.025, length=0.3, G=80e9, rho=7850.0)
    w = bar.natural_frequencies(3, boundary)
    w_fd = _fd_modes(boundary, 3, bar.wave_speed, bar.length)
    rel = np.abs(w_fd / w - 1)
    print(f"{boundary}: analytic {w} rad/s, FD {w_fd}, rel diff {rel}")
    assert np.all(rel < 1e-3)  # brief: 0.1 %; FD error ~ (n pi h/l)^2/24 ~ 1e-4 at n = 3


def test_fixed_fixed_double_only_for_fundamental():
    ff = cp.shaft_natural_frequencies(1.0, 1.0, 3, "fixed-free")
    fx = cp.shaft_natural_frequencies(1.0, 1.0, 3, "fixed-fixed")
    np.testing.assert_allclose(fx / ff, [2.0, 4 / 3, 6 / 5], rtol=1e-15)
    x = np.linspace(0, 1, 5)
    assert cp.shaft_mode_shape(0.0, 2, 1.0) == 0.0
    np.testing.assert_allclose(cp.shaft_mode_shape(x, 1, 1.0, "fixed-fixed"), np.sin(np.pi * x))


def test_shear_modulus_and_moments():
    assert cp.shear_modulus(210e9, 0.3) == pytest.approx(80.769e9, rel=1e-4)
    assert cp.rectangular_polar_moment(1.0, 2.0) == pytest.approx(2 * 5 / 12)
    assert cp.torsional_stiffness(1.0, 2.0, 4.0) == 0.5


def test_bad_parameters():
    with pytest.raises(ParameterError, match=r"diameter must be positive.*got -0.01"):
        cp.CircularShaft(diameter=-0.01, length=1.0, G=1.0, rho=1.0)
    with pytest.raises(ParameterError, match="a must be the shorter side"):
        cp.RectangularShaft(a=0.02, b=0.01, length=1.0, G=1.0, rho=1.0)
    with pytest.raises(ParameterError, match=r"rho must be positive.*got 0.0"):
        cp.RectangularShaft(a=0.01, b=0.02, length=1.0, G=1.0, rho=0.0)
    with pytest.raises(ParameterError, match=r"poisson must be in \(-1, 0.5\].*got 0.7"):
        cp.shear_modulus(1e9, 0.7)
    with pytest.raises(ParameterError, match="boundary must be one of"):
        cp.shaft_natural_frequencies(1.0, 1.0, 2, "free-free")
    with pytest.raises(ParameterError, match="n_modes must be >= 1"):
        cp.shaft_natural_frequencies(1.0, 1.0, 0)
    with pytest.raises(ParameterError, match="mode must be >= 1"):
        cp.shaft_mode_shape(0.1, 0, 1.0)
    with pytest.raises(ParameterError, match="M must be symmetric"):
        cp.modal_analysis([[1.0, 0.1], [0.0, 1.0]], np.eye(2))
    with pytest.raises(ParameterError, match=r"K must be a \(2, 2\) matrix"):
        cp.modal_analysis(np.eye(2), np.eye(3))
    with pytest.raises(ParameterError, match="M must be positive definite"):
        cp.modal_analysis(-np.eye(2), np.eye(2))
    with pytest.raises(ParameterError, match="M must be finite"):
        cp.modal_analysis([[np.nan, 0], [0, 1]], np.eye(2))
    mm = cp.modal_analysis(MASS, STIFF)
    with pytest.raises(ParameterError, match=r"zeta must be in \[0, 1\).*got 1.2"):
        cp.modal_frequency_response(mm, 1.2, [1.0], [1.0, 0, 0])
    with pytest.raises(ParameterError, match="distinct frequencies"):
        cp.rayleigh_coefficients((1.0, 1.0), (0.1, 0.1))
    with pytest.raises(ParameterError, match="omega must be positive"):
        cp.rayleigh_modal_damping(0.0, 1.0, 1.0)
    with pytest.raises(ParameterError, match="must be 1-D, non-empty"):
        cp.peak_deflection([], [])
