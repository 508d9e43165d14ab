"""
f_se: the finite-strain forces beyond [K] + [K_g] (Eq. 14-16).

f_se = -B^T [dW/dg(g_S + g) - dW/dg(g_S) - H_S g] at every Gauss point: the strain energy's
force minus its value and tangent at the prestress, which [K] + [K_g] already carry.

The kernel runs Gauss point by Gauss point with the members of the batch as the inner
(vector) axis, arrays shaped (n_dofs, m): the 8 strains of a point are gathered from its
element's DOFs, its stress is computed and scattered straight back, so no array larger than
(9, m) is made between the displacement and the force. B and H_S are stored row by row with
every row padded to the same number of entries (zeros at the end): loops of a fixed length
cost a third less than the compressed rows' short loops of varying length (28 -> 20 us for
the paper's 224 points, one member), and the padding adds exact zeros, so the sums are those
of the compressed rows bit for bit.

Readings of Eq. 15 (``lateral_readings.strain_kinematics``; docs/LATERAL.md, "Eq. 15 as
printed"): ``invariant`` (the default, docs/MODEL-CHOICES.md, "The finite-strain kinematics
(Eq. 15)") or Eq. 15 as printed, whose energy is W(g~(g, theta_x)) with the tilts turned by the
twist angle theta_x at the point (:func:`~drill_twin.fem.strain_energy.printed_eq15_strains`):
``printed_elastic`` (theta_x the elastic twist, relative to the top drive's angle) or
``printed_absolute`` (the top drive's angle added: it grows like Omega t). The printed energy
depends on theta_x itself, so its force has a term on the twist DOFs, N_theta_x^T dW/dtheta_x;
[K] + [K_g] are the same for every reading (at theta_x = 0 they agree), f_se carries the rest.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.sparse as sp

from drill_twin.numerics.compiled import VECTOR_BATCH, inline, kernel
from drill_twin.numerics.padded_rows import padded_rows, unsigned_index
from drill_twin.fem import strain_energy as se
from drill_twin.fem.strain_energy import section_stress, turned_tilts

READINGS = ('invariant', 'printed_elastic', 'printed_absolute')
"""``lateral_readings.strain_kinematics``, in the order of the kernel's reading code."""
WORK_ROWS = se.N_STRAINS + 1
"""Rows of the strain and stress work arrays: the 8 strains, then the twist angle."""


@dataclass(frozen=True)
class StrainOperators:
    """
    The finite-strain data of a reduced system, in the kernel's layout.

    strain_column, strain_value, strain_length: B in padded rows (:mod:`padded_rows`), (8 P, R):
    row 8 p + k for strain k at Gauss point p, columns the field-wise DOFs; tangent_row,
    tangent_column, tangent_value, tangent_length: the non-zeros of H_S = d2W/dg2(g_S) point
    by point, (P, T), padded alike;
    prestress_strain, prestress_stress: g_S and dW/dg(g_S), (P, 8); section: (P, 5) columns
    EA, EI, ER4, kGA, kGI; weight_m: Gauss weights (m), (P,); reading: the index of the Eq. 15
    reading in READINGS; twist_pointer, twist_column, twist_value: theta_x at the Gauss points
    in CSR (P rows, field-wise DOFs); top_angle: (1,) the top drive's angle (rad), set before
    every evaluation (read by ``printed_absolute`` only).
    """

    strain_column: np.ndarray
    strain_value: np.ndarray
    strain_length: np.ndarray
    tangent_row: np.ndarray
    tangent_column: np.ndarray
    tangent_value: np.ndarray
    tangent_length: np.ndarray
    prestress_strain: np.ndarray
    prestress_stress: np.ndarray
    section: np.ndarray
    weight_m: np.ndarray
    reading: int
    twist_pointer: np.ndarray
    twist_column: np.ndarray
    twist_value: np.ndarray
    top_angle: np.ndarray

    @classmethod
    def of(cls, system) -> 'StrainOperators':
        points = system.n_gauss
        point_major = (np.arange(points)[:, None]
                       + points * np.arange(se.N_STRAINS)[None, :]).ravel()
        strain = system.strain_operator[point_major].tocsr()
        strain.sort_indices()
        tangent = system.prestress_tangent
        point, row, column = np.nonzero(tangent)              # sorted by point
        pointer = np.searchsorted(point, np.arange(points + 1))
        strain_column, strain_value, strain_length = padded_rows(strain.indptr, strain.indices,
                                                                 strain.data)
        (tangent_row, tangent_column), tangent_value, tangent_length = padded_rows(
            pointer, (row, column), tangent[point, row, column])
        s = system.section
        torsion_rows = system.blocks['torsional'].rows
        twist = np.zeros((points, system.permutation.size))
        twist[:, torsion_rows] = system.theta_x_gauss
        twist = sp.csr_matrix(twist)
        twist.sort_indices()
        reading = system.model.config.lateral_readings.strain_kinematics
        return cls(
            strain_column=strain_column, strain_value=strain_value, strain_length=strain_length,
            tangent_row=tangent_row, tangent_column=tangent_column, tangent_value=tangent_value,
            tangent_length=tangent_length,
            prestress_strain=np.ascontiguousarray(system.prestress_strain, dtype=float),
            prestress_stress=np.ascontiguousarray(system.prestress_stress, dtype=float),
            section=np.ascontiguousarray(np.stack([s.EA, s.EI, s.ER4, s.kGA, s.kGI], axis=1),
                                         dtype=float),
            weight_m=np.ascontiguousarray(system.gauss_weight_m, dtype=float),
            reading=READINGS.index(reading),
            twist_pointer=twist.indptr.astype(np.int64),
            twist_column=unsigned_index(twist.indices),
            twist_value=twist.data.astype(float), top_angle=np.zeros(1))

    def set_top_angle(self, angle_rad: float) -> None:
        """Set the top drive's angle (rad) the next evaluation adds (printed_absolute)."""
        self.top_angle[0] = angle_rad

    def arguments(self) -> tuple:
        """Return the kernel's operator arguments, in its order."""
        return (self.strain_column, self.strain_value, self.strain_length, self.tangent_row,
                self.tangent_column, self.tangent_value, self.tangent_length,
                self.prestress_strain, self.prestress_stress, self.section, self.weight_m,
                self.reading, self.twist_pointer, self.twist_column, self.twist_value,
                self.top_angle)


@inline
def _printed_stress(e, a, b, ky, kz, tau, ty, tz, theta, ea, ei, er4, kga, kgi):
    """
    d/d(g, theta_x) of W(g~(g, theta_x)), Eq. 15 as printed: 9 values (the 8 of g, theta_x).

    The chain rule through fem.strain_energy.printed_eq15_strains (its turned_tilts) and the
    section's stress (fem.strain_energy.section_stress, the one implementation of dW/dg).
    """
    c, s = np.cos(theta), np.sin(theta)
    tky, tkz, tty, ttz = turned_tilts(ky, kz, tau, ty, tz, c, s)
    r = section_stress(e, a, b, tky, tkz, tau, tty, ttz, ea, ei, er4, kga, kgi)
    sky, skz, sty, stz = r[3], r[4], r[6], r[7]
    return (r[0], r[1], r[2],
            sky * c + skz * s,
            -sky * s + skz * c,
            r[5] - sky * ttz + skz * tty,
            sty * c + stz * s - sky * tau * s + skz * tau * c,
            -sty * s + stz * c - sky * tau * c - skz * tau * s,
            -sty * ttz + stz * tty + sky * (-ky * s - kz * c - tau * tty)
            + skz * (ky * c - kz * s - tau * ttz))


@kernel
def accumulate_finite_strain(displacement_t, strain_column, strain_value, strain_length,
                             tangent_row, tangent_column, tangent_value, tangent_length,
                             prestress_strain, prestress_stress, section, weight_m, reading,
                             twist_pointer, twist_column, twist_value, top_angle,
                             strain, linear, stress, force_t):
    """
    force_t += f_se for displacements u (both (n_dofs, m), members last).

    strain, stress: work arrays (9, m) (g and theta_x, the weighted stress of a point and of
    theta_x); linear: (8, m) (H_S g). Small batches run member by member (short vector loops
    cost more than they save).
    """
    members = displacement_t.shape[1]
    if members < VECTOR_BATCH:
        for i in range(members):
            _accumulate_member(displacement_t, i, strain_column, strain_value, tangent_row,
                               tangent_column, tangent_value,
                               prestress_strain, prestress_stress, section, weight_m, reading,
                               twist_pointer, twist_column, twist_value, top_angle,
                               strain, linear, stress, force_t)
        return
    for p in range(weight_m.shape[0]):
        for k in range(8):
            row = 8 * p + k
            for i in range(members):
                strain[k, i] = 0.0
                linear[k, i] = 0.0
            for j in range(strain_length[row]):
                column, value = strain_column[row, j], strain_value[row, j]
                for i in range(members):
                    strain[k, i] += value * displacement_t[column, i]
        for j in range(tangent_length[p]):
            k, l, value = tangent_row[p, j], tangent_column[p, j], tangent_value[p, j]
            for i in range(members):
                linear[k, i] += value * strain[l, i]
        g, s, w = prestress_strain[p], section[p], weight_m[p]
        if reading == 0:
            # Scalars and unrolled stores: the member loop then compiles to vector code.
            g0, g1, g2, g3, g4, g5, g6, g7 = g[0], g[1], g[2], g[3], g[4], g[5], g[6], g[7]
            h = prestress_stress[p]
            h0, h1, h2, h3, h4, h5, h6, h7 = h[0], h[1], h[2], h[3], h[4], h[5], h[6], h[7]
            ea, ei, er4, kga, kgi = s[0], s[1], s[2], s[3], s[4]
            for i in range(members):
                r0, r1, r2, r3, r4, r5, r6, r7 = section_stress(
                    g0 + strain[0, i], g1 + strain[1, i], g2 + strain[2, i], g3 + strain[3, i],
                    g4 + strain[4, i], g5 + strain[5, i], g6 + strain[6, i], g7 + strain[7, i],
                    ea, ei, er4, kga, kgi)
                stress[0, i] = ((r0 - h0) - linear[0, i]) * w
                stress[1, i] = ((r1 - h1) - linear[1, i]) * w
                stress[2, i] = ((r2 - h2) - linear[2, i]) * w
                stress[3, i] = ((r3 - h3) - linear[3, i]) * w
                stress[4, i] = ((r4 - h4) - linear[4, i]) * w
                stress[5, i] = ((r5 - h5) - linear[5, i]) * w
                stress[6, i] = ((r6 - h6) - linear[6, i]) * w
                stress[7, i] = ((r7 - h7) - linear[7, i]) * w
        else:
            for i in range(members):
                strain[8, i] = _twist_angle(displacement_t, i, p, reading, twist_pointer,
                                            twist_column, twist_value, top_angle)
                _printed_member(strain, linear, stress, g, s, w, prestress_stress, p, i)
        for k in range(8):
            row = 8 * p + k
            for j in range(strain_length[row]):
                column, value = strain_column[row, j], strain_value[row, j]
                for i in range(members):
                    force_t[column, i] -= value * stress[k, i]
        if reading != 0:
            for j in range(twist_pointer[p], twist_pointer[p + 1]):
                column, value = twist_column[j], twist_value[j]
                for i in range(members):
                    force_t[column, i] -= value * stress[8, i]


@inline
def _twist_angle(displacement_t, i, p, reading, twist_pointer, twist_column, twist_value,
                 top_angle):
    """Return theta_x of member i at Gauss point p (rad; + the top angle if absolute)."""
    total = top_angle[0] if reading == 2 else 0.0
    for j in range(twist_pointer[p], twist_pointer[p + 1]):
        total += twist_value[j] * displacement_t[twist_column[j], i]
    return total


@inline
def _printed_member(strain, linear, stress, g, s, w, prestress_stress, p, i):
    """stress[:, i] of Eq. 15 as printed at Gauss point p (the 8 strains and theta_x)."""
    sigma = _printed_stress(g[0] + strain[0, i], g[1] + strain[1, i], g[2] + strain[2, i],
                            g[3] + strain[3, i], g[4] + strain[4, i], g[5] + strain[5, i],
                            g[6] + strain[6, i], g[7] + strain[7, i], strain[8, i], s[0], s[1],
                            s[2], s[3], s[4])
    for k in range(8):
        stress[k, i] = ((sigma[k] - prestress_stress[p, k]) - linear[k, i]) * w
    stress[8, i] = sigma[8] * w


@inline
def _accumulate_member(displacement_t, i, strain_column, strain_value, tangent_row,
                       tangent_column, tangent_value,
                       prestress_strain, prestress_stress, section, weight_m, reading,
                       twist_pointer, twist_column, twist_value, top_angle, strain, linear,
                       stress, force_t):
    """Run the loop of :func:`accumulate_finite_strain` for member i alone (work column i)."""
    width, tangents = strain_column.shape[1], tangent_row.shape[1]
    for p in range(weight_m.shape[0]):
        for k in range(8):
            row = 8 * p + k
            total = 0.0
            for j in range(width):
                total += strain_value[row, j] * displacement_t[strain_column[row, j], i]
            strain[k, i] = total
            linear[k, i] = 0.0
        for j in range(tangents):
            linear[tangent_row[p, j], i] += (tangent_value[p, j]
                                             * strain[tangent_column[p, j], i])
        g, s, w = prestress_strain[p], section[p], weight_m[p]
        if reading == 0:
            sigma = section_stress(g[0] + strain[0, i], g[1] + strain[1, i],
                                   g[2] + strain[2, i], g[3] + strain[3, i],
                                   g[4] + strain[4, i], g[5] + strain[5, i],
                                   g[6] + strain[6, i], g[7] + strain[7, i],
                                   s[0], s[1], s[2], s[3], s[4])
            for k in range(8):
                stress[k, i] = ((sigma[k] - prestress_stress[p, k]) - linear[k, i]) * w
        else:
            strain[8, i] = _twist_angle(displacement_t, i, p, reading, twist_pointer,
                                        twist_column, twist_value, top_angle)
            _printed_member(strain, linear, stress, g, s, w, prestress_stress, p, i)
        for k in range(8):
            row = 8 * p + k
            sigma_k = stress[k, i]
            for j in range(width):
                force_t[strain_column[row, j], i] -= strain_value[row, j] * sigma_k
        if reading != 0:
            for j in range(twist_pointer[p], twist_pointer[p + 1]):
                force_t[twist_column[j], i] -= twist_value[j] * stress[8, i]


def finite_strain_force(system, displacement: np.ndarray,
                        operators: StrainOperators | None = None,
                        top_angle_rad: float = 0.0) -> np.ndarray:
    """
    f_se on the field-wise DOFs (right-hand side), shape (m, n_dofs).

    displacement: u from the prestressed state, shape (m, n_dofs). ``operators`` (built from
    ``system`` when not given) are :meth:`StrainOperators.of` the system.
    """
    operators = operators or StrainOperators.of(system)
    operators.set_top_angle(top_angle_rad)
    members = displacement.shape[0]
    displacement_t = np.ascontiguousarray(displacement.T, dtype=float)
    force_t = np.zeros_like(displacement_t)
    work = [np.empty((WORK_ROWS, members)), np.empty((se.N_STRAINS, members)),
            np.empty((WORK_ROWS, members))]
    accumulate_finite_strain(displacement_t, *operators.arguments(), *work, force_t)
    return np.ascontiguousarray(force_t.T)
