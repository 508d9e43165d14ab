"""The twin's engine without ROS: transient divergence, member independence, KPIs, commands."""
from __future__ import annotations

import math
import re

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

from drill_twin.config import load_config
from drill_twin.analysis import kpi
from drill_twin.twin.engine import (CommandLimits, CommandRejected, EnsembleSettings,
                                    TwinEngine, TwinStalled)


@pytest.fixture(scope='module')
def config():
    return load_config(None, ['integration.time_step_s=0.01'])


def _engine(config, members=4):
    with threadpool_limits(limits=1, user_api='blas'):
        return TwinEngine(config, EnsembleSettings(members=members, dispersion=0.01, seed=3))


def test_a_diverged_member_is_restarted_and_the_others_go_on(config):
    """
    Corrupt one ensemble member's state.

    Its next step fails for it alone; it is restarted from a safe state at its depth, the step
    is retried and time advances; the other members and the mean model are exactly as in an
    undisturbed twin.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        disturbed, clean = _engine(config), _engine(config)
        for engine in (disturbed, clean):
            for _ in range(100):
                engine.advance(1)
        ensemble = disturbed.ensemble_runner.simulator      # members 1..4 at rows 0..3
        depth = ensemble.observe().depth_m[1]
        ensemble.state.q[1, 5] = np.nan                     # member 2, before its 100th step
        snapshot = disturbed.advance(1)                     # runs that step, starts the 101st
        clean.advance(1)
    events = [e for e in snapshot.events if e.kind == 'diverged']
    assert len(events) == 1 and events[0].level == 'warn'         # a member: WARN
    assert events[0].values['members'] == '2'
    assert 'ensemble members [2] diverged' in events[0].message
    assert snapshot.step == 101 and snapshot.ensemble_step == 100 and disturbed.resets == 1
    state = ensemble.state
    assert np.all(np.isfinite(state.q))
    drilled = ensemble.observe().depth_m[1] - depth
    assert 0 <= drilled < 1e-4                      # kept its depth, drilled on for 10 ms
    for row in (0, 2, 3):
        np.testing.assert_array_equal(state.q[row],
                                      clean.ensemble_runner.simulator.state.q[row])
    np.testing.assert_array_equal(disturbed.simulator.state.q, clean.simulator.state.q)
    assert snapshot.bit == clean.snapshot().bit


def test_an_ensemble_in_a_worker_process_computes_the_same_numbers(config):
    """
    The worker process receives the reduced system built here.

    Its members match the in-process ensemble bit for bit, one tick behind the mean model, under
    changing commands; the mean model does not depend on the ensemble at all.
    """
    with threadpool_limits(limits=1, user_api='blas'):
        local = _engine(config)
        alone = _engine(config, members=0)
        worker = TwinEngine(config, EnsembleSettings(members=4, dispersion=0.01, seed=3,
                                                     separate_process=True))
        try:
            for tick in range(60):
                if tick == 20:
                    for engine in (local, alone, worker):
                        engine.set_top_drive_speed(3.0)
                        engine.set_hook_load(engine.hook_load_command - 20e3)
                ours, theirs, mean_only = local.advance(2), worker.advance(2), alone.advance(2)
                assert ours.ensemble_step == theirs.ensemble_step == ours.step - 2
                assert ours.ensemble_mean == theirs.ensemble_mean
                assert ours.ensemble_lower == theirs.ensemble_lower
                assert ours.ensemble_upper == theirs.ensemble_upper
                assert ours.bit == theirs.bit == mean_only.bit
            assert ours.ensemble_mean != ours.bit           # the germs do act
        finally:
            worker.close()


def test_the_worker_starts_while_the_mean_model_builds_and_ends_if_that_fails(config,
                                                                              monkeypatch):
    """The engine starts the worker first (its imports overlap the mean model's build)."""
    from drill_twin.twin import engine as engine_module
    from drill_twin.twin import ensemble

    started = []

    class Recorded(ensemble.EnsembleProcess):
        def __init__(self):
            super().__init__()
            started.append(self)

    def broken_simulator(*args, **kwargs):
        assert started and started[0]._process.poll() is None    # the worker is starting
        raise RuntimeError('no model today')

    monkeypatch.setattr(ensemble, 'EnsembleProcess', Recorded)
    monkeypatch.setattr(engine_module, 'Simulator', broken_simulator)
    with pytest.raises(RuntimeError, match='no model today'):
        TwinEngine(config, EnsembleSettings(members=2, dispersion=0.01, seed=1,
                                            separate_process=True))
    (worker,) = started
    assert worker._process.poll() is not None                   # stopped, not orphaned
    assert worker._connection.closed


def test_a_worker_that_cannot_start_leaves_the_ensemble_in_this_process(config, monkeypatch):
    from drill_twin.twin import ensemble

    monkeypatch.setattr(ensemble, 'WORKER_MODULE', 'drill_twin.no_such_module')
    with threadpool_limits(limits=1, user_api='blas'):
        engine = TwinEngine(config, EnsembleSettings(members=2, dispersion=0.01, seed=1,
                                                     separate_process=True))
        first = engine.advance(1)
        snapshot = engine.advance(1)
    (event,) = first.events
    assert event.kind == 'ensemble_failed' and event.level == 'warn'
    assert 'exit code 1' in event.message and 'runs in this process' in event.message
    assert isinstance(engine.ensemble_runner, ensemble.LocalEnsemble)
    assert snapshot.ensemble_step == 1 and snapshot.ensemble_mean is not None


def test_a_lost_worker_drops_the_ensemble_and_the_mean_model_goes_on(config):
    with threadpool_limits(limits=1, user_api='blas'):
        engine = TwinEngine(config, EnsembleSettings(members=2, dispersion=0.01, seed=1,
                                                     separate_process=True))
        try:
            engine.advance(5)
            engine.ensemble_runner._process.kill()
            snapshot = engine.advance(1)
            later = engine.advance(1)
        finally:
            engine.close()
    (event,) = snapshot.events
    assert event.kind == 'ensemble_failed' and event.level == 'error'
    assert 'exit code -9' in event.message and 'mean model goes on' in event.message
    assert snapshot.ensemble_mean is None and later.ensemble_mean is None
    assert later.step == 7 and math.isfinite(later.bit.speed_rad_per_s)


def test_a_diverged_mean_model_is_restarted(config):
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=0)
        engine.advance(50)
        engine.simulator.state.q_rate[0, 3] = np.inf
        snapshot = engine.advance(1)
    assert [e.kind for e in snapshot.events] == ['diverged']
    assert 'the mean model diverged' in snapshot.events[0].message
    assert all(math.isfinite(v) for v in vars(snapshot.bit).values())
    assert snapshot.step == 51


def test_a_model_that_cannot_step_stalls_with_an_error(monkeypatch):
    # Ten failures in a row instead of the shipped 100: each failing step also tries its four
    # sub-step levels, and the mechanism is the same.
    from drill_twin.integrator import stepping
    monkeypatch.setattr(stepping, 'MAX_CONSECUTIVE_FAILURES', 10)
    config = load_config(None, ['integration.max_iterations=1', 'integration.tolerance=1e-14'])
    engine = _engine(config, members=0)
    with pytest.raises(TwinStalled, match='10 steps in a row failed'):
        engine.advance(20)
    assert engine.step_index == 0


def test_kpis_over_the_moving_window(config):
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=0)
        engine.kpi_window_s = 5.0
        speeds = []
        for _ in range(1000):                               # 10 s in 10 ms ticks
            snapshot = engine.advance(1)
            speeds.append(snapshot.observation.speed_rad_per_s[0])
    last = np.array(speeds[-501:])                          # the window's 501 samples
    assert snapshot.stick_slip_severity == pytest.approx(float(kpi.stick_slip_severity(last)),
                                                         rel=1e-9)
    assert 0.2 < snapshot.stick_slip_severity < 1.5
    assert 1e8 < snapshot.mse_pa < 3e8
    assert 3.0 < snapshot.rop_m_per_h < 15.0
    # MSE and ROP are kpi.py's over the window's columns (time, speed, ROP, WOB, TOB).
    window = engine.kpi_window_samples()
    assert window.shape == (501, 5)
    mse = kpi.mechanical_specific_energy(window[:, 3], window[:, 4], window[:, 1],
                                         window[:, 2], config.borehole.diameter_m)
    assert snapshot.mse_pa == pytest.approx(float(mse), rel=1e-9)
    assert snapshot.rop_m_per_h == pytest.approx(3600.0 * float(np.mean(window[:, 2])),
                                                 rel=1e-9)


def test_the_kpi_windows_means_are_numpys_over_the_samples_in_the_window():
    """
    kpi.window_means: numpy's reductions over the samples at or after the window's start.

    Samples in storage order (not time order), some before the start, one exactly at it; the
    SSI and MSE made of the means are kpi.py's of those samples. A non-finite sample makes the
    indicators non-finite, as numpy's; no sample in the window gives a count of 0.
    """
    rng = np.random.default_rng(7)
    times = rng.permutation(np.arange(300) * 0.01)
    speed, rop = rng.uniform(-1.0, 12.0, 300), rng.uniform(-1e-3, 5e-3, 300)
    wob, tob = rng.uniform(-2e5, 1e4, 300), rng.uniform(-5e3, 2e4, 300)
    start = times[17]                                       # one sample exactly at the start
    inside = times >= start
    assert 0 < inside.sum() < 300
    count, mean, fastest, slowest, mean_rop, weight, power = kpi.window_means(
        times, start, speed, rop, wob, tob)
    s, r, w, t = speed[inside], rop[inside], wob[inside], tob[inside]
    assert count == inside.sum()
    assert (mean, fastest, slowest) == pytest.approx((s.mean(), s.max(), s.min()), rel=1e-12)
    assert (mean_rop, weight, power) == pytest.approx(
        (r.mean(), np.abs(w).mean(), np.mean(np.abs(t) * np.abs(s))), rel=1e-12)
    assert kpi.severity_of(mean, fastest, slowest) == pytest.approx(
        float(kpi.stick_slip_severity(s)), rel=1e-12)
    assert kpi.specific_energy_of(weight, power, mean_rop, 0.3) == pytest.approx(
        float(kpi.mechanical_specific_energy(w, t, s, r, 0.3)), rel=1e-12)
    assert math.isinf(kpi.specific_energy_of(weight, power, 0.0, 0.3))    # no rock cut
    speed[np.flatnonzero(inside)[3]] = np.nan
    count, mean, fastest, slowest, *_ = kpi.window_means(times, start, speed, rop, wob, tob)
    assert math.isnan(kpi.severity_of(mean, fastest, slowest))
    assert kpi.window_means(times, 10.0, speed, rop, wob, tob)[0] == 0


def test_ensemble_statistics_contain_the_mean(config):
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=8)
        for _ in range(200):
            snapshot = engine.advance(1)
            for field in vars(snapshot.ensemble_mean):
                low = getattr(snapshot.ensemble_lower, field)
                high = getattr(snapshot.ensemble_upper, field)
                assert low <= getattr(snapshot.ensemble_mean, field) <= high


@pytest.mark.parametrize('setter, value, words', [
    ('set_top_drive_speed', float('nan'), 'not a finite number'),
    ('set_top_drive_speed', -1.0, 'outside [0, 30] rad/s'),
    ('set_hook_load', 6e6, 'outside [0, 5e+06] N'),
    ('set_hook_load', 'heavy', 'not a finite number'),
])
def test_bad_commands_are_rejected_and_the_last_valid_stays(config, setter, value, words):
    engine = TwinEngine(config, EnsembleSettings(members=0), CommandLimits())
    engine.set_top_drive_speed(4.0)
    engine.set_hook_load(1.0e6)
    with pytest.raises(CommandRejected, match=re.escape(words)):
        getattr(engine, setter)(value)
    assert engine.top_drive_speed_command == 4.0 and engine.hook_load_command == 1.0e6
    (event,) = engine.snapshot().events
    assert event.kind == 'command_rejected' and 'previous command stays' in event.message


def test_ensemble_columns_are_the_bit_state_fields():
    import dataclasses

    from drill_twin.twin.engine import BitState
    from drill_twin.twin.ensemble import BIT_FIELDS

    assert tuple(f.name for f in dataclasses.fields(BitState)) == BIT_FIELDS


def test_the_torque_limit_command_is_bounded_by_its_node_parameter(config):
    from drill_twin.ros.build import command_limits
    from drill_twin.ros.parameters import TwinParameters

    limits = command_limits(TwinParameters.from_values({'top_drive_torque_limit_max_nm': 80e3}))
    assert limits.top_drive_torque_limit_max_nm == 80e3
    engine = TwinEngine(config, EnsembleSettings(members=0), limits)
    engine.set_top_drive_torque_limit(60e3)
    with pytest.raises(CommandRejected, match=re.escape('is outside [0, 80000] N m')):
        engine.set_top_drive_torque_limit(90e3)
    with pytest.raises(CommandRejected, match='must be > 0 N m'):
        engine.set_top_drive_torque_limit(0.0)
    assert engine.rig.commands.torque_limit_nm == 60e3


def test_a_hook_load_step_that_the_drums_brake_holds_goes_through_the_twin(config):
    """
    The hook load 300 kN below the string's weight, from drilling, with an ensemble.

    The step makes the brake act (drawworks.block_speed_max_m_per_s) on the mean model and
    on the members; every snapshot's surface hook load is one number, the members' too (a
    (1,)-array hook load from the brake would stop the twin), and the top never moves faster
    than the block can.
    """
    from drill_twin.integrator.guard import StateGuard
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=4)
        weight = StateGuard(engine.simulator.system, engine.simulator.law).envelope
        snapshots = [engine.advance(1) for _ in range(50)]
        command = weight.string_weight_n - 3e5
        engine.set_hook_load(command)           # 400 kN less at once: the top would run at 1.7 m/s
        snapshots += [engine.advance(1) for _ in range(300)]
    hooks = [s.surface.hook_load_n for s in snapshots]
    assert all(isinstance(h, float) and math.isfinite(h) for h in hooks)
    assert max(hooks[50:]) > command + 1e4                           # the brake held it
    speeds = [abs(float(s.observation.hook_velocity_m_per_s[0])) for s in snapshots]
    assert max(speeds) <= 1.005
    assert snapshots[-1].health['resets'] == 0


def test_a_landing_is_reported_at_its_touch_down_with_the_impacts_peak_weight_on_bit():
    """
    Picked up off bottom, set down at 0.25 m/s: one 'landing' event.

    It is stamped at the step where the bit touched the rock, with the bit's axial speed
    before it and the first maximum of the WOB after it, both read step by step here. On the
    rock's spring the impact builds over several steps, so the peak is well above the
    touch-down step's WOB.
    """
    from drill_twin.twin.watch import LANDING_PEAK_WINDOW_S
    config = load_config(None, ['integration.time_step_s=0.005'])
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=0)
        engine.advance(200)
        engine.set_axial_mode('block_velocity')
        engine.set_block_velocity(-0.5)
        engine.advance(600)                                   # 3 s up at 0.5 m/s
        engine.set_block_velocity(0.0)
        engine.advance(200)
        assert not engine.simulator.on_bottom()[0]
        engine.set_block_velocity(0.25)
        rows, events = [], []
        for _ in range(3000):
            before = engine.simulator.last
            snapshot = engine.advance(1)
            events += [e for e in snapshot.events if e.kind == 'landing']
            now = engine.simulator.last
            rows.append((engine.time_s, bool(engine.simulator.on_bottom()[0]),
                         float(before.rop_m_per_s[0]), -float(now.weight_on_bit_n[0])))
            if events:
                break
    t, on_bottom, speed, wob = (np.array(c) for c in zip(*rows))
    touch = int(np.flatnonzero(on_bottom)[0])
    assert len(events) == 1
    values = events[0].values
    assert events[0].time_s == pytest.approx(t[touch])
    assert float(values['speed_m_per_s']) == pytest.approx(speed[touch], rel=1e-5)
    assert 0.0 < speed[touch] < 0.5                 # downwards, at most twice the block's speed
    after = wob[touch:]
    falls = np.flatnonzero(np.diff(after) < 0)
    first_peak = after[: falls[0] + 1].max()
    assert float(values['peak_weight_on_bit_n']) == pytest.approx(first_peak, rel=1e-5)
    assert float(values['time_to_peak_s']) < LANDING_PEAK_WINDOW_S
    assert first_peak > 3 * wob[touch]


def test_a_landing_whose_weight_on_bit_still_rises_is_reported_at_the_windows_end(monkeypatch):
    """
    A landing window shorter than the impact's rise (20 ms against some 70 ms on the spring).

    The landing is still reported, once, when the window ends, with the largest WOB since the
    touch-down (read step by step here) although the WOB is still rising: a bit set down
    slowly is not left unreported for as long as its WOB grows.
    """
    import drill_twin.twin.watch as watch_module
    window = 0.02
    monkeypatch.setattr(watch_module, 'LANDING_PEAK_WINDOW_S', window)
    config = load_config(None, ['integration.time_step_s=0.005'])
    with threadpool_limits(limits=1, user_api='blas'):
        engine = _engine(config, members=0)
        engine.advance(200)
        engine.set_axial_mode('block_velocity')
        engine.set_block_velocity(-0.5)
        engine.advance(600)
        engine.set_block_velocity(0.0)
        engine.advance(200)
        engine.set_block_velocity(0.25)
        landed, wob, events = None, [], []
        for _ in range(3000):
            snapshot = engine.advance(1)
            events += [e for e in snapshot.events if e.kind == 'landing']
            if landed is None and engine.simulator.on_bottom()[0]:
                landed = engine.time_s
            if landed is not None:
                wob.append(-float(engine.simulator.last.weight_on_bit_n[0]))
                if len(wob) > 20:
                    break
    steps = int(round(window / engine.dt))
    assert landed is not None and len(events) == 1
    assert np.all(np.diff(wob[:steps + 2]) > 0)         # still rising after the window's end
    assert events[0].time_s == pytest.approx(landed)
    assert float(events[0].values['time_to_peak_s']) == pytest.approx(window, abs=1e-9)
    assert float(events[0].values['peak_weight_on_bit_n']) == pytest.approx(wob[steps],
                                                                            rel=1e-5)


def test_a_start_the_command_door_would_refuse_is_refused_with_its_reason(config):
    """
    ``operation.hook_load_n = 0`` starts no twin: as a command it would be refused.

    The whole string on the bit (a hook load of 0) is far beyond the largest WOB; the start is
    refused with the reason the door gives the same value as a command, and a hook load the
    door accepts starts the twin.
    """
    from dataclasses import replace

    from drill_twin.config import ConfigError

    door = TwinEngine(config, EnsembleSettings(members=0))
    with pytest.raises(CommandRejected) as as_command:
        door.set_hook_load(0.0)
    reason = door.envelope.hook_load_reason(0.0)
    assert reason and reason in str(as_command.value)
    assert door.envelope.string_weight_n > 3e5                 # 0 N: all of it on the bit
    zero = replace(config, operation=replace(config.operation, hook_load_n=0.0))
    with pytest.raises(ConfigError) as at_start:
        TwinEngine(zero, EnsembleSettings(members=0))
    assert str(at_start.value) == f'configuration: operation.hook_load_n: {reason}'
    accepted = door.envelope.string_weight_n - 1e5              # 100 kN on the bit
    assert door.envelope.hook_load_reason(accepted) is None
    fine = replace(config, operation=replace(config.operation, hook_load_n=accepted))
    assert TwinEngine(fine, EnsembleSettings(members=0)).hook_load_command == accepted
