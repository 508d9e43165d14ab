"""Closed-form and exact reference solutions used by the tests (independent of the model)."""
from __future__ import annotations

import numpy as np
from scipy.optimize import brentq


def fixed_free_rod_hz(n_modes: int, length_m: float, wave_speed_m_per_s: float) -> np.ndarray:
    """f_n = (2n - 1) c / (4 L) for a rod fixed at one end, free at the other."""
    n = np.arange(1, n_modes + 1)
    return (2 * n - 1) * wave_speed_m_per_s / (4.0 * length_m)


def rod_with_tip_inertia_hz(n_modes: int, length_m: float, wave_speed_m_per_s: float,
                            inertia_ratio: float) -> np.ndarray:
    """
    Return the frequencies of a fixed rod with a rigid tip inertia: beta tan beta = mu.

    f = beta c / (2 pi L).

    mu is the rod's own inertia divided by the tip's (mass ratio for axial motion,
    polar-inertia ratio for torsion).
    """
    roots = []
    for k in range(n_modes):
        lo = k * np.pi + 1e-12
        hi = k * np.pi + np.pi / 2 - 1e-12
        roots.append(brentq(lambda b: b * np.tan(b) - inertia_ratio, lo, hi))
    return np.array(roots) * wave_speed_m_per_s / (2 * np.pi * length_m)


def tensioned_pinned_beam_hz(n_modes: int, length_m: float, bending_stiffness_n_m2: float,
                             tension_n: float, mass_per_length_kg_per_m: float) -> np.ndarray:
    """
    Euler-Bernoulli beam under tension, pinned at both ends.

    omega_n^2 = [(n pi / L)^4 EI + (n pi / L)^2 T] / m.
    """
    k = np.arange(1, n_modes + 1) * np.pi / length_m
    omega = np.sqrt((k ** 4 * bending_stiffness_n_m2 + k ** 2 * tension_n)
                    / mass_per_length_kg_per_m)
    return omega / (2 * np.pi)


def timoshenko_cantilever_hz(n_modes: int, length_m: float, young_pa: float, shear_pa: float,
                             shear_factor: float, density: float, area_m2: float,
                             inertia_m4: float) -> np.ndarray:
    """
    Exact bending frequencies of a clamped-free Timoshenko beam.

    Solves kGA (W'' - Psi') + rho A w^2 W = 0, EI Psi'' + kGA (W' - Psi) + rho I w^2 Psi = 0
    with W = Psi = 0 at x = 0 and EI Psi' = kGA (W' - Psi) = 0 at x = L, by scanning the
    4 x 4 boundary determinant for sign changes (below the second-spectrum cut-off).
    """
    ei, kga = young_pa * inertia_m4, shear_factor * shear_pa * area_m2
    rho_a, rho_i = density * area_m2, density * inertia_m4
    cutoff = np.sqrt(kga / rho_i)

    def determinant(omega):
        w2 = omega * omega
        a, b, c = ei * kga, w2 * (ei * rho_a + kga * rho_i), rho_a * w2 * (rho_i * w2 - kga)
        disc = np.sqrt(b * b - 4 * a * c)
        s1, s2 = (-b + disc) / (2 * a), (-b - disc) / (2 * a)
        alpha, beta = np.sqrt(s1), np.sqrt(-s2)
        q = rho_a * w2 / kga
        ha, hb = alpha + q / alpha, beta - q / beta
        x = length_m
        th, sech = np.tanh(alpha * x), 1.0 / np.cosh(alpha * x)
        co, si = np.cos(beta * x), np.sin(beta * x)
        # Rows 3 and 4 are divided by cosh(alpha L): same sign, no overflow.
        matrix = np.array([
            [1.0, 0.0, 1.0, 0.0],
            [0.0, ha, 0.0, hb],
            [ha * alpha, ha * alpha * th, -hb * beta * co * sech, -hb * beta * si * sech],
            [-q / alpha * th, -q / alpha, -q / beta * si * sech, q / beta * co * sech],
        ])
        return np.linalg.det(matrix)

    # Euler-Bernoulli frequencies bound the Timoshenko ones from above.
    euler_roots = (2 * np.arange(1, n_modes + 2) - 1) * np.pi / 2
    euler = euler_roots ** 2 * np.sqrt(ei / rho_a) / length_m ** 2
    upper = min(0.999 * cutoff, 1.01 * euler[-1])
    grid = np.linspace(0.02 * euler[0], upper, 40000)
    values = np.array([determinant(w) for w in grid])
    roots = []
    for i in np.flatnonzero(np.sign(values[:-1]) != np.sign(values[1:])):
        roots.append(brentq(determinant, grid[i], grid[i + 1]))
        if len(roots) == n_modes:
            break
    if len(roots) < n_modes:
        raise ValueError('fewer roots than asked below the cut-off frequency')
    return np.array(roots) / (2 * np.pi)
