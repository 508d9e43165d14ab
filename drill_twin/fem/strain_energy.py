"""
Strain energy per unit length of the finite-strain Timoshenko beam (Eq. 12-16).

Kinematics. A material point (y, z) of the cross-section moves by (Eq. 15, see below)

    u_x = u - theta_z y' + theta_y z'
    u_y = v + y' - y,   u_z = w + z' - z,
    (y', z') = (y cos theta_x - z sin theta_x, y sin theta_x + z cos theta_x),

i.e. the section is first twisted by theta_x and then tilted by the small bending
rotations theta_y, theta_z: the rotation sequence of the paper's Eq. 7. Eq. 15 as printed
(u_x = u - y theta_z + z theta_y) is the same at theta_x = 0 but makes the energy of a bent,
spinning string depend on the absolute rotation theta_x, which grows like Omega t; the
form above is invariant under a rigid rotation about x (docs/MODEL-CHOICES.md).

Strains. Green-Lagrange (Eq. 14). Because the annulus is axisymmetric, integrating over
(y, z) is integrating over (y', z'), and the shear pair rotated back by -theta_x has the same
sum of squares. With the generalized strains

    g = (e, a, b, kappa_y, kappa_z, tau, theta_y, theta_z)
      = (u', v', w', theta_y', theta_z', theta_x', theta_y, theta_z)

and p = tau theta_y - kappa_z, q = kappa_y + tau theta_z:

    eps_xx = c0 + c1 y' + c2 z' + c11 y'^2 + c22 z'^2 + c12 y' z'
        c0 = e + (e^2 + a^2 + b^2)/2,  c1 = p (1 + e) + b tau,  c2 = q (1 + e) - a tau,
        c11 = (p^2 + tau^2)/2,  c22 = (q^2 + tau^2)/2,  c12 = p q
    2 eps_xy -> E1 = s1 - theta_z p y' - t2 z',   2 eps_xz -> E2 = s2 + t3 y' + theta_y q z'
        s1 = a - theta_z (1 + e),  s2 = b + theta_y (1 + e),
        t1 = theta_z p,  t2 = tau + theta_z q,  t3 = tau + theta_y p,  t4 = theta_y q

and the energy per unit length (Eq. 16, U = 1/2 int E eps_xx^2 + k_s G (E1^2 + E2^2) dA):

    W = 1/2 E [A c0^2 + I (c1^2 + c2^2) + 2 I c0 (c11 + c22)
               + R4 (3 c11^2 + 3 c22^2 + 2 c11 c22 + c12^2)]
      + 1/2 k_s G [A (s1^2 + s2^2) + I (t1^2 + t2^2 + t3^2 + t4^2)]

with A, I = int y^2 dA, R4 = int y^2 z^2 dA (int y^4 dA = 3 R4). The quadratic part gives
[K] (axial EA, torsion k_s G I_p, Timoshenko bending and shear); its Hessian at the
prestress gives [K] + [K_g]; the rest is f_se.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.numerics.compiled import inline

N_STRAINS = 8
E_AXIAL, A_SLOPE_V, B_SLOPE_W, KAPPA_Y, KAPPA_Z, TAU, THETA_Y, THETA_Z = range(N_STRAINS)
_COMPLEX_STEP = 1e-30


@dataclass(frozen=True)
class SectionStiffness:
    """
    Section constants (broadcastable arrays).

    EA (N), EI (N m^2), ER4 (N m^4), kGA (N), kGI (N m^2).
    """

    EA: np.ndarray
    EI: np.ndarray
    ER4: np.ndarray
    kGA: np.ndarray
    kGI: np.ndarray

    @classmethod
    def from_mesh(cls, mesh) -> 'SectionStiffness':
        """Per-element constants of a :class:`~drill_twin.fem.mesh.Mesh`, shape (n_el, 1)."""
        kg = mesh.shear_correction * mesh.shear_modulus_pa
        col = (lambda a: np.asarray(a, dtype=float)[:, None])
        return cls(EA=col(mesh.young_modulus_pa * mesh.area_m2),
                   EI=col(mesh.young_modulus_pa * mesh.inertia_m4),
                   ER4=col(mesh.young_modulus_pa * mesh.fourth_moment_m6),
                   kGA=col(kg * mesh.area_m2),
                   kGI=col(kg * mesh.inertia_m4))


def _unpack(g):
    return tuple(g[..., k] for k in range(N_STRAINS))


def energy_density(g: np.ndarray, s: SectionStiffness) -> np.ndarray:
    """W(g) in J/m for generalized strains g of shape (..., 8)."""
    e, a, b, ky, kz, tau, ty, tz = _unpack(g)
    p = tau * ty - kz
    q = ky + tau * tz
    c0 = e + 0.5 * (e * e + a * a + b * b)
    c1 = p * (1 + e) + b * tau
    c2 = q * (1 + e) - a * tau
    c11 = 0.5 * (p * p + tau * tau)
    c22 = 0.5 * (q * q + tau * tau)
    c12 = p * q
    s1 = a - tz * (1 + e)
    s2 = b + ty * (1 + e)
    t1, t2, t3, t4 = tz * p, tau + tz * q, tau + ty * p, ty * q
    axial = (s.EA * c0 * c0 + s.EI * (c1 * c1 + c2 * c2) + 2 * s.EI * c0 * (c11 + c22)
             + s.ER4 * (3 * c11 * c11 + 3 * c22 * c22 + 2 * c11 * c22 + c12 * c12))
    shear = s.kGA * (s1 * s1 + s2 * s2) + s.kGI * (t1 * t1 + t2 * t2 + t3 * t3 + t4 * t4)
    return 0.5 * (axial + shear)


def stress_resultants(g: np.ndarray, s: SectionStiffness) -> np.ndarray:
    """dW/dg (the generalized stresses), shape (..., 8); works for complex g too."""
    components = stress_components(_unpack(g), s)
    out = np.empty(np.broadcast_shapes(g.shape, np.shape(s.EA) + (1,)),
                   dtype=np.result_type(g, float))
    for k, value in enumerate(components):
        out[..., k] = value
    return out


def stress_components(g, s: SectionStiffness):
    """
    dW/dg component by component: :func:`section_stress` over arrays.

    ``g`` is a sequence of 8 arrays (e, a, b, kappa_y, kappa_z, tau, theta_y, theta_z)
    broadcastable with the section constants; returns the 8 components (contiguous arrays make
    this several times faster than a strided last axis).
    """
    return section_stress.py_func(*g, s.EA, s.EI, s.ER4, s.kGA, s.kGI)


@inline
def section_stress(e, a, b, ky, kz, tau, ty, tz, ea, ei, er4, kga, kgi):
    """
    Return dW/dg at the strains g = (e, a, b, kappa_y, kappa_z, tau, theta_y, theta_z).

    Of a section (EA, EI, ER4, kGA, kGI), as the 8 components of g (module docstring). The one
    implementation: compiled into the finite-strain kernel
    (:mod:`drill_twin.model.finite_strain`), and run over numpy arrays (real or complex, any
    broadcastable shapes) by :func:`stress_components` through its Python function.
    """
    one_e = 1 + e
    p = tau * ty - kz
    q = ky + tau * tz
    c0 = e + 0.5 * (e * e + a * a + b * b)
    c1 = p * one_e + b * tau
    c2 = q * one_e - a * tau
    c11 = 0.5 * (p * p + tau * tau)
    c22 = 0.5 * (q * q + tau * tau)
    c12 = p * q
    s1 = kga * (a - tz * one_e)            # dW/ds1
    s2 = kga * (b + ty * one_e)            # dW/ds2
    t1 = kgi * (tz * p)
    t2 = kgi * (tau + tz * q)
    t3 = kgi * (tau + ty * p)
    t4 = kgi * (ty * q)
    w0 = ea * c0 + ei * (c11 + c22)
    w1 = ei * c1
    w2 = ei * c2
    w11 = ei * c0 + er4 * (3 * c11 + c22)
    w22 = ei * c0 + er4 * (3 * c22 + c11)
    w12 = er4 * c12
    dp = w1 * one_e + w11 * p + w12 * q + t1 * tz + t3 * ty
    dq = w2 * one_e + w22 * q + w12 * p + t2 * tz + t4 * ty
    return (w0 * one_e + w1 * p + w2 * q - s1 * tz + s2 * ty,      # e
            w0 * a - w2 * tau + s1,                                # a
            w0 * b + w1 * tau + s2,                                # b
            dq,                                                    # kappa_y
            -dp,                                                   # kappa_z
            w1 * b - w2 * a + (w11 + w22) * tau + t2 + t3 + dp * ty + dq * tz,   # tau
            s2 * one_e + t3 * p + t4 * q + dp * tau,               # theta_y
            -s1 * one_e + t1 * p + t2 * q + dq * tau)              # theta_z


def tangent_stiffness(g: np.ndarray, s: SectionStiffness) -> np.ndarray:
    """d^2W/dg^2, shape (..., 8, 8), exact to rounding by complex-step differentiation."""
    g = np.asarray(g, dtype=float)
    columns = []
    for k in range(N_STRAINS):
        probe = g.astype(complex)
        probe[..., k] += 1j * _COMPLEX_STEP
        columns.append(stress_resultants(probe, s).imag / _COMPLEX_STEP)
    return np.stack(columns, axis=-1)


def printed_eq15_strains(g: np.ndarray, theta_x) -> np.ndarray:
    """
    Return the strains g~ whose W(g~) is the energy of Eq. 15 as printed, shape (..., 8).

    Eq. 15 as printed, u_x = u - y theta_z + z theta_y, is the kinematics used here with the
    tilts turned by the twist angle theta_x (rad; absolute or elastic, as the reading says):
    theta~_y = theta_y cos - theta_z sin, theta~_z = theta_z cos + theta_y sin, so that
    -theta~_z y' + theta~_y z' = -theta_z y + theta_y z for the twisted coordinates (y', z').
    Their derivatives follow: kappa~_y = kappa_y cos - kappa_z sin - tau theta~_z,
    kappa~_z = kappa_z cos + kappa_y sin + tau theta~_y; e, a, b and tau are unchanged.
    (docs/LATERAL.md, "Eq. 15 as printed"; test/fem/test_strain_energy.py checks it against
    the 3D derivation of the printed displacement field.)
    """
    g = np.asarray(g)
    out = np.array(g, dtype=np.result_type(g, float), copy=True)
    (out[..., KAPPA_Y], out[..., KAPPA_Z], out[..., THETA_Y],
     out[..., THETA_Z]) = turned_tilts.py_func(g[..., KAPPA_Y], g[..., KAPPA_Z], g[..., TAU],
                                               g[..., THETA_Y], g[..., THETA_Z],
                                               np.cos(theta_x), np.sin(theta_x))
    return out


@inline
def turned_tilts(ky, kz, tau, ty, tz, c, s):
    """
    (kappa~_y, kappa~_z, theta~_y, theta~_z) of :func:`printed_eq15_strains`.

    The tilts and their derivatives turned by the twist angle whose cosine and sine are c, s.
    The one implementation: compiled into the finite-strain kernel's printed stress, and run
    over numpy arrays by :func:`printed_eq15_strains` through its Python function.
    """
    turned_y = ty * c - tz * s
    turned_z = tz * c + ty * s
    return (ky * c - kz * s - tau * turned_z, kz * c + ky * s + tau * turned_y,
            turned_y, turned_z)


def printed_eq15_jacobian(theta_x: float) -> np.ndarray:
    """
    Return dg~/dg of :func:`printed_eq15_strains` at the prestress, shape (8, 8).

    Where the section is neither tilted nor twisted at a rate (theta_y = theta_z = tau = 0).

    The tangent of the printed energy at a frozen twist angle there is J^T H_S J.
    """
    c, s = np.cos(theta_x), np.sin(theta_x)
    jacobian = np.eye(N_STRAINS)
    for first, second in ((KAPPA_Y, KAPPA_Z), (THETA_Y, THETA_Z)):
        jacobian[first, first], jacobian[first, second] = c, -s
        jacobian[second, first], jacobian[second, second] = s, c
    return jacobian
