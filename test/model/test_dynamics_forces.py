"""
The non-linear forces against independent derivations from their energies and laws.

f_se must be minus the gradient of the discrete non-linear strain energy, and f_ke must follow
from the coupling term of the kinetic energy by Lagrange's equations; both derivatives are
taken here numerically (complex step and finite differences in time) from the energies
alone, not from the force formulas. The bit-rock Jacobian and the contact tangent are checked
the same way.
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.model.bit_rock import BitRockLaw
from drill_twin.model.contact import contact_force
from drill_twin.model.finite_strain import finite_strain_force
from drill_twin.model.forces import Kinematics
from drill_twin.model.kinetic_coupling import kinetic_coupling_energy, kinetic_coupling_force
from drill_twin.model.reduced_system import build_reduced_system
from drill_twin.fem import strain_energy as se

STEP = 1e-30


@pytest.fixture(scope='module')
def system(default_analysis):
    model, _, basis = default_analysis
    return build_reduced_system(model, basis)


def _nonlinear_strain_energy(system, u):
    """sum_p w_p [W(g_S + g) - W(g_S) - sigma_S g - g H_S g / 2], g = B u, u (n_dofs,)."""
    g = (system.strain_operator @ u).reshape(se.N_STRAINS, system.n_gauss).T
    g_s = system.prestress_strain
    w = (se.energy_density(g_s + g, system.section) - se.energy_density(g_s, system.section)
         - np.einsum('pk,pk->p', system.prestress_stress, g)
         - 0.5 * np.einsum('pk,pkl,pl->p', g, system.prestress_tangent, g))
    return np.sum(system.gauss_weight_m * w)


def _random_displacement(system, rng, scale):
    """Return a smooth random field: random modal amplitudes, large enough to be non-linear."""
    q = rng.normal(size=(1, system.size)) * scale
    return system.physical(q)[0]


def test_finite_strain_force_is_minus_the_energy_gradient(system):
    rng = np.random.default_rng(3)
    u = _random_displacement(system, rng, 20.0)
    force = finite_strain_force(system, u[None])[0]
    energy = _nonlinear_strain_energy(system, u)
    assert energy > 1e-3 * np.abs(force).max()          # the state is really non-linear
    for _ in range(5):
        direction = rng.normal(size=u.size)
        derivative = _nonlinear_strain_energy(system, u + 1j * STEP * direction).imag / STEP
        assert -force @ direction == pytest.approx(derivative, rel=1e-8)


def _printed_strain_energy(system, u, top_angle):
    """Return the remainder of Eq. 15 as printed beyond [K] + [K_g], theta_x at the points."""
    g = (system.strain_operator @ u).reshape(se.N_STRAINS, system.n_gauss).T
    theta_x = system.theta_x_gauss @ u[system.blocks['torsional'].rows] + top_angle
    g_s = system.prestress_strain
    turned = se.printed_eq15_strains(g_s + g, theta_x)
    w = (se.energy_density(turned, system.section) - se.energy_density(g_s, system.section)
         - np.einsum('pk,pk->p', system.prestress_stress, g)
         - 0.5 * np.einsum('pk,pkl,pl->p', g, system.prestress_tangent, g))
    return np.sum(system.gauss_weight_m * w)


@pytest.mark.parametrize('reading, top_angle', [('printed_elastic', 0.0),
                                                ('printed_absolute', 0.0),
                                                ('printed_absolute', 2.7)])
@pytest.mark.parametrize('members', [1, 20])            # member by member, and vectorised
def test_printed_eq15_force_is_minus_its_energy_gradient(system, reading, top_angle, members):
    """
    f_se of Eq. 15 as printed, on the strains and on the twist DOFs, against its energy.

    The energy is W(g~) of fem.strain_energy.printed_eq15_strains (itself checked against the
    sympy derivation of the printed field), differentiated by complex step; the twist is large
    (random modal amplitudes of 20 give radians) so that every angle term matters.
    """
    import dataclasses

    from drill_twin.model.finite_strain import READINGS, StrainOperators

    operators = dataclasses.replace(StrainOperators.of(system), reading=READINGS.index(reading),
                                    top_angle=np.zeros(1))
    rng = np.random.default_rng(11)
    u = np.stack([_random_displacement(system, rng, 20.0) for _ in range(members)])
    force = finite_strain_force(system, u, operators, top_angle_rad=top_angle)
    angle = 0.0 if reading == 'printed_elastic' else top_angle
    invariant = finite_strain_force(system, u)
    assert np.abs(force - invariant).max() > 0.1 * np.abs(invariant).max()   # it differs
    for member in (0, members - 1):
        for _ in range(3):
            direction = rng.normal(size=u.shape[1])
            derivative = _printed_strain_energy(system, u[member] + 1j * STEP * direction,
                                                angle).imag / STEP
            assert -force[member] @ direction == pytest.approx(derivative, rel=1e-8)


def test_finite_strain_force_is_of_second_order(system):
    rng = np.random.default_rng(4)
    u = _random_displacement(system, rng, 1.0)
    small = np.abs(finite_strain_force(system, 1e-3 * u[None])).max()
    smaller = np.abs(finite_strain_force(system, 0.5e-3 * u[None])).max()
    assert smaller / small == pytest.approx(0.25, rel=0.02)


@pytest.mark.parametrize('members', [1, 20])            # member by member, and vectorised
def test_finite_strain_force_vanishes_exactly_at_the_prestress(system, members):
    """
    f_se(0) = -B^T w [dW/dg(g_S) - sigma_S] is zero to the bit.

    sigma_S is computed once over numpy arrays (fem.strain_energy.stress_resultants) and
    dW/dg(g_S + g) at every step by the compiled kernel: zero at u = 0 only if both are the
    same arithmetic, the section's stress written once.
    """
    force = finite_strain_force(system, np.zeros((members, system.n_dofs)))
    assert not np.any(force)


def _kinematics(system, u, rate, acceleration):
    """Kinematics from full field-wise arrays (1, n_dofs)."""
    b = system.blocks
    return Kinematics(displacement=u,
                      theta_x_rate=rate[:, system.field(1)],
                      theta_x_acceleration=acceleration[:, system.field(1)],
                      bending_y_rate=rate[:, b['bending_y'].rows],
                      bending_y_acceleration=acceleration[:, b['bending_y'].rows],
                      bending_z_rate=rate[:, b['bending_z'].rows],
                      bit_axial_rate=rate[:, system.bit_node])


def _coupling_lagrangian(system, u, rate):
    return kinetic_coupling_energy(system, _kinematics(system, u[None], rate[None],
                                                       np.zeros_like(rate)[None]))[0]


def test_kinetic_coupling_follows_from_lagranges_equations(system):
    """f_ke = -(d/dt dT_c/d(u') - dT_c/du), derivatives taken numerically from T_c alone."""
    rng = np.random.default_rng(5)
    u = _random_displacement(system, rng, 5.0)
    rate = _random_displacement(system, rng, 5.0)
    rate[system.field(1)] += 5.2                          # the string spins
    acceleration = _random_displacement(system, rng, 5.0)
    force = kinetic_coupling_force(system, _kinematics(system, u[None], rate[None],
                                                       acceleration[None]))[0]
    assert np.abs(force).max() > 0

    def momentum(time, direction):
        # d T_c / d(u') . direction along the trajectory u(t), u'(t) through the state.
        position = u + time * rate + 0.5 * time ** 2 * acceleration
        velocity = rate + time * acceleration
        probe = _coupling_lagrangian(system, position, velocity + 1j * STEP * direction)
        return probe.imag / STEP

    h = 1e-4
    for _ in range(5):
        direction = rng.normal(size=u.size)
        rate_of_momentum = (momentum(h, direction) - momentum(-h, direction)) / (2 * h)
        gradient = _coupling_lagrangian(system, u + 1j * STEP * direction, rate).imag / STEP
        expected = -(rate_of_momentum - gradient)
        assert force @ direction == pytest.approx(expected, rel=1e-6,
                                                  abs=1e-9 * np.abs(force).max())


def test_contact_force_and_tangent(system):
    n = system.n_nodes
    u = np.zeros((1, system.n_dofs))
    node = 16                                              # x = 700 m, clearance 86.5 mm
    clearance = system.clearance_m[node]
    assert clearance == pytest.approx((0.3 - 0.127) / 2)
    v, w = 0.07, 0.06                                      # r = 92.2 mm: in contact
    u[0, system.field(2).start + node] = v
    u[0, system.field(4).start + node] = w
    rate = np.zeros((1, system.n_dofs))
    rate[0, system.field(1)] = 5.0                         # spinning forwards
    fields = _kinematics(system, u, rate, np.zeros_like(rate))
    force, contact, tangent = contact_force(system, 1e8, 0.0005, 0.1, fields)
    r = np.hypot(v, w)
    magnitude = 1e8 * (r - clearance)
    assert contact.in_contact[0].sum() == 1 and contact.in_contact[0, node]
    assert contact.radial_force_n[0, node] == pytest.approx(magnitude)
    assert force[0, system.field(2).start + node] == pytest.approx(-magnitude * v / r)
    assert force[0, system.field(4).start + node] == pytest.approx(-magnitude * w / r)
    spin = 5.0 / np.sqrt(25.0 + 0.01)
    assert force[0, system.field(1).start + node] == pytest.approx(
        -0.0005 * magnitude * system.node_outer_radius_m[node] * spin)
    h = 1e-7
    for k, field in enumerate((2, 4)):
        shifted = u.copy()
        shifted[0, system.field(field).start + node] += h
        moved, _, _ = contact_force(system, 1e8, 0.0005, 0.1,
                                    _kinematics(system, shifted, rate, np.zeros_like(rate)))
        column = -(moved - force)[0, [system.field(2).start + node,
                                      system.field(4).start + node]] / h
        np.testing.assert_allclose(tangent[0, node, :, k], column, rtol=1e-5)
    inside = np.zeros_like(u)
    inside[0, system.field(2).start + node] = 0.08
    none, flags, _ = contact_force(system, 1e8, 0.0005, 0.1,
                                   _kinematics(system, inside, rate, np.zeros_like(rate)))
    assert not flags.in_contact.any() and not none.any()
    assert n == 57


@pytest.mark.parametrize('seed', range(4))
def test_tangential_wall_friction_opposes_the_slip_and_never_does_work(system, seed):
    """
    borehole.tangential_friction: a friction force at the contact point (model/contact.py).

    At a node pressed on the wall with a random whirl velocity and spin: the radial force is the
    paper's, the friction force is tangential, of size mu |F_r| |sign_eps(s)|, and with its moment
    about the axis it dissipates -mu |F_r| s sign_eps(s) <= 0 (s the slip of the pipe's surface
    on the wall); rolling without slip (the backward whirl (v', w') . t = -R_o theta_x') feels
    no friction at all.
    """
    rng = np.random.default_rng(seed)
    node, mu, eps = system.n_nodes - 2, 0.3, 0.1            # a collar node
    clearance, lever = system.clearance_m[node], system.node_outer_radius_m[node]
    angle = rng.uniform(0, 2 * np.pi)
    r = clearance + rng.uniform(1e-4, 2e-3)
    v, w = r * np.cos(angle), r * np.sin(angle)
    n, t = np.array([v, w]) / r, np.array([-w, v]) / r
    u = np.zeros((1, system.n_dofs))
    u[0, system.field(2).start + node] = v
    u[0, system.field(4).start + node] = w
    spin = rng.uniform(-10, 10)

    def forces(whirl_velocity):
        rate = np.zeros((1, system.n_dofs))
        rate[0, system.field(1)] = spin
        rate[0, system.field(2).start + node] = whirl_velocity[0]
        rate[0, system.field(4).start + node] = whirl_velocity[1]
        fields = _kinematics(system, u, rate, np.zeros_like(rate))
        force, contact, _ = contact_force(system, 1e8, mu, eps, fields, tangential=True)
        lateral = force[0, [system.field(2).start + node, system.field(4).start + node]]
        return lateral, force[0, system.field(1).start + node], contact.radial_force_n[0, node]

    velocity = rng.normal(size=2)
    lateral, torque, radial = forces(velocity)
    assert radial == pytest.approx(1e8 * (r - clearance))
    assert lateral @ n == pytest.approx(-radial)                  # the paper's normal force
    slip = velocity @ t + lever * spin
    sign = slip / np.hypot(slip, eps * lever)
    assert lateral @ t == pytest.approx(-mu * radial * sign)
    assert torque == pytest.approx(-mu * radial * lever * sign)
    power = (lateral - (lateral @ n) * n) @ velocity + torque * spin
    assert power == pytest.approx(-mu * radial * slip * sign) and power <= 0.0
    rolling = -lever * spin * t + rng.normal() * n               # no slip, any radial speed
    lateral, torque, _ = forces(rolling)
    assert abs(lateral @ t) < 1e-9 * radial and abs(torque) < 1e-9 * radial


@pytest.fixture(scope='module')
def law(default_config):
    return BitRockLaw.from_config(default_config.bit_rock)


def test_law_reproduces_eq24_far_from_zero_speed(law):
    """Z -> 1 for omega >> e: ROP = -a1 - a2 f + a3 omega, t = -a4 ROP/omega - a5."""
    omega, wob = 400.0, -1e5
    rop = law.steady_rop(omega, wob)
    assert rop == pytest.approx(-law.a1 - law.a2 * wob + law.a3 * omega, rel=1e-4)
    force, torque = law.mean(rop, omega)
    assert force == pytest.approx(wob, rel=1e-9)
    assert torque == pytest.approx(-law.a4 * rop / omega - law.a5, rel=1e-4)


def test_law_vanishes_as_the_bit_stops(law):
    omega = np.array([1e-2, 1e-4, 1e-6])
    rop = law.steady_rop(omega, -1e5)
    assert np.all(np.diff(np.abs(rop)) < 0) and abs(rop[-1]) < 1e-15
    torque = law.steady_torque(omega, -1e5)
    assert np.all(np.abs(torque) < law.a5 * omega / law.e * 1.01 + 1e-12)


def test_matrix_form_of_eq41(law):
    """f_bit = -[A_b] x with the diagonal [A_b] of Eq. 41."""
    rop, omega = 2.5e-3, 5.0
    z = omega / np.hypot(omega, law.e)
    a11 = law.a1 / (law.a2 * rop) + 1 / (law.a2 * z * z) - law.a3 * omega / (law.a2 * z * rop)
    a22 = law.a4 * z * z * rop / omega ** 2 + law.a5 * z / omega
    force, torque = law.mean(rop, omega)
    assert force == pytest.approx(-a11 * rop, rel=1e-12)
    assert torque == pytest.approx(-a22 * omega, rel=1e-12)
    assert a11 > 0 and a22 > 0


def test_the_graph_of_the_law_is_the_law_on_its_cutting_branch(law):
    """
    Along ROP = R(f, omega) the law's views give back Eq. 25-26 and Eq. 50.

    The views (cutting rate, torque of force, random point) are read against the law at
    the velocities (``mean``, ``forces``) where the bit cuts: f below the fade force.
    """
    omega = np.array([0.5, 2.0, 5.2, 9.0, 15.0])
    force = np.array([-2.5e5, -1.8e5, -1.2e5, -1.5e5, -2.2e5])
    assert np.all(force < law.fade_force(omega)) and np.all(law.threshold_force(omega) > force)
    rop = law.cutting_rate(force, omega)
    assert np.all(rop > 0)
    np.testing.assert_array_equal(law.steady_rop(omega, force), rop)
    mean_force, mean_torque = law.mean(rop, omega)
    np.testing.assert_allclose(mean_force, force, rtol=1e-9)
    torque = law.torque_of_force(force, omega)
    np.testing.assert_allclose(torque, mean_torque, rtol=1e-9)
    np.testing.assert_allclose(law.steady_torque(omega, force), mean_torque, rtol=1e-15)
    germ = np.array([[[0.93, 0.08], [0.08, 1.08]]])
    random_force, random_torque = law.randomised(force, torque, rop, rop, omega, germ)
    expected_force, expected_torque, _ = law.forces(rop, omega, germ)
    np.testing.assert_allclose(random_force, expected_force, rtol=1e-8)
    np.testing.assert_allclose(random_torque, expected_torque, rtol=1e-8)


def test_random_law_is_continuous_at_zero_rop(law):
    """The random deviation fades into the mean law as ROP -> 0+ (no jump at the edge of C)."""
    germ = np.array([[[0.93, 0.08], [0.08, 1.08]]])
    for rop in (1e-7, 1e-8):
        random, _, _ = law.forces(np.array([rop]), np.array([5.2]), germ)
        mean, _ = law.mean(rop, 5.2)
        assert abs(random[0] - mean) < 1e-2 * abs(mean)


def test_lift_off_removes_the_bit_forces(law):
    force, torque, lifted, jacobian = law.forces_and_jacobian(np.array([-1e-2, 2e-3]),
                                                              np.array([5.0, 5.0]))
    assert lifted.tolist() == [True, False]
    assert force[0] == 0 and torque[0] == 0 and not jacobian[0].any()
    assert force[1] < 0


@pytest.mark.parametrize('germ', [None, np.array([[[1.05, 0.08], [0.08, 0.93]]] * 4)])
def test_bit_rock_jacobian(law, germ):
    """
    Analytic Jacobian against complex-step derivatives of the (random) law.

    Also inside the blend near ROP = 0.
    """
    rop = np.array([2.6e-3, 1.1e-3, 3.3e-3, 8e-5])
    omega = np.array([5.2, 0.7, 9.0, 4.0])
    _, _, _, jacobian = law.forces_and_jacobian(rop, omega, germ)
    for column, (dr, dw) in enumerate(((1j * STEP, 0.0), (0.0, 1j * STEP))):
        f, t, _ = law.forces(rop + dr, omega + dw, germ)
        np.testing.assert_allclose(jacobian[:, 0, column], np.imag(f) / STEP, rtol=1e-9)
        np.testing.assert_allclose(jacobian[:, 1, column], np.imag(t) / STEP, rtol=1e-9)


def test_random_law_is_the_quadratic_form_of_eq50(law):
    """F = -L^T G L x with L = sqrt(diag(A_b)), written out, on the admissible set."""
    rng = np.random.default_rng(2)
    rop, omega = np.array([2.4e-3]), np.array([4.7])
    germ = np.eye(2)[None] + 0.05 * rng.normal(size=(1, 2, 2))
    germ = 0.5 * (germ + germ.transpose(0, 2, 1))
    f, t = law.mean(rop, omega)
    lower = np.diag([np.sqrt(-f[0] / rop[0]), np.sqrt(-t[0] / omega[0])])
    eq50 = -lower.T @ germ[0] @ lower @ np.array([rop[0], omega[0]])
    # Blended into the mean law near ROP = 0 with w = ROP^2 / (ROP^2 + r^2) (r = 1e-4 m/s).
    weight = rop[0] ** 2 / (rop[0] ** 2 + law.rop_scale ** 2)
    expected = np.array([f[0], t[0]]) + weight * (eq50 - np.array([f[0], t[0]]))
    force, torque, _ = law.forces(rop, omega, germ)
    np.testing.assert_allclose([force[0], torque[0]], expected, rtol=1e-12)
    assert weight > 0.998
    mean_force, mean_torque, _ = law.forces(rop, omega, np.eye(2)[None])
    np.testing.assert_allclose([mean_force[0], mean_torque[0]], [f[0], t[0]], rtol=1e-14)
