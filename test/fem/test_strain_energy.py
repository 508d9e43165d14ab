"""
The finite-strain energy of the beam against an independent derivation from Eq. 14-16.

sympy builds the 3D displacement field of the cross-section, differentiates it, forms the
Green-Lagrange strains and the energy density; the density is integrated numerically over
the annulus (polar Gauss rule, exact for these polynomials). The model's closed form must
agree to rounding, for any twist theta_x.
"""
from __future__ import annotations

import functools

import numpy as np
import pytest
import sympy as sp

from drill_twin.fem import strain_energy as se

E, KG = 210e9, 0.857 * 81.4e9
R_OUT, R_IN = 0.0635, 0.0475


@functools.lru_cache(maxsize=None)
def _energy_density_3d(paper_eq15: bool):
    """Lambdified pointwise energy density e(g, theta_x, y, z) and its gradient in g."""
    x, y, z = sp.symbols('x y z', real=True)
    names = ('u', 'v', 'w', 'tx', 'ty', 'tz')
    f = {n: sp.Function(n)(x) for n in names}
    if paper_eq15:
        ux = f['u'] - y * f['tz'] + z * f['ty']
    else:
        yr = y * sp.cos(f['tx']) - z * sp.sin(f['tx'])
        zr = y * sp.sin(f['tx']) + z * sp.cos(f['tx'])
        ux = f['u'] - f['tz'] * yr + f['ty'] * zr
    uy = f['v'] + y * (sp.cos(f['tx']) - 1) - z * sp.sin(f['tx'])
    uz = f['w'] + z * (sp.cos(f['tx']) - 1) + y * sp.sin(f['tx'])
    d = sp.diff
    exx = d(ux, x) + (d(ux, x) ** 2 + d(uy, x) ** 2 + d(uz, x) ** 2) / 2
    gxy = d(uy, x) + d(ux, y) + d(ux, x) * d(ux, y) + d(uy, x) * d(uy, y) + d(uz, x) * d(uz, y)
    gxz = d(uz, x) + d(ux, z) + d(ux, x) * d(ux, z) + d(uy, x) * d(uy, z) + d(uz, x) * d(uz, z)
    density = sp.Rational(1, 2) * (E * exx ** 2 + KG * (gxy ** 2 + gxz ** 2))
    g = sp.symbols('e a b ky kz tau thy thz', real=True)
    theta_x = sp.Symbol('theta_x', real=True)
    replace = {d(f['u'], x): g[0], d(f['v'], x): g[1], d(f['w'], x): g[2],
               d(f['ty'], x): g[3], d(f['tz'], x): g[4], d(f['tx'], x): g[5]}
    density = density.subs(replace).subs({f['ty']: g[6], f['tz']: g[7], f['tx']: theta_x})
    gradient = [sp.diff(density, gi) for gi in g]
    args = (g, theta_x, y, z)
    return sp.lambdify(args, density, 'numpy'), sp.lambdify(args, gradient, 'numpy')


def _section_integral(function, g, theta_x):
    """Integrate a pointwise function over the annulus R_IN < r < R_OUT."""
    radial, weights = np.polynomial.legendre.leggauss(6)
    r = 0.5 * (R_OUT - R_IN) * radial + 0.5 * (R_OUT + R_IN)
    wr = 0.5 * (R_OUT - R_IN) * weights * r
    angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
    rr, aa = np.meshgrid(r, angles, indexing='ij')
    ww = np.repeat(wr[:, None], angles.size, axis=1) * (2 * np.pi / angles.size)
    values = function(tuple(g), theta_x, rr * np.cos(aa), rr * np.sin(aa))
    if isinstance(values, list):
        return np.array([np.sum(np.broadcast_to(v, ww.shape) * ww) for v in values])
    return np.sum(values * ww)


def _section():
    area = np.pi * (R_OUT ** 2 - R_IN ** 2)
    inertia = np.pi * (R_OUT ** 4 - R_IN ** 4) / 4
    fourth = np.pi * (R_OUT ** 6 - R_IN ** 6) / 24
    return se.SectionStiffness(EA=np.array(E * area), EI=np.array(E * inertia),
                               ER4=np.array(E * fourth), kGA=np.array(KG * area),
                               kGI=np.array(KG * inertia))


def _random_strains(rng, scale):
    # Curvatures and twist rates (1/m) scaled so that every term matters at the radius.
    return rng.normal(size=8) * scale * np.array([1, 1, 1, 1 / R_OUT, 1 / R_OUT,
                                                  1 / R_OUT, 1, 1])


@pytest.mark.parametrize('seed', range(4))
def test_energy_and_stresses_match_the_3d_derivation(seed):
    rng = np.random.default_rng(seed)
    density, gradient = _energy_density_3d(paper_eq15=False)
    section = _section()
    g = _random_strains(rng, 0.05)
    for theta_x in (0.0, 1.3, -7.9, 1e3):
        expected_w = _section_integral(density, g, theta_x)
        expected_s = _section_integral(gradient, g, theta_x)
        np.testing.assert_allclose(se.energy_density(g, section), expected_w, rtol=1e-11)
        np.testing.assert_allclose(se.stress_resultants(g, section), expected_s,
                                   rtol=1e-9, atol=1e-9 * np.max(np.abs(expected_s)))


def test_agrees_with_the_printed_eq15_where_it_should():
    """
    Eq. 15 as printed and the kinematics used here agree where the section is not twisted.

    They give the same energy when the section is not twisted (theta_x = theta_x' = 0), and the
    same tangent (so the same [K] and [K_g]) about an axial prestress; they differ only in the
    twist-bending products of f_se.
    """
    rng = np.random.default_rng(7)
    ours, ours_gradient = _energy_density_3d(paper_eq15=False)
    paper, paper_gradient = _energy_density_3d(paper_eq15=True)
    for _ in range(3):
        g = _random_strains(rng, 0.05)
        g[se.TAU] = 0.0
        np.testing.assert_allclose(_section_integral(paper, g, 0.0),
                                   _section_integral(ours, g, 0.0), rtol=1e-12)
    prestrain = np.zeros(8)
    prestrain[se.E_AXIAL] = 4e-4
    steps = 1e-7 * np.array([1, 1, 1, 1 / R_OUT, 1 / R_OUT, 1 / R_OUT, 1, 1])
    for gradient in (ours_gradient, paper_gradient):
        columns = [(_section_integral(gradient, prestrain + h * unit, 0.0)
                    - _section_integral(gradient, prestrain - h * unit, 0.0)) / (2 * h)
                   for h, unit in zip(steps, np.eye(8))]
        if gradient is ours_gradient:
            ours_tangent = np.array(columns).T
        else:
            paper_tangent = np.array(columns).T
    scale = np.abs(ours_tangent).max()
    np.testing.assert_allclose(ours_tangent, paper_tangent, atol=1e-7 * scale)
    np.testing.assert_allclose(se.tangent_stiffness(prestrain, _section()), ours_tangent,
                               rtol=1e-6, atol=1e-7 * scale)


def test_printed_eq15_is_not_invariant_under_rigid_rotation():
    """
    Why Eq. 15 is not taken literally.

    A bent, shear-free beam spun rigidly about its axis would store energy that depends on the
    spin angle (docs/MODEL-CHOICES.md).
    """
    paper, _ = _energy_density_3d(paper_eq15=True)
    ours, _ = _energy_density_3d(paper_eq15=False)
    slope = 1e-3
    g = np.array([0, slope, 0, 0, 0, 0, 0, slope])      # v' = theta_z: bending, no shear
    energies_paper = [_section_integral(paper, g, a) for a in (0.0, 0.5, 1.0, 2.0)]
    energies_ours = [_section_integral(ours, g, a) for a in (0.0, 0.5, 1.0, 2.0)]
    assert np.ptp(energies_ours) < 1e-9 * max(energies_ours[0], 1.0)
    assert np.ptp(energies_paper) > 1e3 * (np.ptp(energies_ours) + 1e-12)


def test_linear_part_is_the_timoshenko_beam():
    s = _section()
    tangent = se.tangent_stiffness(np.zeros(8), s)
    expected = np.zeros((8, 8))
    expected[se.E_AXIAL, se.E_AXIAL] = s.EA
    expected[se.KAPPA_Y, se.KAPPA_Y] = expected[se.KAPPA_Z, se.KAPPA_Z] = s.EI
    expected[se.TAU, se.TAU] = 2 * s.kGI                  # k_s G I_p (MODEL.md point 1)
    for slope, rotation, sign in ((se.A_SLOPE_V, se.THETA_Z, -1), (se.B_SLOPE_W, se.THETA_Y, 1)):
        expected[slope, slope] = expected[rotation, rotation] = s.kGA
        expected[slope, rotation] = expected[rotation, slope] = sign * s.kGA
    np.testing.assert_allclose(tangent, expected, rtol=1e-12, atol=1e-6)


def test_geometric_stiffness_terms_of_an_axial_prestress():
    """
    Geometric stiffness of an axial prestress N = EA e0 (MODEL.md point 3).

    3N on u' and the bending rotations, N on v'^2 and w'^2, N I_p/A on theta_x'^2 (N = EA e0),
    to first order in the prestrain e0.
    """
    s = _section()
    e0 = 1e-6
    n = float(s.EA) * e0
    strain = np.zeros(8)
    strain[se.E_AXIAL] = e0
    geometric = se.tangent_stiffness(strain, s) - se.tangent_stiffness(np.zeros(8), s)
    ratio = float(s.EI / s.EA)                             # I / A
    assert geometric[se.E_AXIAL, se.E_AXIAL] == pytest.approx(3 * n, rel=1e-5)
    assert geometric[se.KAPPA_Z, se.KAPPA_Z] == pytest.approx(3 * n * ratio, rel=1e-5)
    assert geometric[se.KAPPA_Y, se.KAPPA_Y] == pytest.approx(3 * n * ratio, rel=1e-5)
    assert geometric[se.A_SLOPE_V, se.A_SLOPE_V] == pytest.approx(n, rel=1e-5)
    assert geometric[se.B_SLOPE_W, se.B_SLOPE_W] == pytest.approx(n, rel=1e-5)
    assert geometric[se.TAU, se.TAU] == pytest.approx(n * 2 * ratio, rel=1e-5)


@pytest.mark.parametrize('seed', range(3))
def test_printed_eq15_is_the_energy_of_turned_tilts(seed):
    """
    W_printed(g, theta_x) = W(g~(g, theta_x)) for any twist (the printed reading's map).

    Against the 3D derivation of the printed displacement field, at large strains so that
    every product matters.
    """
    rng = np.random.default_rng(seed)
    paper, _ = _energy_density_3d(paper_eq15=True)
    section = _section()
    g = _random_strains(rng, 0.05)
    for theta_x in (0.0, 0.4, 2.0, -7.9):
        expected = _section_integral(paper, g, theta_x)
        mapped = se.energy_density(se.printed_eq15_strains(g, theta_x), section)
        np.testing.assert_allclose(mapped, expected, rtol=1e-11)
    # Where the map is linearised (no tilt, no twist rate), J is its derivative.
    g0 = np.zeros(8)
    g0[se.E_AXIAL] = 1e-4
    h = 1e-7
    numeric = np.array([(se.printed_eq15_strains(g0 + h * unit, 1.1)
                         - se.printed_eq15_strains(g0 - h * unit, 1.1)) / (2 * h)
                        for unit in np.eye(8)]).T
    np.testing.assert_allclose(se.printed_eq15_jacobian(1.1), numeric, atol=1e-8)
