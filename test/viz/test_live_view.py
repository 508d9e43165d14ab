"""LiveView: the entities it logs, and the rates it keeps, without a viewer."""
import math
import os
import subprocess

import numpy as np
import pytest

from drill_twin.viz import rerun_blueprint
from drill_twin.viz import rerun_entities as entities
from drill_twin.viz.live_view import LiveView
from drill_twin.viz.rerun_view import rerun_executable
from snapshots import impact, snapshot
import rerun_capture
from rerun_capture import Capture, rrd_chunks

rerun_env = rerun_capture.rerun_env        # a fixture, requested by name below

STATIONS_M = (700.0, 1590.0)


class FakeClock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def run_view(view, clock, seconds: float, dt: float = 0.01, wall_per_tick: float = 0.01,
             events_at=()):
    steps = int(round(seconds / dt))
    for i in range(1, steps + 1):
        t = i * dt
        clock.now += wall_per_tick
        events = [impact(t)] if any(abs(t - e) < dt / 2 for e in events_at) else []
        view.update(snapshot(t, events=events))


def test_live_view_logs_the_layout_entities(rerun_env, tmp_path):
    import rerun as rr

    recording = rr.RecordingStream(entities.APPLICATION_ID)
    clock = FakeClock()
    view = LiveView(STATIONS_M, recording=recording, clock=clock, active_tab='lateral')
    path = tmp_path / 'live.rrd'
    recording.save(path, default_blueprint=view.blueprint)     # after the view is made
    run_view(view, clock, 3.0, events_at=(1.0,))
    view.command(1.5, top_drive_speed_rad_per_s=6.0, hook_load_n=1.0e6)
    view.log_line(2.0, 'a line of the twin')
    view.close()
    recording.disconnect()
    subprocess.run([rerun_executable(), 'rrd', 'verify', str(path)], env=rerun_env, check=True,
                   capture_output=True, timeout=60)
    columns = rrd_chunks(path, rerun_env)
    for entity, column in (('/bit/speed', 'Scalars:scalars'), ('/top/torque', 'Scalars:scalars'),
                           ('/kpi/ssi', 'Scalars:scalars'),
                           ('/ensemble/speed/band', 'Scalars:scalars'),
                           ('/ensemble/speed/model', 'Scalars:scalars'),
                           ('/lateral/x700m/orbit', 'LineStrips2D:strips'),
                           ('/lateral/x1590m/pipe', 'Ellipses2D:centers'),
                           ('/lateral/x1590m/pipe', 'Ellipses2D:colors'),     # static style
                           ('/lateral/x700m/wall', 'Ellipses2D:half_sizes'),
                           ('/along/contact_force', 'BarChart:values'),
                           ('/along/contact_force', 'BarChart:abscissa'),
                           ('/along/deflection', 'BarChart:values'),
                           ('/cmd/top_drive_speed', 'Scalars:scalars'),
                           ('/diagnostics/real_time_factor', 'Scalars:scalars'),
                           ('/diagnostics/events', 'TextLog:text'),
                           ('/rosout', 'TextLog:text')):
        assert column in columns.get(entity, set()), (entity, column)
    assert 'ViewportBlueprint:root_container' in set().union(*columns.values())


def test_live_view_rates_and_values():
    rec, clock = Capture(), FakeClock()
    view = LiveView(STATIONS_M, recording=rec, clock=clock, sample_rate_hz=20.0,
                    profile_rate_hz=5.0, send_rate_hz=2.0)
    # twin at 100 Hz, 2 x real time: 10 s of twin time in 5 s of wall time
    run_view(view, clock, 10.0, wall_per_tick=0.005, events_at=(2.0, 2.5, 7.0))
    view.close()
    times, speed = rec.rows('bit/speed')
    assert 195 <= times.size <= 201                          # 20 samples per twin second
    assert np.all(np.diff(times) >= 0.05 - 1e-9)
    assert np.allclose(np.ravel(speed), (5.0 + 4.0 * np.sin(times)) * 60 / (2 * math.pi))
    sends = len(rec.sent['bit/speed'])
    assert 9 <= sends <= 11                                  # 2 sends per wall second, + close
    profile_times, _ = rec.rows('along/contact_force', 'BarChart:values')
    assert 49 <= profile_times.size <= 51                    # 5 per twin second
    event_times, events = rec.rows('diagnostics/events', 'TextLog:text')
    assert np.allclose(event_times, [2.0, 2.5, 7.0]) and all(e[0].startswith('impact: ')
                                                             for e in events)
    # orbits: one segment per sample, joined across sends; the ensemble at its own time
    _, strips = rec.rows('lateral/x1590m/orbit', 'LineStrips2D:strips')
    ends = np.array([s[0][1] for s in strips])
    starts = np.array([s[0][0] for s in strips])
    assert np.allclose(starts[1:], ends[:-1])
    assert np.allclose(np.hypot(ends[:, 0], ends[:, 1]), 20.0)          # 0.02 m in mm
    ensemble_times, _ = rec.rows('ensemble/speed/mean')
    assert np.allclose(ensemble_times, times - 0.01)
    rtf_times, rtf = rec.rows('diagnostics/real_time_factor')
    finite = np.ravel(rtf)[np.isfinite(np.ravel(rtf))]
    assert finite.size and np.allclose(finite, 2.0, rtol=0.05)


def test_live_view_without_ensemble_or_stations():
    rec, clock = Capture(), FakeClock()
    view = LiveView((), recording=rec, clock=clock)
    for i in range(1, 101):
        clock.now += 0.01
        view.update(snapshot(i * 0.01, stations=0, ensemble=False))
    view.close()
    assert 'bit/speed' in rec.sent and 'along/contact_force' in rec.sent
    assert not any(entity.startswith(('lateral/', 'along/deflection'))
                   or entity.endswith(('/band', '/mean')) for entity in rec.sent)
    assert 'ensemble/speed/model' in rec.sent          # the mean model alone


@pytest.mark.parametrize('web', [False, True])
def test_spawn_viewer_binds_localhost(monkeypatch, web):
    started = []

    class FakePopen:
        def __init__(self, command):
            started.append(command)

    connected = []
    monkeypatch.setattr(subprocess, 'Popen', FakePopen)
    view = LiveView(STATIONS_M, recording=Capture(), clock=FakeClock())
    monkeypatch.setattr(view, 'connect', connected.append)
    view.spawn_viewer(web=web, port=9871, web_port=9072)
    (command,) = started
    assert command[command.index('--bind') + 1] == '127.0.0.1'
    assert ('--web-viewer' in command) == web and '--expect-data-soon' in command
    assert connected == ['rerun+http://127.0.0.1:9871/proxy']
    assert os.path.basename(command[0]).startswith('rerun')


def test_live_view_sends_every_analysis_of_a_twin_that_assimilates():
    """
    Each analysis's germ (mean, 2.5 %, 97.5 %) is sent at its time.

    The blueprint has the germ's view only for a twin that assimilates.
    """
    import dataclasses

    from drill_twin.assimilation.sequential import AnalysisRecord
    rec, clock = Capture(), FakeClock()
    view = LiveView((), recording=rec, clock=clock, assimilation=True)
    for i in range(1, 51):
        clock.now += 0.01
        t = i * 0.01
        analyses = (AnalysisRecord(time_s=t, nis=1.0, measurements=2, germ_mean=(1.0, t, 2.0),
                                   germ_lower=(0.5, -t, 1.5), germ_upper=(1.5, 2 * t, 2.5)),
                    ) if i % 10 == 0 else ()
        view.update(dataclasses.replace(snapshot(t, stations=0), analyses=analyses))
    view.close()
    times, g12 = rec.rows('ensemble/germ/g12/mean')
    assert np.allclose(times, [0.1, 0.2, 0.3, 0.4, 0.5])
    assert np.allclose(np.ravel(g12), times)
    assert np.allclose(np.ravel(rec.rows('ensemble/germ/g12/upper')[1]), 2 * times)
    assert np.allclose(np.ravel(rec.rows('ensemble/germ/g22/lower')[1]), 1.5)

    def views(assimilation, law=False):
        tab = rerun_blueprint._ensemble_tab(assimilation, law)
        return ' '.join(str(v.name) for v in tab.contents)
    assert 'Estimated bit-rock germ' in views(True)
    assert 'Estimated bit-rock germ' not in views(False)
    assert 'Law factors a1..a5' in views(True, law=True)
    assert 'Law factors a1..a5' not in views(True)
    assert 'ensemble/law/a1/mean' not in rec.sent            # the germ only: no law sent


def test_live_view_sends_the_estimated_law_when_the_filter_estimates_it():
    """An analysis with the law's factors (parameters 'law') sends them at its time."""
    import dataclasses

    from drill_twin.assimilation.sequential import AnalysisRecord
    rec, clock = Capture(), FakeClock()
    view = LiveView((), recording=rec, clock=clock, assimilation=True, law=True)
    for i in range(1, 31):
        clock.now += 0.01
        t = i * 0.01
        analyses = (AnalysisRecord(time_s=t, nis=1.0, measurements=2, germ_mean=(1.0, 0.0, 1.0),
                                   germ_lower=(1.0, 0.0, 1.0), germ_upper=(1.0, 0.0, 1.0),
                                   law_mean=(1.0, 1.0, 1.0, 1.0 + t, 1.0),
                                   law_lower=(0.9,) * 5, law_upper=(1.1,) * 5),
                    ) if i % 10 == 0 else ()
        view.update(dataclasses.replace(snapshot(t, stations=0), analyses=analyses))
    view.close()
    times, a4 = rec.rows('ensemble/law/a4/mean')
    assert np.allclose(times, [0.1, 0.2, 0.3])
    assert np.allclose(np.ravel(a4), 1.0 + times)
    assert np.allclose(np.ravel(rec.rows('ensemble/law/a2/upper')[1]), 1.1)


def test_live_view_sends_the_estimated_sensor_bias_labelled_by_channel():
    """An analysis with a sensor bias (bias_prior_std) sends it under its channel's name."""
    import dataclasses

    from drill_twin.assimilation.sequential import AnalysisRecord
    rec, clock = Capture(), FakeClock()
    view = LiveView((), recording=rec, clock=clock, assimilation=True,
                    bias_channels=('top_torque',))
    for i in range(1, 31):
        clock.now += 0.01
        t = i * 0.01
        analyses = (AnalysisRecord(time_s=t, nis=1.0, measurements=2, germ_mean=(1.0, 0.0, 1.0),
                                   germ_lower=(1.0, 0.0, 1.0), germ_upper=(1.0, 0.0, 1.0),
                                   bias_channels=('top_torque',), bias_mean=(100.0 * t,),
                                   bias_lower=(-5.0,), bias_upper=(50.0,)),
                    ) if i % 10 == 0 else ()
        view.update(dataclasses.replace(snapshot(t, stations=0), analyses=analyses))
    view.close()
    times, mean = rec.rows('ensemble/bias/top_torque/mean')
    assert np.allclose(times, [0.1, 0.2, 0.3])
    assert np.allclose(np.ravel(mean), 100.0 * times)
    assert np.allclose(np.ravel(rec.rows('ensemble/bias/top_torque/lower')[1]), -5.0)
    titles = ' '.join(str(v.name) for v in rerun_blueprint._ensemble_tab(
        True, False, ('top_torque',)).contents)
    assert 'Estimated top_torque sensor bias (N m)' in titles
    assert 'sensor bias' not in ' '.join(str(v.name)
                                         for v in rerun_blueprint._ensemble_tab(True).contents)
