"""
The twin's wall-contact events (docs/LATERAL.md, "Contact and lift-off episodes").

One impact per contact episode of a node, with its depth, and the episode's peak force when it
ends, not one per step a node chattering on the wall starts touching.
"""
from __future__ import annotations

from dataclasses import replace

import pytest
from imbalanced_string import imbalanced_string as _config

from drill_twin.twin.engine import EnsembleSettings, TwinEngine


def test_a_whirling_bha_gives_one_impact_event_per_contact_episode():
    """
    The twin's 'impact' and 'contact_end' events are the wall's contact episodes.

    The coarse string at its BHA resonance with an imbalance whose free orbit overshoots
    the wall (test_contact_events): the mean model's 'impact' events are its contact
    episodes, each with the node's depth, fewer than the raw contact onsets; every
    'contact_end' carries the episode's peak force (k_ip times its peak penetration) and its
    duration.
    """
    config = _config(4.44, contact=True, time_step_s=0.005)
    imbalance = replace(config.excitation.imbalance, mass_kg=4000.0, eccentricity_m=0.1)
    config = replace(config, excitation=replace(config.excitation, imbalance=imbalance))
    engine = TwinEngine(config, EnsembleSettings(members=0))
    events = []
    try:
        for _ in range(20):
            events += engine.advance(100).events
    finally:
        engine.close()
    simulator = engine.simulator
    impacts = [e for e in events if e.kind == 'impact']
    ends = [e for e in events if e.kind == 'contact_end']
    assert not [e for e in events if e.kind in ('diverged', 'implausible')]
    assert len(impacts) == simulator.impact_count[0] > 0
    assert len(impacts) < simulator.contact_onset_count[0]
    assert 0 < len(ends) <= len(impacts)
    assert all(1400.0 < float(e.values['x_m']) <= 1600.0 for e in impacts)
    stiffness = config.borehole.contact_stiffness_n_per_m
    for end in ends:
        peak, depth = float(end.values['peak_force_n']), float(end.values['peak_penetration_m'])
        assert peak > 0 and peak == pytest.approx(stiffness * depth, rel=1e-5)
        assert float(end.values['duration_s']) > 0
