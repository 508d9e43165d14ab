"""
Wall friction drives backward whirl where rotordynamics says it should.

A collar pressed on the wall by a rotating imbalance, with the friction acting as a force at
the contact point (``borehole.tangential_friction``) and mu = 0.25, ends up rolling on the
wall: the pipe's surface does not slip, so its centre whirls backwards at the rolling speed

    omega_whirl = -Omega R_o / r        (r = clearance + penetration: "dry whip")

the kinematic closed form of rolling without slip (e.g. Jansen 1991, Black 1968). With the
paper's rubbing torque alone (friction brakes the spin but does not push the string sideways)
the same collar whirls forwards with the imbalance, as nothing can make it roll
(docs/LATERAL.md, "Friction at the wall and backward whirl").
"""
from __future__ import annotations

import numpy as np
import pytest

from drill_twin.config import load_config
from drill_twin.integrator.simulator import Simulator

SHORT = ['excitation.imbalance.enabled=true', 'excitation.imbalance.position_m=1500',
         'excitation.imbalance.mass_kg=4000', 'excitation.imbalance.eccentricity_m=0.05',
         'initial_conditions.steady_twist=true', 'initial_conditions.lateral_deflection_m=0',
         'reduced_basis.lateral_modes=40', 'borehole.friction_coefficient=0.25']
"""The paper's string with a strong imbalance (m e = 200 kg m at 1500 m) so that the BHA
reaches the wall within seconds, 40 lateral modes, steady drilling at the paper's speed."""


def _whirl_at_the_wall(tangential: bool, seconds: float = 10.0):
    """(whirl / spin, -R_o / r) of every (step, node) in contact over the last half."""
    config = load_config(None, SHORT + [f'borehole.tangential_friction={tangential}'])
    simulator = Simulator(config)
    system = simulator.system
    v_rows = system.field(2)
    w_rows = system.field(4)
    x_rows = system.field(1)
    radius = system.node_outer_radius_m
    ratios, rolling = [], []
    steps = int(round(seconds / simulator.dt))
    for step in range(steps):
        simulator.step()
        if step < steps // 2:
            continue
        contact = simulator.last.contact.in_contact[0]
        if not contact.any():
            continue
        state = simulator.state
        u = system.physical(state.q)[0]
        rate = system.physical(state.q_rate)[0]
        v, w = u[v_rows][contact], u[w_rows][contact]
        v_rate, w_rate = rate[v_rows][contact], rate[w_rows][contact]
        spin = state.top_speed_rad_per_s + rate[x_rows][contact]
        r2 = v * v + w * w
        ratios.extend((v * w_rate - w * v_rate) / r2 / spin)
        rolling.extend(-radius[contact] / np.sqrt(r2))
    return np.array(ratios), np.array(rolling)


def test_friction_at_the_contact_makes_the_collar_roll_backwards():
    ratio, rolling = _whirl_at_the_wall(tangential=True)
    assert ratio.size > 100                                  # it rides the wall
    assert np.mean(ratio < 0) > 0.9                          # backward whirl
    assert np.median(ratio) == pytest.approx(np.median(rolling), rel=0.03)


def test_the_papers_rubbing_torque_alone_does_not():
    ratio, _ = _whirl_at_the_wall(tangential=False)
    assert ratio.size > 0
    assert np.mean(ratio < 0) < 0.1                          # forward, with the imbalance
