"""Eq. 15 as printed, linearised at a frozen twist angle: the full FE model against the reduced one.

    python benchmarks/printed_eq15_modes.py [--angles-deg 0 15 30 45 60 90] [--modes 8]

Eq. 15 as printed, u_x = u - y theta_z + z theta_y, is the model's kinematics with the tilts
turned by the twist angle theta_x (fem.strain_energy.printed_eq15_strains, checked against
the 3D derivation). Linearised about the prestress at a uniform angle phi (a string turned
rigidly by phi: theta_x = phi everywhere, no twist rate), its stiffness is
K + sum_p w_p B_p^T (J^T H_p J - H_p) B_p, J = printed_eq15_jacobian(phi): the shear
constraint becomes theta_z = v' cos phi + w' sin phi, theta_y = v' sin phi - w' cos phi.

For the full FE model the rotations are free DOFs, so that is a relabelling of the bending
rotations and the frequencies cannot depend on phi (the mass of the rotations is
isotropic). The reduced model's basis is the modes at rest: its bending pairs carry
theta_z = v' and theta_y = -w', which the turned constraint does not admit, so its lateral
frequencies move with phi. With theta_x growing like Omega t, as it does when theta_x is the
absolute angle, the reduced model's lateral stiffness would then be modulated at the spin
(parametric excitation), and at the elastic twist (several radians near the bit in the
stick-slip) it would be set by the twist. Prints the lowest lateral frequencies of both
models per angle.
"""
from __future__ import annotations

import argparse

import numpy as np
import scipy.linalg as la
import scipy.sparse as sp

from drill_twin.config import load_config
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.fem import strain_energy as se
from drill_twin.modal.reduced_basis import modal_analysis


def point_jacobians(system, angle_rad, twist_rate_rad_per_m) -> np.ndarray:
    """
    dg~/dg of the printed map at every Gauss point, (P, 8, 8).

    About the prestress with the twist angle and rate of each point (arrays of shape (P,)),
    by central differences of ``printed_eq15_strains`` (exact: the map is bilinear in g).
    """
    base = system.prestress_strain.copy()
    base[:, se.TAU] = twist_rate_rad_per_m
    h = 1e-6
    columns = [(se.printed_eq15_strains(base + h * unit, angle_rad)
                - se.printed_eq15_strains(base - h * unit, angle_rad)) / (2 * h)
               for unit in np.eye(se.N_STRAINS)]
    return np.stack(columns, axis=-1)


def stiffness_change(system, angle_rad, twist_rate_rad_per_m=0.0) -> sp.csr_matrix:
    """sum_p w_p B_p^T (J_p^T H_p J_p - H_p) B_p on the field-wise DOFs."""
    points = system.gauss_weight_m.size
    jacobian = point_jacobians(system, np.broadcast_to(angle_rad, (points,)),
                               np.broadcast_to(twist_rate_rad_per_m, (points,)))
    tangent = system.prestress_tangent                         # (P, 8, 8)
    turned = np.einsum('pki,pkl,plj->pij', jacobian, tangent, jacobian) - tangent
    turned *= system.gauss_weight_m[:, None, None]
    blocks = sp.bmat([[sp.diags(turned[:, k, l]) for l in range(se.N_STRAINS)]  # noqa: E741
                      for k in range(se.N_STRAINS)]).tocsr()
    b = system.strain_operator                                  # row k * P + p
    return (b.T @ blocks @ b).tocsr()


def lateral_frequencies(mass, stiffness, lateral, count):
    values, vectors = la.eigh(stiffness, mass)
    order = np.argsort(values)
    share = np.sum(np.abs(vectors[lateral]) ** 2, axis=0) / np.sum(np.abs(vectors) ** 2, axis=0)
    picked = [i for i in order if share[i] > 0.5 and values[i] > 1e-6][:count]
    return np.sqrt(np.maximum(values[picked], 0.0)) / (2 * np.pi)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--angles-deg', type=float, nargs='+',
                        default=[0.0, 5.0, 15.0, 45.0, 90.0, 180.0])
    parser.add_argument('--modes', type=int, default=6)
    parser.add_argument('--steady-twist', action='store_true',
                        help='also the printed reading at the elastic twist of steady drilling '
                             '(theta_x the elastic twist, frozen)')
    parser.add_argument('--set', dest='overrides', action='append', default=[],
                        metavar='KEY=VALUE', help='override the model configuration')
    args = parser.parse_args()
    config = load_config(None, args.overrides)
    model, _, basis = modal_analysis(config)
    system = build_reduced_system(model, basis)
    permutation = system.permutation                       # field-wise DOF -> model DOF
    phi = basis.shapes[permutation][:, system.basis_columns]
    n = permutation.size
    to_model = sp.csr_matrix((np.ones(n), (permutation, np.arange(n))), shape=(n, n))
    free = model.free
    full_mass = model.total_mass.tocsr()[free][:, free].toarray()
    full_stiffness = (model.stiffness + model.geometric_stiffness
                      + model.fluid_stiffness).tocsr()
    lateral_fw = np.zeros(n, dtype=bool)
    for block in ('bending_y', 'bending_z'):
        lateral_fw[system.blocks[block].rows] = True
    lateral_model = np.zeros(n, dtype=bool)
    lateral_model[permutation[lateral_fw]] = True
    lateral_reduced = np.zeros(system.size, dtype=bool)
    for block in ('bending_y', 'bending_z'):
        lateral_reduced[system.blocks[block].columns] = True
    print(f'paper string: {n} DOFs, {system.size} reduced coordinates; lowest '
          f'{args.modes} lateral frequencies (Hz), Eq. 15 as printed at a frozen uniform twist')
    print(f'{"angle":>7} {"model":>8}  frequencies')
    for angle in args.angles_deg:
        change = stiffness_change(system, np.radians(angle))
        change_model = (to_model @ change @ to_model.T).tocsr()
        full = lateral_frequencies(full_mass, (full_stiffness + change_model).tocsr()[free][
            :, free].toarray(), lateral_model[free], args.modes)
        reduced = lateral_frequencies(system.mass, system.stiffness + phi.T @ (change @ phi),
                                      lateral_reduced, args.modes)
        print(f'{angle:>6g}° {"full":>8}  ' + ' '.join(f'{f:9.5f}' for f in full))
        print(f'{"":>7} {"reduced":>8}  ' + ' '.join(f'{f:9.5f}' for f in reduced))
    if args.steady_twist:
        from drill_twin.integrator.simulator import Simulator
        simulator = Simulator(config, system=system)
        q = simulator._initial_coordinates(config.operation.top_drive_speed_rad_per_s,
                                           lateral=False, steady_twist=True)[0][0]
        u = phi @ q
        rows = system.blocks['torsional'].rows
        angle = system.theta_x_gauss @ u[rows]
        points = system.gauss_weight_m.size
        rate = system.strain_operator[se.TAU * points:(se.TAU + 1) * points] @ u
        change = stiffness_change(system, angle, rate)
        change_model = (to_model @ change @ to_model.T).tocsr()
        full = lateral_frequencies(full_mass, (full_stiffness + change_model).tocsr()[free][
            :, free].toarray(), lateral_model[free], args.modes)
        reduced = lateral_frequencies(system.mass, system.stiffness + phi.T @ (change @ phi),
                                      lateral_reduced, args.modes)
        print(f'steady twist at the paper point: theta_x from {angle.min():.3f} to '
              f'{angle.max():.3f} rad (elastic, relative to the top)')
        print(f'{"twist":>7} {"full":>8}  ' + ' '.join(f'{f:9.5f}' for f in full))
        print(f'{"":>7} {"reduced":>8}  ' + ' '.join(f'{f:9.5f}' for f in reduced))


if __name__ == '__main__':
    main()
