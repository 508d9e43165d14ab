"""
The compiled step's named operands (drill_twin.integrator.step_operands).

Each field of the structures the integrator hands the compiled step has the shape and dtype
its documentation gives, and the value its name says, computed here from the reduced system
(by the field-wise DOFs, not by the integrator's code). No structure is built by position
anywhere in the package, so two operands of the same shape cannot be exchanged.
"""
from __future__ import annotations

import ast
from pathlib import Path

import numpy as np
import pytest

from drill_twin.integrator import bit_solve, newmark_kernel, step_operands
from drill_twin.integrator.newmark import NewmarkIntegrator
from drill_twin.integrator.newmark_operands import BatchWork
from drill_twin.model.forces import NonlinearForces
from drill_twin.model.reduced_system import build_reduced_system

MEMBERS = 3
PACKAGE = Path(step_operands.__file__).resolve().parents[1]
BLOCK_NAMES = ('axial', 'torsional', 'bending_y', 'bending_z')


@pytest.fixture(scope='module')
def integrator(default_config, default_analysis):
    model, _, basis = default_analysis
    system = build_reduced_system(model, basis)
    rng = np.random.default_rng(11)
    germ = np.eye(2) + 0.05 * rng.standard_normal((MEMBERS, 2, 2))
    scales = np.exp(0.1 * rng.standard_normal((MEMBERS, 5)))
    integration = default_config.integration
    return NewmarkIntegrator(NonlinearForces(system), integration.time_step_s,
                             integration.tolerance, integration.max_iterations, germ, scales)


def _sizes(integrator):
    system = integrator.system
    return system.size, system.n_nodes, system.n_dofs


def _check(structure, expected):
    """Every field of ``structure`` has the (shape, dtype) of ``expected`` (a dict by name)."""
    assert set(structure._fields) == set(expected)
    for name, (shape, dtype) in expected.items():
        value = getattr(structure, name)
        assert np.shape(value) == shape, name
        assert np.asarray(value).dtype == dtype, name
        if isinstance(value, np.ndarray):
            assert value.flags.c_contiguous, name


def test_the_operators_have_their_documented_shapes(integrator):
    n, nodes, dofs = _sizes(integrator)
    operators = integrator.operators
    local_count = 3 + 2 * nodes
    _check(operators.local, {'directions': ((n, local_count), float),
                             'response': ((n, local_count), float),
                             'gram': ((local_count, local_count), float),
                             'bit_rows': ((2, n), float), 'bit_response': ((n, 2), float),
                             'bit_flexibility': ((2, 2), float), 'bit_axial_row': ((n,), float)})
    _check(operators.load, {'mass_driven': ((n,), float), 'damping_driven': ((n,), float),
                            'top_axial_row': ((n,), float), 'static_hook_n': ((), float)})
    _check(operators.scheme, {'time_step_s': ((), float), 'beta_dt2': ((), float),
                              'tolerance': ((), float), 'max_iterations': ((), int)})
    linear = operators.linear
    assert linear.mass.shape == linear.stiffness.shape == (n, n)
    assert linear.stiffness_diagonal.shape in ((n,), (0,))
    assert linear.groups.shape == (4, 2) and linear.groups.dtype == np.int64
    basis = operators.basis
    assert basis.ranges.shape == (4, 4) and basis.ranges.dtype == np.int64
    law = integrator._law
    _check(law._replace(pattern=None), {
        'static_force_n': ((), float), 'bit_rock': ((), bool), 'rows': ((MEMBERS, 8), float),
        'fade_speeds': ((MEMBERS,), float), 'germs': ((MEMBERS, 2, 2), float),
        'random': ((), bool), 'pattern': ((), object)})


def test_the_operators_are_what_their_names_say(integrator):
    """Against the field-wise DOFs: Phi q read at the bit, the nodes and the top."""
    system, operators = integrator.system, integrator.operators
    n, nodes, _ = _sizes(integrator)
    q = np.random.default_rng(3).standard_normal((4, n))
    u = system.physical(q)
    axial, torsion = system.field(0), system.field(1)
    v, w = system.field(2), system.field(4)
    basis, local = operators.basis, operators.local
    assert (basis.bit_axial_dof, basis.bit_torsion_dof) == (axial.start + system.bit_node,
                                                            torsion.start + system.bit_node)
    assert (basis.n_nodes, basis.bit_node) == (nodes, system.bit_node)
    for b, name in enumerate(BLOCK_NAMES):
        block = system.blocks[name]
        np.testing.assert_array_equal(basis.shapes[b], block.shapes)
        np.testing.assert_array_equal(basis.shapes_t[b], block.shapes_t)
        assert tuple(basis.ranges[b]) == (block.rows.start, block.rows.stop,
                                          block.columns.start, block.columns.stop)
    expected = np.concatenate([u[:, [basis.bit_axial_dof, basis.bit_torsion_dof]], u[:, v],
                               u[:, w], np.zeros((4, 1))], axis=1)
    scale = np.abs(u).max()
    np.testing.assert_allclose(q @ local.directions, expected, rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(q @ local.bit_rows.T, expected[:, :2], rtol=0, atol=1e-12 * scale)
    np.testing.assert_allclose(q @ local.bit_axial_row, u[:, basis.bit_axial_dof], rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(q @ operators.load.top_axial_row, u[:, axial.start], rtol=0,
                               atol=1e-12 * scale)


def test_the_step_matrix_and_its_responses(integrator):
    """S0 = M + dt/2 C + dt^2/4 K (average acceleration); S0^-1 by blocks and on U."""
    system, operators = integrator.system, integrator.operators
    dt = integrator.time_step_s
    effective = system.mass + 0.5 * dt * system.damping + 0.25 * dt * dt * system.stiffness
    linear, local = operators.linear, operators.local
    inverse = np.zeros_like(effective)
    damping = np.zeros_like(effective)
    for (start, stop), block, c_block in zip(linear.groups, linear.inverse, linear.damping):
        inverse[start:stop, start:stop] = block
        damping[start:stop, start:stop] = c_block
    np.testing.assert_allclose(inverse @ effective, np.eye(system.size), rtol=0, atol=1e-12)
    np.testing.assert_array_equal(damping, system.damping)
    np.testing.assert_array_equal(linear.mass, system.mass)
    np.testing.assert_array_equal(linear.stiffness, system.stiffness)
    if linear.stiffness_diagonal.size:                 # diagonal within 1e-9 of its largest
        stiffness = system.stiffness
        np.testing.assert_array_equal(linear.stiffness_diagonal, np.diag(stiffness))
        np.testing.assert_allclose(np.diag(linear.stiffness_diagonal), stiffness, rtol=0,
                                   atol=1e-9 * np.abs(stiffness).max())
    scale = np.abs(local.directions).max()
    np.testing.assert_allclose(effective @ local.response, local.directions, rtol=0,
                               atol=1e-12 * scale)
    np.testing.assert_allclose(local.gram, local.directions.T @ local.response, rtol=1e-12,
                               atol=1e-15 * np.abs(local.gram).max())
    np.testing.assert_array_equal(local.bit_response, local.response[:, :2])
    np.testing.assert_array_equal(local.bit_flexibility, local.gram[:2, :2])
    assert operators.scheme.time_step_s == dt
    assert operators.scheme.beta_dt2 == pytest.approx(dt * dt / 4, rel=1e-15)


def test_the_driven_load_and_the_law(integrator, default_config):
    """g(t) of the top drive and the hook, against its formula; the law of the germs."""
    system, operators = integrator.system, integrator.operators
    load = operators.load
    rows = system.driven_rows
    np.testing.assert_allclose(load.mass_driven, system.project(rows['mass']), rtol=1e-10,
                               atol=1e-12 * np.abs(load.mass_driven).max())
    np.testing.assert_allclose(load.damping_driven, system.project(rows['damping']),
                               rtol=1e-10, atol=1e-12 * np.abs(load.damping_driven).max())
    assert load.static_hook_n == system.model.prestress.hook_load_n
    speed, acceleration, hooks = 5.2, 0.7, np.array([1.1e6, 0.9e6, 1.0e6])
    computed = np.empty((system.size, MEMBERS))
    newmark_kernel.external_load(step_operands.StepInputs(
        top_speed=speed, top_acceleration=acceleration, hooks=hooks), load, computed)
    expected = (-(load.mass_driven * acceleration + load.damping_driven * speed)[:, None]
                - np.outer(load.top_axial_row, hooks - load.static_hook_n))
    np.testing.assert_allclose(computed, expected, rtol=1e-13, atol=1e-9)
    law = integrator._law
    np.testing.assert_array_equal(law.rows, integrator.forces.law.rows(integrator.law_scales))
    np.testing.assert_array_equal(law.germs, integrator.germ)
    assert law.random and law.bit_rock
    assert law.static_force_n == default_config.bit_rock.static_weight_on_bit_n


def test_the_work_arrays_have_their_documented_shapes(integrator):
    n, nodes, dofs = _sizes(integrator)
    m = MEMBERS
    work = BatchWork(integrator.forces, m)
    _check(work.modal, {name: ((n, m), float) for name in step_operands.ModalWork._fields})
    _check(work.members, {
        'touch': ((m,), float), 'hole': ((m,), float), 'error': ((m,), float),
        'previous_error': ((m,), float), 'active': ((m,), bool), 'bit_ok': ((m,), bool),
        'due': ((m,), bool), 'on_wall': ((m,), bool), 'scratch': ((6, m), float),
        'responses': ((m, n, 2), float), 'flexibilities': ((m, 2, 2), float)})
    _check(work.force_work, {
        'displacement_t': ((dofs, m), float), 'theta_x_rate_t': ((nodes, m), float),
        'theta_x_acceleration_t': ((nodes, m), float),
        'bending_y_rate_t': ((2 * nodes, m), float),
        'bending_y_acceleration_t': ((2 * nodes, m), float),
        'bending_z_rate_t': ((2 * nodes, m), float),
        'bending_z_acceleration_t': ((2 * nodes, m), float), 'strain': ((9, m), float),
        'linear': ((8, m), float), 'stress': ((9, m), float), 'coupling': ((9, m), float),
        'force_t': ((dofs, m), float), 'radial': ((m, nodes), float),
        'in_contact': ((m, nodes), bool), 'tangent': ((m, nodes, 2, 2), float)})
    _check(work.outputs.take(), {
        'q': ((m, n), float), 'q_rate': ((m, n), float), 'q_acceleration': ((m, n), float),
        'hole': ((m,), float), 'finite': ((m,), bool), 'converged': ((m,), bool),
        'on_bottom': ((m,), bool), 'error': ((m,), float), 'full': ((dofs, m), float),
        'modal': ((n, m), float), 'radial': ((m, nodes), float), 'rop': ((m,), float),
        'omega': ((m,), float), 'force': ((m,), float), 'torque': ((m,), float),
        'jacobian': ((m, 2, 2), float)})
    _check(work.kept.take(), {'saved_rate': ((m,), float), 'contact': ((m, nodes), bool),
                              'lifted': ((m,), bool)})
    assert work.final_tangent.shape == (m, nodes, 2, 2)
    assert work.final_solved.shape == (m,) and work.final_solved.dtype == bool


def _structures():
    """Return the names of the structures of the compiled step and of the bit's solve."""
    return {name for module in (step_operands, bit_solve)
            for name, value in vars(module).items()
            if isinstance(value, type) and issubclass(value, tuple) and hasattr(value, '_fields')}


def test_no_structure_is_built_by_position():
    """
    Every structure of the step is built by keyword (or as ``Class(*tuple(structure))``).

    Read from the source of every module of the package: a positional argument to one of
    the structures' classes, or to make_step_operands, fails this test.
    """
    names = _structures() | {'make_step_operands'}
    assert {'StepOperators', 'ModalWork', 'BitEquation', 'StepOutputs'} <= names
    found = []
    for path in sorted(PACKAGE.rglob('*.py')):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if not isinstance(node, ast.Call):
                continue
            called = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(
                node.func, 'id', None)
            if called not in names:
                continue
            starred_only = len(node.args) == 1 and isinstance(node.args[0], ast.Starred)
            if node.args and not starred_only:
                found.append(f'{path.relative_to(PACKAGE)}:{node.lineno} {called}')
    assert not found, found
