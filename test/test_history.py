"""The recorder of observations (drill_twin.simulation.history): what goes in comes out."""
import dataclasses

import numpy as np

from drill_twin.dynamics.simulator import Observation
from drill_twin.simulation.history import (BIT_CHANNELS, SHARED_CHANNELS, STATION_RECORDS,
                                           History)


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
