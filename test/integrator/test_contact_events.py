"""
Wall contact under sustained whirl (docs/LATERAL.md, "Contact and lift-off episodes").

The contact force never does net positive work, the wall holds the string within a bounded
penetration, and events are one per contact episode (hysteresis), with node depth and peak
force.
"""
from __future__ import annotations

from dataclasses import replace
from types import SimpleNamespace

import numpy as np
import pytest
from imbalanced_string import imbalanced_string as _config

from drill_twin.model.contact import contact_force
from drill_twin.integrator.contact_events import (ContactEpisodes, LiftOffEpisodes,
                                                  event_rate_per_s, radial_gap_m)
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig
from drill_twin.analysis.harmonic import forced_whirl
from drill_twin.simulation.summary import summarize


def test_a_chattering_contact_is_one_episode():
    depth = np.array([0.0, 800.0, 1600.0])
    episodes = ContactEpisodes(2, depth, release_m=1e-3)
    # Member 0, node 1 grazes the wall: in, out by less than the release, in again, then away.
    gaps = [2e-4, -5e-4, 3e-4, -2e-4, 1e-4, -2e-3, 4e-4, -3e-3]
    forces = [1e8 * max(g, 0.0) for g in gaps]
    opened, closed = [], []
    for step, (gap, force) in enumerate(zip(gaps, forces)):
        g = np.full((2, 3), -0.05)
        f = np.zeros((2, 3))
        g[0, 1], f[0, 1] = gap, force
        episodes.update(0.01 * step, g, f)
        opened += episodes.opened
        closed += episodes.closed
    assert episodes.count.tolist() == [2, 0]            # two episodes, not four onsets
    assert [e.start_s for e in opened] == pytest.approx([0.0, 0.06])
    first = closed[0]
    assert (first.node, first.depth_m, first.end_s) == (1, 800.0, pytest.approx(0.05))
    assert first.peak_force_n == pytest.approx(3e4)
    assert first.peak_penetration_m == pytest.approx(3e-4)
    assert len(episodes.history) == 2 and not episodes.open_events
    assert event_rate_per_s([0, 0], episodes.count, 0.08).tolist() == [25.0, 0.0]


def test_an_untouched_step_changes_nothing_and_is_refused_while_an_episode_is_open():
    episodes = ContactEpisodes(1, np.array([0.0, 800.0]), release_m=1e-3)
    gap = np.array([[-0.05, 2e-4]])
    episodes.update(0.0, gap, 1e8 * np.maximum(gap, 0.0))
    assert episodes.any_open and episodes.opened
    with pytest.raises(ValueError, match='open'):
        episodes.update_untouched()                    # the open episode needs its gap
    episodes.update(0.01, np.full((1, 2), -0.05), np.zeros((1, 2)))
    assert not episodes.any_open and episodes.closed
    episodes.update_untouched()
    assert (episodes.opened, episodes.closed, episodes.count.tolist()) == ([], [], [1])


def test_a_bit_touching_without_reload_is_one_lift_off():
    episodes = LiftOffEpisodes(1, release_n=1e3)
    sequence = [(False, -1e5), (True, 0.0), (False, -200.0), (True, 0.0), (False, -5e3),
                (False, -1e5), (True, 0.0)]
    for lifted, force in sequence:
        episodes.update(np.array([lifted]), np.array([force]))
    assert episodes.count.tolist() == [2]
    with pytest.raises(ValueError, match='release_n'):
        LiftOffEpisodes(1, release_n=-1.0)


def _whirl_at_the_wall(friction, unbalance_kg_m=400.0, duration_s=10.0):
    """
    Run the coarse string at its BHA resonance with an imbalance that overshoots the wall.

    The imbalance's free orbit overshoots the wall; returns the running dissipation of the
    wall, the energy it passed, the largest penetration, the closed-form free orbit, the
    clearance and the episode tracker.
    """
    spin = 4.44
    config = _config(spin, contact=True, time_step_s=0.005)
    imbalance = replace(config.excitation.imbalance, mass_kg=unbalance_kg_m / 0.1,
                        eccentricity_m=0.1)
    config = replace(config, excitation=replace(config.excitation, imbalance=imbalance),
                     borehole=replace(config.borehole, friction_coefficient=friction))
    simulator = Simulator(config)
    system, borehole = simulator.system, config.borehole
    stiffness = borehole.contact_stiffness_n_per_m
    episodes = ContactEpisodes(1, system.model.mesh.node_x_m)

    def wall():
        u = system.physical(simulator.state.q)
        spin_rate = (system.physical(simulator.state.q_rate)[:, system.field(1)]
                     + simulator.state.top_speed_rad_per_s)
        force, contact, _ = contact_force(system, stiffness, friction,
                                          borehole.friction_regularization_rad_per_s,
                                          SimpleNamespace(displacement=u,
                                                          theta_x_rate=spin_rate))
        position = u[0].copy()
        position[system.field(1)] += simulator.state.top_angle_rad       # absolute angle
        gap = radial_gap_m(system, u)
        potential = 0.5 * stiffness * np.sum(np.maximum(gap, 0.0) ** 2)
        return position, force[0], potential, gap, contact.radial_force_n

    position, force, potential_0, _, _ = wall()
    work = passed = deepest = 0.0
    dissipation = []
    for _ in range(int(round(duration_s / simulator.dt))):
        simulator.step()
        new_position, new_force, potential, gap, radial = wall()
        # Work over the step along the trapezoidal rule's path (Newmark average acceleration).
        step_work = 0.5 * (force + new_force) @ (new_position - position)
        work += step_work
        passed += abs(step_work)
        dissipation.append(-(work + potential - potential_0))
        deepest = max(deepest, float(gap.max()))
        episodes.update(simulator.state.time_s, gap, radial)
        position, force = new_position, new_force
    force_model = simulator.forces.imbalance
    free = forced_whirl(system.model, force_model.node, force_model.unbalance_kg_m, spin)
    clearance = float(system.clearance_m[force_model.node])
    return (np.array(dissipation), passed, deepest, free, clearance, episodes, simulator)


@pytest.mark.parametrize('friction', [0.0, 0.3])
def test_the_wall_never_does_net_positive_work(friction):
    """
    The wall only dissipates, and holds the BHA within a small penetration.

    Dissipation of the wall D(t) = -(W_contact(0, t) + V(t) - V(0)) with V = k_ip p^2 / 2
    the penalty's stored energy: D >= 0 at all times (the radial force is conservative, the
    rubbing torque only dissipates). Without friction the wall loses less than 1 % of the
    energy it exchanges (the trapezoidal rule's error at the kinks); with mu = 0.3 it
    dissipates. The wall holds a BHA whose free orbit overshoots it by centimetres within a
    penetration below 2 mm, and the episodes are fewer than the raw contact onsets.
    """
    dissipation, passed, deepest, free, clearance, episodes, simulator = _whirl_at_the_wall(
        friction)
    onsets = int(simulator.contact_onset_count[0])
    assert free.radius_m > clearance + 0.03                 # the free orbit would be outside
    assert passed > 1e3                                       # the wall really works (J)
    assert dissipation.min() >= -1e-6 * passed
    if friction == 0.0:
        assert dissipation[-1] < 0.01 * passed
    else:
        assert dissipation[-1] > 0.5 * passed                 # rubbing takes most of it
    assert 0.0 < deepest < 2e-3
    assert 0 < episodes.count[0] <= onsets
    events = episodes.history + episodes.open_events
    assert all(e.peak_force_n == pytest.approx(1e8 * e.peak_penetration_m) for e in events)
    assert all(1400.0 < e.depth_m <= 1600.0 for e in events)    # in the BHA
    # The Simulator's own tracker, fed from the step's contact flags and forces (the gap
    # computed only where an open episode no longer touches), counts the same episodes as
    # this one, fed with the full gap of the end-of-step state.
    assert simulator.impact_count.tolist() == episodes.count.tolist()
    assert episodes.count[0] < onsets                       # fewer than the raw onsets


def test_the_simulator_counts_a_bit_lift_off_once_and_the_summary_gives_rates():
    """
    Pulled up by a hook load far above the string's weight, the bit leaves the rock.

    The Simulator's lift-off tracker (hysteresis: test above) counts one episode, in progress;
    the summary turns the running counts into counts and rates in its window.
    """
    config = _config(2.0, bit_rock=True)
    simulator = Simulator(config)
    rig = Rig(simulator)
    assert simulator.lift_off_count.tolist() == [0]
    rig.set_hook_load(rig.hook_load_command_n + 5e5)
    lifted = []
    for _ in range(200):
        rig.step()
        lifted.append(bool(simulator.last.lifted[0]))
    assert lifted[-1] and simulator.lift_off_count.tolist() == [1]
    assert simulator.lift_off_episodes.lifted[0]
    time = np.arange(11) * 0.5
    result = SimpleNamespace(
        time_s=time, window=lambda seconds: time >= time[-1] - seconds - 1e-9,
        channels={'impacts_so_far': np.array([[0, 1, 1, 3, 3, 3, 4, 6, 6, 6, 9]]),
                  'lift_offs_so_far': np.array([[0] * 8 + [1, 1, 1]]),
                  'landings_so_far': np.zeros((1, 11), dtype=int),
                  **{name: np.ones((1, 11)) for name in (
                      'rop_m_per_s', 'bit_speed_rad_per_s', 'weight_on_bit_n',
                      'torque_on_bit_nm')}},
        impact_count=np.array([9]), lift_off_count=np.array([1]), retries=0,
        real_time_factor=1.0, time_step_s=0.5)
    summary = summarize(result, 2.0, 0.3)
    assert summary['window_s'] == 2.0
    assert (summary['impact_count'], summary['lift_off_count']) == (5, 1)
    assert summary['impact_rate_per_s'] == 2.5 and summary['lift_off_rate_per_s'] == 0.5
    assert summary['impact_count_whole_run'] == 9
