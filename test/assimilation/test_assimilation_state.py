"""The analysed state of a batch: germ coordinates, reading and writing members back."""
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from drill_twin.assimilation.measurements import channel_values, sample_times
from drill_twin.assimilation.state import (MemberState, coordinates_to_germ,
                                           germ_to_coordinates)
from drill_twin.uncertainty.germ import germs_for_realizations

SMALL = ['sections.drill_pipe.elements=8', 'sections.drill_collar.elements=4',
         'reduced_basis.lateral_modes=6']


@settings(max_examples=50, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=3, max_size=3))
def test_any_coordinates_give_a_positive_definite_germ_and_back(values):
    coordinates = np.array([values])
    germ = coordinates_to_germ(coordinates)
    np.testing.assert_allclose(germ, np.swapaxes(germ, 1, 2))
    assert np.all(np.linalg.eigvalsh(germ) > 0)
    np.testing.assert_allclose(germ_to_coordinates(germ), coordinates, atol=1e-9)


def test_the_identity_germ_is_the_origin():
    np.testing.assert_allclose(germ_to_coordinates(np.eye(2)[None]), 0.0, atol=1e-15)


def _small_simulator():
    """Six members (three germs twice) of the small string, 100 steps on."""
    from drill_twin.config import load_config
    from drill_twin.integrator.simulator import Simulator

    config = load_config(None, SMALL)
    germs = germs_for_realizations(0.2, 0, range(3))
    sim = Simulator(config, 6, germs=np.concatenate([germs, germs]))
    for _ in range(100):
        sim.step()
    return sim


@pytest.fixture(scope='module')
def small_simulator():
    return _small_simulator()


def test_writing_the_state_read_changes_nothing(small_simulator):
    sim = small_simulator
    members = MemberState(sim, 3, ('axial', 'torsional'))
    before = sim.state.copy()
    speed = sim.observe().speed_rad_per_s.copy()
    members.write(members.extract())
    np.testing.assert_allclose(sim.state.q, before.q, atol=1e-12)
    np.testing.assert_allclose(sim.state.q_rate, before.q_rate, atol=1e-12)
    np.testing.assert_allclose(sim.state.hole_u, before.hole_u, atol=1e-12)
    np.testing.assert_allclose(sim.observe().speed_rad_per_s, speed, atol=1e-9)


def test_a_written_state_is_what_is_read_and_the_rest_is_untouched(small_simulator):
    sim = small_simulator
    members = MemberState(sim, 3, ('torsional',))
    before = sim.state.copy()
    germ_before = sim.integrator.germ.copy()
    vectors = members.extract()
    k = members.columns.size
    vectors[:, k:2 * k] += 0.1                               # torsional rates
    vectors[:, -3:] = 0.0                                    # germ = identity
    members.write(vectors)
    after = members.extract()
    np.testing.assert_allclose(after[:, :2 * k], vectors[:, :2 * k], atol=1e-12)
    np.testing.assert_allclose(members.germs(), np.broadcast_to(np.eye(2), (3, 2, 2)),
                               atol=1e-12)
    np.testing.assert_allclose(sim.state.q[3:], before.q[3:])           # open-loop members
    np.testing.assert_allclose(sim.state.q_rate[3:], before.q_rate[3:])
    np.testing.assert_allclose(sim.integrator.germ[3:], germ_before[3:])
    sim.step()                                               # and it integrates on
    assert np.all(np.isfinite(sim.state.q))


def test_a_member_on_bottom_stays_on_bottom(small_simulator):
    sim = small_simulator
    members = MemberState(sim, 3, ('axial', 'torsional'))
    on = sim.on_bottom()[:3].copy()
    vectors = members.extract()
    vectors[:, 2 * members.columns.size] = 0.5                # ask for a hole 0.5 m deeper
    members.write(vectors)
    np.testing.assert_array_equal(sim.on_bottom()[:3], on)


def test_channels_read_the_observation_with_a_drillers_signs(small_simulator):
    o = small_simulator.observe()
    np.testing.assert_allclose(channel_values(o, 'torque_on_bit', 2), -o.torque_on_bit_nm[:2])
    np.testing.assert_allclose(channel_values(o, 'weight_on_bit', 2), -o.weight_on_bit_n[:2])
    assert np.all(channel_values(o, 'weight_on_bit', 6)[~o.lifted] > 0)
    np.testing.assert_allclose(channel_values(o, 'top_speed', 3), o.top_speed_rad_per_s)


def test_sample_times_are_the_rate_multiples_within_the_log():
    np.testing.assert_allclose(sample_times(4.0, 1.0), [0.25, 0.5, 0.75, 1.0])
    assert sample_times(0.2, 4.9).size == 0


def test_the_steady_point_of_the_mean_law_is_its_closed_form(default_config):
    from drill_twin.assimilation.steady_law import steady_point
    from drill_twin.model.bit_rock import BitRockLaw

    law = BitRockLaw.from_config(default_config.bit_rock)
    omega, wob = 5.2, 100e3
    rop, tob = steady_point(law, omega, wob)
    np.testing.assert_allclose(rop, law.steady_rop(omega, -wob), rtol=1e-9)
    np.testing.assert_allclose(-tob, law.steady_torque(omega, -wob), rtol=1e-9)
    # A germ G = diag(g11, g22) scales the forces, F1 = g11 f and F2 = g22 t, but for the
    # blend into the mean law near ROP = 0 (weight 0.998 at 2.5 mm/s: within 0.5 %).
    germ = np.diag([1.2, 0.8])
    rop_g, tob_g = steady_point(law, omega, wob, germ)
    np.testing.assert_allclose(rop_g, law.steady_rop(omega, -wob / 1.2), rtol=5e-3)
    np.testing.assert_allclose(-tob_g, 0.8 * law.steady_torque(omega, -wob / 1.2), rtol=5e-3)


def test_the_bit_speed_direction_changes_the_bit_speed_by_one(small_simulator):
    sim = small_simulator
    members = MemberState(sim, 3, ('axial', 'torsional'))
    before = sim.observe().speed_rad_per_s.copy()
    members.write(members.extract() + 0.5 * members.bit_speed_direction())
    after = sim.observe().speed_rad_per_s
    np.testing.assert_allclose(after[:3] - before[:3], 0.5, atol=1e-9)
    np.testing.assert_allclose(after[3:], before[3:], atol=1e-12)


def test_a_germ_near_singular_has_finite_coordinates():
    """G22 - L12^2 lost to rounding: the coordinates stay finite (L22 floored)."""
    l12 = 3.0
    germ = np.array([[[1.0, l12], [l12, l12 * l12 * (1.0 + 1e-17)]]])
    coordinates = germ_to_coordinates(germ)
    assert np.all(np.isfinite(coordinates))
    np.testing.assert_allclose(coordinates_to_germ(coordinates), germ, rtol=1e-5)


def test_an_analysed_germ_is_kept_within_bounds_and_a_nan_state_is_refused(small_simulator):
    from drill_twin.assimilation.state import GERM_DIAGONAL_LIMIT
    state = MemberState(small_simulator, 3, ['axial', 'torsional'])
    vectors = state.extract()
    before = small_simulator.integrator.germ.copy()
    bad = vectors.copy()
    bad[0, 0] = np.nan
    with pytest.raises(ValueError, match='not finite'):
        state.write(bad)
    np.testing.assert_array_equal(small_simulator.integrator.germ, before)
    wild = vectors.copy()
    wild[:, -3:] = [[40.0, -50.0, -40.0], [0.0, 0.0, 0.0], [-1.0, 0.5, 1.0]]
    state.write(wild)
    germs = small_simulator.integrator.germ[:3]
    diagonal = np.concatenate([germs[:, 0, 0], np.linalg.eigvalsh(germs).ravel()])
    assert np.all(np.linalg.eigvalsh(germs) > 0)
    assert germs[0, 0, 0] == pytest.approx(GERM_DIAGONAL_LIMIT)
    np.testing.assert_allclose(germs[1], np.eye(2), atol=1e-15)
    np.testing.assert_allclose(germs[2], coordinates_to_germ(wild[2:, -3:])[0], rtol=1e-12)
    assert np.all(np.isfinite(diagonal))
    state.write(vectors)                                   # put the fixture back


def test_the_law_factors_are_read_written_bounded_and_change_the_members_law():
    """
    Parameters 'law': the germ's coordinates, then log a1 ... a5 factors per member.

    Written back, a member's factors are its integrator's (within LAW_SCALE_LIMIT), the
    other members keep theirs, and the members' law changes: the torque on bit of a member
    whose a5 doubled is evaluated with the doubled coefficient (at the force its rock bears).
    """
    from drill_twin.assimilation.state import LAW_SCALE_LIMIT, law_scales_for_members
    sim = _small_simulator()              # its own: the bits press the rock as a step leaves them
    state = MemberState(sim, 3, ['axial', 'torsional'], parameters='law')
    assert state.size == MemberState(sim, 3, ['axial', 'torsional']).size + 5
    vectors = state.extract()
    np.testing.assert_allclose(vectors[:, -5:], 0.0, atol=1e-15)    # the configured law
    np.testing.assert_allclose(vectors[:, -8:-5],
                               germ_to_coordinates(sim.integrator.germ[:3]), rtol=1e-12)
    law = vectors.copy()
    law[:, -5:] = [[0.0, 0.0, 0.0, 0.0, np.log(2.0)], [9.0, -9.0, 0.0, 0.0, 0.0],
                   [0.1, 0.2, 0.3, 0.4, 0.5]]
    state.write(law)
    scales = sim.integrator.law_scales
    np.testing.assert_allclose(scales[0], [1, 1, 1, 1, 2], rtol=1e-14)
    np.testing.assert_allclose(scales[1], [LAW_SCALE_LIMIT, 1 / LAW_SCALE_LIMIT, 1, 1, 1],
                               rtol=1e-14)
    np.testing.assert_allclose(np.log(scales[2]), law[2, -5:], rtol=1e-14)
    np.testing.assert_array_equal(scales[3:], 1.0)
    np.testing.assert_allclose(state.extract()[2, -5:], law[2, -5:], rtol=1e-14)
    # The law the members now have: Eq. 26 with a5 doubled for member 0.
    evaluation = sim.integrator.evaluate(sim.state)
    force, omega = evaluation.weight_on_bit_n[:1], evaluation.bit_speed_rad_per_s[:1]
    doubled = sim.law.scaled([1, 1, 1, 1, 2])
    germ = sim.integrator.germ[:1]
    expected = doubled.bearing_torque(force, omega, germ)[0]
    assert evaluation.torque_on_bit_nm[0] == pytest.approx(expected, rel=1e-12)
    assert expected != pytest.approx(sim.law.bearing_torque(force, omega, germ)[0], rel=1e-3)
    assert force[0] < -1e4
    prior = law_scales_for_members(0.15, 0, 2000)
    assert prior.shape == (2000, 5)
    assert np.std(np.log(prior)) == pytest.approx(0.15, rel=0.05)
    assert np.array_equal(prior, law_scales_for_members(0.15, 0, 2000))


def test_an_analysis_that_turns_the_bit_keeps_it_pressed_on_the_lobes():
    """
    On a lobed bottom the state's offset is the bit's distance to the surface under it.

    An analysis that changes the twist turns the bit over the lobes: the rock surface under it
    moves by up to 2 A; the member keeps pressing it by the depth it did (the hole's mean
    bottom moves instead), so no landing or lift-off is made up by the analysis.
    """
    from drill_twin.config import load_config
    from drill_twin.integrator.simulator import Simulator

    config = load_config(None, SMALL + ['excitation.bottom_hole_pattern.enabled=true',
                                        'excitation.bottom_hole_pattern.amplitude_m=0.001'])
    sim = Simulator(config, 3)
    for _ in range(100):
        sim.step()
    integrator = sim.integrator

    def surface_minus_bit():
        height = integrator.bottom_surface(sim.state)[0]
        return sim.hole_u() + height - sim.state.q @ integrator.bit_axial_row

    members = MemberState(sim, 3, ('torsional',), parameters='none')
    before = surface_minus_bit()
    assert np.all(sim.on_bottom()) and np.all(before < 0)       # pressed into the rock
    vectors = members.extract()
    vectors[:, :members.columns.size] *= 1.1                    # 10 % more twist
    angle_before = integrator.bit_rows[1] @ sim.state.q[0]
    members.write(vectors)
    turned = integrator.bit_rows[1] @ sim.state.q[0] - angle_before
    assert abs(np.sin(3 * turned / 2)) > 0.1                    # the lobes did move
    np.testing.assert_allclose(surface_minus_bit(), before, atol=1e-12)
