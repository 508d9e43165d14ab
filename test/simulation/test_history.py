"""The recorder of observations (drill_twin.simulation.history): what goes in comes out."""
import dataclasses

from pathlib import Path

import numpy as np

from drill_twin.config import load_config

from drill_twin.integrator.simulator import Observation
from drill_twin.simulation.history import (BIT_CHANNELS, SHARED_CHANNELS, STATION_RECORDS,
                                           History)

REPO = Path(__file__).resolve().parents[2]


def _observation(rng, time_s, members, stations, nodes):
    """Return an Observation of random values (flags random too) at ``time_s``."""
    values = {}
    for field in dataclasses.fields(Observation):
        name = field.name
        if name == 'time_s':
            values[name] = time_s
        elif name in ('top_speed_rad_per_s', 'top_angle_rad', 'hook_load_n'):
            values[name] = float(rng.normal())
        elif name in ('lifted', 'on_bottom'):
            values[name] = rng.random(members) < 0.5
        elif name == 'in_contact':
            values[name] = rng.random((members, nodes)) < 0.3
        elif name == 'contact_force_n':
            values[name] = rng.random((members, nodes))
        elif name in STATION_RECORDS:
            values[name] = rng.normal(size=(members, stations, 3))
        else:
            values[name] = rng.normal(size=members)
    return Observation(**values)


def test_every_channel_comes_out_time_last_as_it_was_recorded():
    rng = np.random.default_rng(4)
    members, stations, nodes, samples = 3, 2, 5, 4
    history = History(members, stations, samples + 2, 0.01, [100.0, 700.0])
    seen = [_observation(rng, 0.01 * k, members, stations, nodes) for k in range(samples)]
    for observation in seen:
        history.record(observation)
    result = history.result([1, 2, 3], [0, 1, 0], steps=4, iterations=5, wall_time_s=1.0)
    np.testing.assert_array_equal(result.time_s, [0.0, 0.01, 0.02, 0.03])
    for name, attribute in BIT_CHANNELS.items():
        expected = np.stack([getattr(o, attribute) for o in seen], axis=-1)
        assert result.channels[name].shape == (members, samples)
        np.testing.assert_array_equal(result.channels[name], expected)
    assert result.channels['bit_on_bottom'].dtype == bool
    np.testing.assert_array_equal(result.channels['contact_nodes'],
                                  np.stack([o.in_contact.sum(axis=1) for o in seen], axis=-1))
    np.testing.assert_array_equal(result.channels['max_contact_force_n'],
                                  np.stack([o.contact_force_n.max(axis=1) for o in seen], -1))
    for name, attribute in SHARED_CHANNELS.items():
        np.testing.assert_array_equal(result.shared[name], [getattr(o, attribute) for o in seen])
    for name in STATION_RECORDS:
        recorded = getattr(result, name)
        assert recorded.shape == (members, stations, 3, samples)
        assert recorded.flags.c_contiguous
        np.testing.assert_array_equal(recorded, np.stack([getattr(o, name) for o in seen], -1))


def test_the_simulator_records_what_it_observes():
    """record_simulator writes what record(observe()) writes, bit for bit, on and off the wall."""
    from drill_twin.integrator.simulator import Simulator
    from drill_twin.uncertainty.germ import germs_for_realizations

    members = 3                  # an imbalance of m e = 400 kg m at 1500 m: on the wall at 0.3 s
    config = load_config(REPO / 'config' / 'ritto2009_lateral.yaml',
                         ['excitation.imbalance.mass_kg=8000.0'])
    simulator = Simulator(config, members=members,
                          germs=germs_for_realizations(0.1, 5, range(members)))
    stations = [s.x_m for s in simulator.system.stations]
    direct, observed = (History(members, len(stations), 40, simulator.dt, stations)
                        for _ in range(2))
    touched = 0
    for _ in range(40):
        for _ in range(4):
            simulator.step()
        direct.record_simulator(simulator)
        observed.record(simulator.observe())
        touched += int(simulator.last.contact.in_contact.any())
    assert touched > 0                                  # the wall's channels are exercised
    first, second = (h.result([0] * members, [0] * members, 1, 1, 1.0) for h in (direct,
                                                                                 observed))
    np.testing.assert_array_equal(first.time_s, second.time_s)
    assert first.channels.keys() == second.channels.keys()
    for name in first.channels:
        assert first.channels[name].dtype == second.channels[name].dtype
        np.testing.assert_array_equal(first.channels[name], second.channels[name])
    for name in first.shared:
        np.testing.assert_array_equal(first.shared[name], second.shared[name])
    for name in STATION_RECORDS:
        np.testing.assert_array_equal(getattr(first, name), getattr(second, name))


def test_the_recorded_stations_follow_the_newmark_kinematics():
    """
    Each station record is read from its own state vector, as the integrator's kinematics say.

    Average-acceleration Newmark (beta 1/4, gamma 1/2) makes d_n+1 - d_n = dt (v_n + v_n+1) / 2
    and v_n+1 - v_n = dt (a_n + a_n+1) / 2 exactly; the stations' (u, v, w) are linear in q,
    so their records obey it too.
    """
    from drill_twin.simulation.run import run_simulation

    # Whole steps only: a step that touches or leaves the wall is otherwise integrated on
    # sub-steps (integration.contact_substeps), a trapezoid on each.
    config = load_config(REPO / 'config' / 'ritto2009_lateral.yaml',
                         ['excitation.imbalance.mass_kg=8000.0',
                          'integration.contact_substeps=1'])
    dt = config.integration.time_step_s
    result = run_simulation(config, 150 * dt, record_interval_s=dt)
    assert result.channels['contact_nodes'].any()  # on the wall too
    assert result.retries == 0                     # every record one whole step apart
    for position, rate in ((result.station_displacement_m, result.station_velocity_m_per_s),
                           (result.station_velocity_m_per_s,
                            result.station_acceleration_m_per_s2)):
        step = np.diff(position, axis=-1)
        trapezoid = 0.5 * dt * (rate[..., 1:] + rate[..., :-1])
        scale = np.max(np.abs(step))
        assert scale > 0.0
        np.testing.assert_allclose(step, trapezoid, rtol=0.0, atol=1e-9 * scale)
    assert np.max(np.abs(result.station_displacement_m[0, :, 1:])) > 1e-4    # it whirls
