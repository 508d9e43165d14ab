"""The rerun views of a twin log: CDR decoding, units, band, orbits, .rrd, viewers on localhost."""
import math
from pathlib import Path
import socket
import subprocess
import sys
import time
import urllib.request

import numpy as np
import pytest

from drill_twin import interface as itf
from drill_twin.recording import cdr
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.message_types import import_message_class
from drill_twin.recording.reader import iter_raw
from drill_twin.viz import rerun_blueprint
from drill_twin.viz import rerun_entities as entities
from drill_twin.viz import rerun_series as series
from drill_twin.viz import rerun_styles
from drill_twin.viz.rerun_native import geometry_of
from drill_twin.viz.run_columns import LogNotFound, log_files, read_run, stations_from_topics
from drill_twin.viz.rerun_view import (has_display, LOCALHOST, NO_DISPLAY_HINT,
                                       open_viewer, rerun_executable, save_rrd,
                                       viewer_command)
import rerun_capture
from rerun_capture import Capture, rrd_chunks
from synthetic import write_synthetic_log
from drill_twin.recording.topics import twin_topics

rerun_env = rerun_capture.rerun_env        # a fixture, requested by name below

STATIONS_M = (600.0, 1200.0)
RPM = 60.0 / (2.0 * math.pi)


@pytest.fixture(scope='module')
def log_path(tmp_path_factory):
    path = tmp_path_factory.mktemp('rerun_log') / 'twin.mcap'
    write_synthetic_log(path, duration_s=2.0, rate_hz=20.0, stations_m=STATIONS_M)
    return path


def geometry(stations=STATIONS_M):
    from drill_twin.config import load_config

    return entities.StringGeometry.from_config(load_config(None), stations)


# -- CDR decoding, checked against rclpy's deserializer -----------------------------------------

def test_cdr_decoders_match_rclpy(log_path):
    from rclpy.serialization import deserialize_message

    checked = set()
    for schema, channel, record in iter_raw(log_path):
        reference = deserialize_message(record.data, import_message_class(schema.name))
        name = schema.name
        if name == 'sensor_msgs/msg/JointState':
            stamp, position, velocity, effort = cdr.joint_state(record.data)
            assert stamp == reference.header.stamp.sec * 10**9 + reference.header.stamp.nanosec
            assert (list(position), list(velocity), list(effort)) == (
                list(reference.position), list(reference.velocity), list(reference.effort))
        elif name == 'geometry_msgs/msg/Vector3Stamped':
            assert cdr.vector3_stamped(record.data)[1] == (
                reference.vector.x, reference.vector.y, reference.vector.z)
        elif name == 'sensor_msgs/msg/Imu':
            _, angular, linear = cdr.imu(record.data)
            v, a = reference.angular_velocity, reference.linear_acceleration
            assert (angular, linear) == ((v.x, v.y, v.z), (a.x, a.y, a.z))
        elif name == 'std_msgs/msg/Float64MultiArray':
            assert list(cdr.float64_multi_array(record.data)) == list(reference.data)
        elif name == 'std_msgs/msg/Float64':
            assert cdr.float64(record.data) == reference.data
        else:
            continue
        checked.add(name)
    assert len(checked) == 5, checked
    with pytest.raises(cdr.CdrError):
        cdr.float64(b'\x00\x00\x00\x00' + bytes(8))          # big endian: not ours
    # several layout dimensions and an empty array
    message = import_message_class('std_msgs/msg/Float64MultiArray')()
    dimension = import_message_class('std_msgs/msg/MultiArrayDimension')
    message.layout.dim = [dimension(label='node depth 0.0 m', size=3, stride=3),
                          dimension(label='x', size=1, stride=1)]
    message.data = [1.5, -2.0, 3.25]
    from rclpy.serialization import serialize_message

    assert cdr.float64_multi_array(serialize_message(message)) == (1.5, -2.0, 3.25)
    assert cdr.float64_multi_array_labels(serialize_message(message)) == (
        'node depth 0.0 m', 'x')
    message.layout.dim = [dimension(label='ab', size=3, stride=3),      # unaligned string ends
                          dimension(label='top_torque,bit_speed', size=1, stride=1)]
    assert cdr.float64_multi_array_labels(serialize_message(message)) == (
        'ab', 'top_torque,bit_speed')
    assert cdr.float64_multi_array(serialize_message(message)) == (1.5, -2.0, 3.25)
    message.data = []
    assert cdr.float64_multi_array(serialize_message(message)) == ()


# -- units, band, orbits: what the layout functions send ------------------------------------

def test_units_and_signs():
    rec = Capture()
    t = np.array([0.0, 0.5])
    series.send_bit(rec, t, [1600.0, 1600.1], [1e-3, 2e-3], [2 * math.pi, math.pi],
                    [-1e5, -5e4], [-3e3, 0.0])
    series.send_top(rec, t, [5.0, 5.0], [2e3, 4e3], [1.2e6, 1.1e6])
    series.send_kpis(rec, t, [0.5, 0.7], [1e8, 2e8], [6.0, 7.0])
    times, speed = rec.rows('bit/speed')
    assert np.allclose(times, t)
    assert np.allclose(np.ravel(speed), [60.0, 30.0])                    # rpm
    assert np.allclose(np.ravel(rec.rows('bit/rop')[1]), [3.6, 7.2])      # m/h
    assert np.allclose(np.ravel(rec.rows('bit/wob')[1]), [100.0, 50.0])   # kN, + in compression
    assert np.allclose(np.ravel(rec.rows('bit/tob')[1]), [3.0, 0.0])      # kN m
    assert np.allclose(np.ravel(rec.rows('top/speed')[1]), 5.0 * RPM)
    assert np.allclose(np.ravel(rec.rows('top/torque')[1]), [2.0, 4.0])
    assert np.allclose(np.ravel(rec.rows('top/hook_load')[1]), [1200.0, 1100.0])
    assert np.allclose(np.ravel(rec.rows('kpi/mse')[1]), [100.0, 200.0])  # MPa


def test_band_fills_from_lower_to_upper():
    rec = Capture()
    mean = np.array([[0.0, 2e-3, -1e5, 0.0, 5.0, -3e3]] * 3)
    lower, upper = mean * 0.9, mean * 1.1
    series.send_ensemble(rec, [1.0, 2.0, 3.0], mean, lower, upper)
    _, band = rec.rows('ensemble/speed/band')
    for row in band:
        assert len(row) == entities.BAND_LINES
        assert np.all(np.diff(row) >= 0)
        assert row[0] == pytest.approx(0.9 * 5.0 * RPM) and row[-1] == pytest.approx(
            1.1 * 5.0 * RPM)
    assert np.allclose(np.ravel(rec.rows('ensemble/wob/mean')[1]), 100.0)
    # the band's lines share one legend name: the legend shows one entry, no hidden series
    (styles,) = rec.static.get('ensemble/speed/band') or [None]
    assert styles is None                                  # styles come from log_styles
    rerun_styles.log_styles(rec, geometry())
    (band_style,) = rec.static['ensemble/speed/band']
    assert set(band_style.names.as_arrow_array().to_pylist()) == {'95 % band'}


@pytest.mark.parametrize('group, keys', [('germ', ('g11', 'g12', 'g22')),
                                         ('law', ('a1', 'a2', 'a3', 'a4', 'a5'))])
def test_the_estimated_germ_and_law_are_sent_entry_by_entry(group, keys):
    rec = Capture()
    mean = np.array([[1.0, 0.1, 1.2, 0.9, 0.8], [0.9, 0.0, 1.1, 1.3, 0.7]])[:, :len(keys)]
    send = series.send_germ if group == 'germ' else series.send_law
    send(rec, [1.0, 2.0], mean, mean - 0.1, mean + 0.2)
    for column, key in enumerate(keys):
        for bound, expected in (('mean', mean), ('lower', mean - 0.1), ('upper', mean + 0.2)):
            assert np.allclose(np.ravel(rec.rows(f'ensemble/{group}/{key}/{bound}')[1]),
                               expected[:, column])


def test_orbit_segments_and_wall():
    g = geometry()
    assert g.station_clearance_m == pytest.approx((0.15 - 0.0635, 0.15 - 0.0635))
    assert entities.StringGeometry.from_config(_config(), (1590.0,)).station_clearance_m == (
        pytest.approx(0.15 - 0.1143),)                     # a drill collar
    rec = Capture()
    v, w = np.array([0.01, 0.02, 0.0]), np.array([0.0, 0.01, -0.03])
    series.send_station(rec, g, 1, [0.0, 0.1, 0.2], v, w, previous=(0.005, 0.0))
    entity = entities.station_entity(1200.0)
    _, strips = rec.rows(f'{entity}/orbit', 'LineStrips2D:strips')
    assert np.allclose(strips[0][0], [[5.0, 0.0], [10.0, 0.0]])           # mm, joined on
    assert np.allclose(strips[2][0], [[20.0, 10.0], [0.0, -30.0]])
    _, centres = rec.rows(f'{entity}/pipe', 'Ellipses2D:centers')
    _, sizes = rec.rows(f'{entity}/pipe', 'Ellipses2D:half_sizes')
    assert np.allclose(centres[1][0], [20.0, 10.0]) and np.allclose(sizes[0][0], [63.5, 63.5])
    assert np.allclose(np.ravel(rec.rows(f'{entity}/radial')[1]),
                       [10.0, math.hypot(20, 10), 30.0])
    assert np.allclose(np.ravel(rec.rows(f'{entity}/clearance')[1]), 86.5)
    rerun_styles.log_styles(rec, g)
    (wall,) = rec.static[f'{entity}/wall']
    assert np.allclose(wall.half_sizes.as_arrow_array().to_pylist(), [[150.0, 150.0]])


def test_profiles_along_the_depth():
    g = geometry()
    rec = Capture()
    forces = np.zeros((2, g.node_x_m.size))
    forces[1, 10] = 2500.0
    series.send_profiles(rec, g, [0.0, 0.1], forces, [[0.0, 0.0], [0.0865, 0.04325]])
    _, chart = rec.rows('along/contact_force', 'BarChart:values')
    assert chart[1][0]['shape'] == [g.node_x_m.size]
    assert chart[1][0]['buffer'][10] == pytest.approx(2.5)                # kN
    _, share = rec.rows('along/deflection', 'BarChart:values')
    assert np.allclose(share[1][0]['buffer'], [100.0, 50.0])             # % of clearance
    assert np.allclose(np.ravel(rec.rows('contact/max_force')[1]), [0.0, 2.5])


def _config():
    from drill_twin.config import load_config

    return load_config(None)


# -- reading a log ----------------------------------------------------------------------------

def test_read_run_times_from_zero_and_station_names(log_path):
    run = read_run(log_files(log_path))
    bit = run.array('bit', 6)
    assert bit[0, 0] == pytest.approx(0.0) and bit[-1, 0] == pytest.approx(1.95)
    assert stations_from_topics(run.topics) == list(STATIONS_M)
    assert stations_from_topics([itf.vibration_displacement_topic(950.25)]) == [950.25]
    assert geometry_of(run).stations_m == STATIONS_M     # unreadable config: built-in sizes
    assert run.array('contact', 5).shape[0] == pytest.approx(20, abs=1)   # 10 Hz of 2 s
    assert run.texts['rosout'] and run.texts['diagnostics/events']   # no health: synthetic


def test_log_files_of_a_bag_directory_and_split_files(log_path, tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    for name in ('run_0.mcap', 'run_1.mcap'):
        (bag / name).write_bytes(log_path.read_bytes())
    assert log_files(bag) == [bag / 'run_0.mcap', bag / 'run_1.mcap']
    (bag / 'metadata.yaml').write_text('rosbag2_bagfile_information:\n  version: 9\n'
                                       '  relative_file_paths: [run_1.mcap, run_0.mcap]\n')
    assert log_files(bag) == [bag / 'run_1.mcap', bag / 'run_0.mcap']
    assert log_files([log_path, bag / 'run_0.mcap']) == [log_path, bag / 'run_0.mcap']
    with pytest.raises(LogNotFound):
        log_files(tmp_path / 'missing.mcap')
    empty = tmp_path / 'empty_dir'
    empty.mkdir()
    with pytest.raises(LogNotFound):
        log_files(empty)
    run = read_run(log_files(bag))
    assert run.array('bit', 6).shape[0] == 2 * read_run([log_path]).array('bit', 6).shape[0]


# -- the .rrd ---------------------------------------------------------------------------------

def test_save_rrd_is_self_contained_with_blueprint(log_path, rerun_env, tmp_path):
    rrd = save_rrd(log_path, tmp_path / 'twin.rrd', active_tab='lateral')
    subprocess.run([rerun_executable(), 'rrd', 'verify', str(rrd)], env=rerun_env,
                   check=True, capture_output=True, timeout=60)
    columns = rrd_chunks(rrd, rerun_env)
    for entity, column in (('/bit/speed', 'Scalars:scalars'),
                           ('/top/hook_load', 'Scalars:scalars'),
                           ('/kpi/ssi', 'Scalars:scalars'),
                           ('/ensemble/rop/band', 'Scalars:scalars'),
                           ('/ensemble/germ/g12/mean', 'Scalars:scalars'),
                           ('/ensemble/germ/g22/upper', 'Scalars:scalars'),
                           ('/ensemble/law/a4/mean', 'Scalars:scalars'),
                           ('/ensemble/law/a1/lower', 'Scalars:scalars'),
                           ('/ensemble/bias/top_torque/mean', 'Scalars:scalars'),
                           ('/ensemble/bias/top_torque/upper', 'Scalars:scalars'),
                           ('/lateral/x600m/orbit', 'LineStrips2D:strips'),
                           ('/lateral/x1200m/pipe', 'Ellipses2D:centers'),
                           ('/lateral/x1200m/wall', 'Ellipses2D:half_sizes'),
                           ('/along/deflection', 'BarChart:values'),
                           ('/contact/max_force', 'Scalars:scalars'),
                           ('/diagnostics/events', 'TextLog:text'),
                           ('/rosout', 'TextLog:text')):
        assert column in columns.get(entity, set()), entity
    # the synthetic log's 4 contact forces do not match the model's nodes: no profile drawn
    assert 'BarChart:values' not in columns['/along/contact_force']
    blueprint = set().union(*columns.values())
    assert {'ViewportBlueprint:root_container', 'TimePanelBlueprint:timeline',
            'VisibleTimeRanges:ranges', 'PlotLegend:visible'} <= blueprint
    verbose = subprocess.run([rerun_executable(), 'rrd', 'print', '-vvv', str(rrd)],
                             env=rerun_env, capture_output=True, text=True, check=True,
                             timeout=60).stdout
    for text in ('run time', 'Orbit at 1200 m', 'Bit speed (rpm)', 'Surface torque (kN·m)',
                 'Estimated bit-rock germ', 'Law factors a1..a5',
                 'Estimated top_torque sensor bias (N m)',
                 'Wall contact force (kN) vs depth (m)', entities.APPLICATION_ID):
        assert text in verbose, text
    assert 'message_log_time' not in verbose              # no wall-clock timeline


def test_save_rrd_of_a_log_cut_short(rerun_env, tmp_path):
    complete = tmp_path / 'complete.mcap'
    write_synthetic_log(complete, duration_s=1.0, rate_hz=50.0, stations_m=())
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(complete.read_bytes()[: complete.stat().st_size * 2 // 3])
    rrd = save_rrd(cut, tmp_path / 'cut.rrd', stations_m=())
    assert {'/bit/speed', '/kpi/rop'} <= set(rrd_chunks(rrd, rerun_env))


def test_empty_log_converts(rerun_env, tmp_path):
    path = tmp_path / 'empty.mcap'
    with McapLog(path) as log:
        for topic, spec in twin_topics().items():
            log.add_topic(topic, spec.type_name, spec.qos)
    save_rrd(path, tmp_path / 'empty.rrd', stations_m=())
    assert (tmp_path / 'empty.rrd').stat().st_size > 0


def test_blueprint_variants(rerun_env, tmp_path):
    assert entities.TABS == ('bit', 'driller', 'lateral', 'ensemble', 'diagnostics')
    for i, stations in enumerate(((), (500.0,), (500.0, 1000.0, 1500.0))):
        for tab in (entities.TABS[i], i + 2, entities.TAB_TITLES[entities.TABS[i]].upper()):
            path = tmp_path / f'layout_{i}_{tab}.rbl'
            rerun_blueprint.twin_blueprint(geometry(stations), active_tab=tab).save(
                entities.APPLICATION_ID, path)
            assert path.stat().st_size > 0
    assert entities.tab_index('Lateral motion') == 2
    for bad in ('No such tab', 7, -1):
        with pytest.raises(ValueError):
            entities.tab_index(bad)


# -- viewers: localhost only, and no display ---------------------------------------------------

def test_viewer_commands_bind_localhost(tmp_path):
    native = viewer_command(tmp_path / 'x.rrd', port=9999)
    assert native[1:5] == ['--bind', LOCALHOST, '--port', '9999'] and '--web-viewer' not in native
    web = viewer_command(None, web=True, port=9999, web_port=9998)
    assert web[web.index('--bind') + 1] == '127.0.0.1' and '--expect-data-soon' in web
    assert web[web.index('--web-viewer-port') + 1] == '9998'
    assert not has_display({}) or sys.platform in ('darwin', 'win32')
    assert has_display({'DISPLAY': ':0'}) and has_display({'WAYLAND_DISPLAY': 'wayland-0'})


def _free_port() -> int:
    with socket.socket() as s:
        s.bind((LOCALHOST, 0))
        return s.getsockname()[1]


def _listening(port: int) -> set[str]:
    """Local IPv4/IPv6 addresses listening on ``port`` (from /proc/net/tcp*)."""
    found = set()
    for table in ('/proc/net/tcp', '/proc/net/tcp6'):
        try:
            lines = Path(table).read_text().splitlines()[1:]
        except OSError:
            continue
        for line in lines:
            local, state = line.split()[1], line.split()[3]
            address, port_hex = local.split(':')
            if state == '0A' and int(port_hex, 16) == port:              # LISTEN
                found.add(address)
    return found


def test_web_viewer_serves_on_localhost_only(log_path, rerun_env, tmp_path):
    port, web_port = _free_port(), _free_port()
    process = open_viewer(log_path, rrd_dir=tmp_path, web=True, port=port, web_port=web_port)
    try:
        deadline = time.monotonic() + 60
        while not (_listening(port) and _listening(web_port)) and time.monotonic() < deadline:
            assert process.poll() is None, 'the web viewer exited'
            time.sleep(0.2)
        assert _listening(port) == {'0100007F'} and _listening(web_port) == {'0100007F'}
        with urllib.request.urlopen(f'http://{LOCALHOST}:{web_port}/', timeout=10) as page:
            assert page.status == 200
    finally:
        process.terminate()
        process.wait(timeout=30)
    assert not _listening(port) and not _listening(web_port)   # no viewer left behind
    assert (tmp_path / 'twin.rrd').stat().st_size > 0


def test_open_viewer_starts_rerun_on_the_rrd(log_path, rerun_env, tmp_path):
    # No display here: '--version' makes the real viewer binary exit right after parsing
    # its arguments (the bind address and the .rrd path included).
    process = open_viewer(log_path, rrd_dir=tmp_path, extra_args=['--version'])
    assert process.wait(timeout=60) == 0
    assert process.args[:3] == [rerun_executable(), '--bind', LOCALHOST]
    assert str(tmp_path / 'twin.rrd') in process.args


def _cli(args, env):
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', *args], env=env,
                          capture_output=True, text=True, timeout=120)


def test_cli_without_display(log_path, rerun_env, tmp_path):
    env = {k: v for k, v in rerun_env.items()
           if k not in ('DISPLAY', 'WAYLAND_DISPLAY', 'WAYLAND_SOCKET')}
    env['PYTHONPATH'] = str(Path(__file__).resolve().parents[2])
    result = _cli(['view', str(log_path)], env)
    assert result.returncode == 2
    assert result.stderr.strip() == f'drill-twin: view: {NO_DISPLAY_HINT}'
    assert '--rrd' in result.stderr and '--web' in result.stderr
    out = tmp_path / 'out.rrd'
    result = _cli(['view', str(log_path), '--rrd', str(out), '--tab', 'ensemble'], env)
    assert result.returncode == 0, result.stderr
    assert out.stat().st_size > 0
    result = _cli(['view', str(log_path), '--rrd', str(out), '--tab', 'nope'], env)
    assert result.returncode == 2 and 'invalid choice' in result.stderr
    result = _cli(['view', str(tmp_path / 'missing.mcap'), '--rrd', str(out)], env)
    assert result.returncode == 2 and 'no such file' in result.stderr
