"""rerun 0.41 really loads the twin's logs: entity paths, blueprint inside the .rrd."""
import os
from pathlib import Path
import re
import subprocess

import pytest

from drill_twin import interface as itf
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.rerun_view import (
    APPLICATION_ID, joint_entity, open_viewer, rerun_executable, save_rrd,
    stations_from_topics, TABS, twin_blueprint)
from drill_twin.recording.synthetic import write_synthetic_log
from drill_twin.recording.topics import BIT_JOINTS, JOINT_STATE, TOP_JOINTS, twin_topics

STATIONS_M = (600.0, 1200.0)
CHUNK_LINE = re.compile(r'^Chunk\(\S+\) with \d+ rows \([^)]*\) - (\S+) - data columns: \[(.*)\]$')


@pytest.fixture(scope='module')
def rerun_env(tmp_path_factory):
    """Environment for the rerun CLI and SDK: analytics config kept out of $HOME."""
    root = tmp_path_factory.mktemp('rerun_home')
    overrides = {'XDG_CONFIG_HOME': str(root / 'config'), 'XDG_DATA_HOME': str(root / 'data'),
                 'RMW_IMPLEMENTATION': 'rmw_fastrtps_cpp'}
    saved = {key: os.environ.get(key) for key in overrides}
    os.environ.update(overrides)
    yield dict(os.environ)
    for key, value in saved.items():
        if value is None:
            os.environ.pop(key, None)
        else:
            os.environ[key] = value


@pytest.fixture(scope='module')
def log_path(tmp_path_factory):
    path = tmp_path_factory.mktemp('rerun_log') / 'twin.mcap'
    write_synthetic_log(path, duration_s=1.0, rate_hz=20.0, stations_m=STATIONS_M)
    return path


def rrd_chunks(rrd: Path, env: dict) -> list[tuple[str, str]]:
    """(entity path, data columns) of every chunk of an .rrd, via ``rerun rrd print``."""
    result = subprocess.run([rerun_executable(), 'rrd', 'print', str(rrd)], env=env,
                            capture_output=True, text=True, check=True, timeout=60)
    chunks = [CHUNK_LINE.match(line) for line in result.stdout.splitlines()]
    return [(m.group(1), m.group(2)) for m in chunks if m]


def expected_entities(stations_m) -> set[str]:
    """Entity paths rerun's MCAP importer makes of the twin's topics."""
    entities = set()
    for topic, spec in twin_topics(stations_m).items():
        entities.add(topic)
        if spec.type_name == JOINT_STATE:
            entities.update(joint_entity(topic, f) for f in ('position', 'velocity', 'effort'))
    return entities


def test_cli_conversion_has_every_topic(log_path, rerun_env, tmp_path):
    rrd = tmp_path / 'cli.rrd'
    subprocess.run([rerun_executable(), 'mcap', 'convert', str(log_path), '-o', str(rrd)],
                   env=rerun_env, check=True, capture_output=True, timeout=60)
    chunks = rrd_chunks(rrd, rerun_env)
    entities = {entity for entity, _ in chunks}
    assert expected_entities(STATIONS_M) <= entities
    columns = {}
    for entity, data_columns in chunks:
        columns.setdefault(entity, set()).update(data_columns.split())
    # plotted by rerun itself ...
    assert 'Scalars:scalars' in columns[joint_entity(itf.BIT_STATE, 'velocity')]
    assert 'Scalars:scalars' in columns[itf.vibration_imu_topic(600.0)]
    assert 'Scalars:scalars' in columns[itf.CONTACT_FORCES]
    assert 'TextLog:text' in columns[itf.ROSOUT]
    # ... and the reflected messages our blueprint maps onto scalars
    assert 'std_msgs.msg.Float64:message' in columns[itf.KPI_ROP]
    assert 'geometry_msgs.msg.WrenchStamped:message' in columns[itf.BIT_WRENCH]
    assert 'geometry_msgs.msg.Vector3Stamped:message' in columns[
        itf.vibration_displacement_topic(1200.0)]
    assert 'drill_twin' in columns['/__mcap_metadata']
    # the instance order the blueprint's visible_series relies on
    verbose = subprocess.run([rerun_executable(), 'rrd', 'print', '-vvv', str(rrd)],
                             env=rerun_env, capture_output=True, text=True, check=True,
                             timeout=60).stdout
    assert '[{}, {}]'.format(*BIT_JOINTS) in verbose
    assert '[{}, {}]'.format(*TOP_JOINTS) in verbose
    assert ('[gyroscope/x, gyroscope/y, gyroscope/z, accelerometer/x, accelerometer/y, '
            'accelerometer/z]') in verbose


def test_save_rrd_is_self_contained_with_blueprint(log_path, rerun_env, tmp_path):
    rrd = save_rrd(log_path, tmp_path / 'twin.rrd')
    subprocess.run([rerun_executable(), 'rrd', 'verify', str(rrd)], env=rerun_env,
                   check=True, capture_output=True, timeout=60)
    chunks = rrd_chunks(rrd, rerun_env)
    entities = {entity for entity, _ in chunks}
    assert expected_entities(STATIONS_M) <= entities           # the data ...
    columns = [c for _, c in chunks]
    assert any('ViewportBlueprint:root_container' in c for c in columns)   # ... the layout
    assert any('TimePanelBlueprint:timeline' in c for c in columns)
    assert sum('ViewBlueprint:display_name' in c for c in columns) >= 20
    # field-to-scalar mappings (Float64, WrenchStamped, Vector3Stamped, commands)
    assert sum('VisualizerInstruction:component_map' in c for c in columns) >= 9
    verbose = subprocess.run([rerun_executable(), 'rrd', 'print', '-vvv', str(rrd)],
                             env=rerun_env, capture_output=True, text=True, check=True,
                             timeout=60).stdout
    assert 'Blueprint' in verbose and APPLICATION_ID in verbose
    for text in ('message_log_time', 'Ensemble bit speed', 'Lateral displacement at 1200 m',
                 'source_component: geometry_msgs.msg.WrenchStamped',
                 'source_component: geometry_msgs.msg.Vector3Stamped',
                 'source_component: std_msgs.msg.Float64'):
        assert text in verbose, text
    assert verbose.count('target: Scalars:scalars, source_kind: 1') >= 9


def test_save_rrd_of_a_log_cut_short(rerun_env, tmp_path):
    complete = tmp_path / 'complete.mcap'
    write_synthetic_log(complete, duration_s=1.0, rate_hz=50.0, stations_m=())
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(complete.read_bytes()[: complete.stat().st_size * 2 // 3])
    rrd = save_rrd(cut, tmp_path / 'cut.rrd', stations_m=())
    entities = {entity for entity, _ in rrd_chunks(rrd, rerun_env)}
    assert {itf.KPI_ROP, joint_entity(itf.BIT_STATE, 'velocity')} <= entities


def test_blueprint_variants(rerun_env, tmp_path):
    assert len(TABS) == 6
    for i, stations in enumerate(((), (500.0,), (500.0, 1000.0, 1500.0))):
        for tab in (TABS[i], i + 3):
            path = tmp_path / f'layout_{i}_{tab}.rbl'
            twin_blueprint(stations, active_tab=tab).save(APPLICATION_ID, path)
            assert path.stat().st_size > 0
    with pytest.raises(ValueError):
        twin_blueprint((), active_tab='No such tab')
    topics = [itf.vibration_imu_topic(x) for x in (1200.0, 700.0, 950.25)]
    topics += [itf.vibration_displacement_topic(700.0), itf.BIT_STATE]
    assert stations_from_topics(topics) == [700.0, 950.25, 1200.0]


def test_viewer_blueprint_from_log_topics(log_path, rerun_env, tmp_path):
    # stations_m=None reads the stations off the log's topic names
    rrd = save_rrd(log_path, tmp_path / 'auto.rrd')
    verbose = subprocess.run([rerun_executable(), 'rrd', 'print', '-vvv', str(rrd)],
                             env=rerun_env, capture_output=True, text=True, check=True,
                             timeout=60).stdout
    assert 'Acceleration at 600 m' in verbose and 'Acceleration at 1200 m' in verbose


def test_empty_log_converts(rerun_env, tmp_path):
    path = tmp_path / 'empty.mcap'
    with McapLog(path) as log:
        for topic, spec in twin_topics().items():
            log.add_topic(topic, spec.type_name, spec.qos)
    save_rrd(path, tmp_path / 'empty.rrd', stations_m=())
    assert (tmp_path / 'empty.rrd').stat().st_size > 0


def test_open_viewer_starts_rerun_on_the_rrd(log_path, rerun_env, tmp_path):
    # No display here: '--version' makes the real viewer binary exit right after parsing
    # its arguments (the .rrd path first, as a user's viewer gets it).
    process = open_viewer(log_path, rrd_dir=tmp_path, extra_args=['--version'])
    assert process.wait(timeout=60) == 0
    assert process.args[0] == rerun_executable()
    assert process.args[1] == str(tmp_path / 'twin.rrd')
    assert (tmp_path / 'twin.rrd').stat().st_size > 0
