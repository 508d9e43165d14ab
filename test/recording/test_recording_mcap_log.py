"""McapLog writes rosbag2-compatible MCAP; the reader and independent readers read it back."""
import os
from pathlib import Path
import signal
import subprocess
import sys
import time
from types import SimpleNamespace

from mcap.reader import make_reader
import numpy as np
from mcap_ros2.reader import read_ros2_messages
import pytest
import yaml

from drill_twin import interface as itf
from drill_twin.recording import reader
from drill_twin.recording.log_metadata import RECORD_NAME as TWIN_METADATA_NAME
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.message_types import import_message_class
from drill_twin.recording.recovery import recover_log
from drill_twin.recording.schemas import ros2msg_schema, type_hash
from mcap_probe import non_seeking_prefix
from synthetic import synthetic_messages
from drill_twin.recording.topics import twin_topics

STATIONS_M = (700.0, 1250.5)
CONFIG_YAML = 'drill_string:\n  length_m: 1500.0\n  stations_m: [700.0, 1250.5]\n'


def child_env(tmp_path: Path) -> dict:
    env = dict(os.environ)
    env.update(RMW_IMPLEMENTATION='rmw_fastrtps_cpp', ROS_LOG_DIR=str(tmp_path / 'ros_log'))
    return env


@pytest.fixture(scope='module')
def written(tmp_path_factory):
    """Write a log of every twin topic; give (path, [(topic, msg, log_ns, publish_ns)])."""
    path = tmp_path_factory.mktemp('log') / 'twin.mcap'
    expected = []
    with McapLog(path, chunk_size=8 * 1024) as log:
        for topic, spec in twin_topics(STATIONS_M).items():
            log.add_topic(topic, spec.type_name, spec.qos)
        log.add_metadata(TWIN_METADATA_NAME, {'config': CONFIG_YAML, 'seed': '1234'})
        for i, item in enumerate(synthetic_messages(duration_s=1.0, rate_hz=20.0,
                                                    stations_m=STATIONS_M)):
            publish = item.log_time_ns - 1000 if i % 2 else None
            log.write(item.topic, item.message, item.log_time_ns, publish)
            expected.append((item.topic, item.message, item.log_time_ns,
                             item.log_time_ns if publish is None else publish))
        counts = log.message_counts
    assert sum(counts.values()) == len(expected)
    return path, expected


def plain(value):
    """Field values of an rclpy or mcap_ros2 (SimpleNamespace) message as plain Python."""
    if hasattr(value, 'get_fields_and_field_types'):
        return {name: plain(getattr(value, name)) for name in value.get_fields_and_field_types()}
    if isinstance(value, SimpleNamespace):
        names = [*getattr(type(value), '__slots__', ()), *vars(value)]
        return {name: plain(getattr(value, name)) for name in names if not name.startswith('_')}
    if isinstance(value, (bytes, bytearray)) and len(value) == 1:
        return value[0]                       # rclpy 'byte' fields; mcap_ros2 gives ints
    if hasattr(value, 'tolist'):              # numpy arrays and scalars, array.array
        return plain(value.tolist())
    if isinstance(value, (list, tuple)):
        return [plain(v) for v in value]
    return value


def test_every_interface_type_is_recorded(written):
    path, expected = written
    assert set(reader.topics(path)) == set(twin_topics(STATIONS_M))
    assert {topic for topic, *_ in expected} == set(twin_topics(STATIONS_M))
    type_names = {spec.type_name for spec in twin_topics(STATIONS_M).values()}
    assert type_names == {
        'sensor_msgs/msg/JointState', 'geometry_msgs/msg/WrenchStamped', 'sensor_msgs/msg/Imu',
        'geometry_msgs/msg/Vector3Stamped', 'std_msgs/msg/Float64MultiArray',
        'std_msgs/msg/Float64', 'std_msgs/msg/String', 'diagnostic_msgs/msg/DiagnosticArray',
        'rosgraph_msgs/msg/Clock', 'rcl_interfaces/msg/Log'}


def test_independent_reader_decodes_with_the_schemas(written):
    path, expected = written
    decoded = list(read_ros2_messages(str(path)))
    assert len(decoded) == len(expected)
    for item, (topic, message, log_time, publish_time) in zip(decoded, expected):
        assert item.channel.topic == topic
        assert item.log_time_ns == log_time and item.publish_time_ns == publish_time
        assert plain(item.ros_msg) == plain(message) != {}, topic


def test_own_reader_round_trip(written):
    path, expected = written
    got = list(reader.iter_messages(path))
    assert len(got) == len(expected)
    for item, (topic, message, log_time, publish_time) in zip(got, expected):
        assert (item.topic, item.log_time_ns, item.publish_time_ns) == (
            topic, log_time, publish_time)
        assert item.type_name == twin_topics(STATIONS_M)[topic].type_name
        assert type(item.message) is type(message)
        assert item.message == message
    only = list(reader.iter_messages(path, topics=[itf.KPI_ROP]))
    assert len(only) == sum(1 for e in expected if e[0] == itf.KPI_ROP) > 0


def test_file_layout_is_what_rosbag2_writes(written):
    path, expected = written
    with open(path, 'rb') as stream:
        mcap = make_reader(stream)
        header = mcap.get_header()
        summary = mcap.get_summary()
    assert header.profile == 'ros2' and header.library.startswith('drill_twin')
    specs = twin_topics(STATIONS_M)
    assert len(summary.schemas) == len({s.type_name for s in specs.values()})
    for channel in summary.channels.values():
        spec = specs[channel.topic]
        schema = summary.schemas[channel.schema_id]
        assert channel.message_encoding == 'cdr'
        assert (schema.name, schema.encoding) == (spec.type_name, 'ros2msg')
        assert schema.data.decode() == ros2msg_schema(spec.type_name)
        assert set(channel.metadata) == {'offered_qos_profiles', 'topic_type_hash'}
        profiles = yaml.safe_load(channel.metadata['offered_qos_profiles'])
        assert profiles[0]['reliability'] == spec.qos.reliability
        assert profiles[0]['durability'] == spec.qos.durability
        assert profiles[0]['depth'] == spec.qos.depth
        assert set(profiles[0]) == {
            'history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
            'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions'}
        type_hash_value = channel.metadata['topic_type_hash']
        assert type_hash_value.startswith('RIHS01_') and len(type_hash_value) == 7 + 64
        assert type_hash_value == type_hash(spec.type_name)
    # Statistics: the totals rosbag2 reads when there is no 'rosbag2' metadata record
    statistics = summary.statistics
    assert statistics.message_count == len(expected)
    assert statistics.channel_count == len(specs)
    assert statistics.message_start_time == min(e[2] for e in expected)
    assert statistics.message_end_time == max(e[2] for e in expected)
    by_topic = {summary.channels[cid].topic: n
                for cid, n in statistics.channel_message_counts.items()}
    for topic in specs:
        assert by_topic[topic] == sum(1 for e in expected if e[0] == topic)
    assert statistics.chunk_count > 1 and len(summary.chunk_indexes) == statistics.chunk_count
    assert [m.name for m in summary.metadata_indexes] == [TWIN_METADATA_NAME]   # no 'rosbag2'


def test_metadata_round_trip(written):
    path, _ = written
    metadata = reader.read_metadata(path)
    assert metadata == {TWIN_METADATA_NAME: {'config': CONFIG_YAML, 'seed': '1234'}}
    assert yaml.safe_load(metadata[TWIN_METADATA_NAME]['config'])['drill_string'][
        'stations_m'] == [700.0, 1250.5]


def float64(value: float):
    return import_message_class('std_msgs/msg/Float64')(data=value)


def test_finish_is_idempotent_and_closes(tmp_path):
    log = McapLog(tmp_path / 'a.mcap')
    log.add_topic(itf.KPI_MSE, 'std_msgs/msg/Float64')
    log.write(itf.KPI_MSE, float64(1.0), 10)
    log.finish()
    log.finish()
    log.close()
    assert log.closed
    with pytest.raises(ValueError):
        log.write(itf.KPI_MSE, float64(2.0), 20)
    with pytest.raises(ValueError):
        log.add_topic(itf.KPI_ROP, 'std_msgs/msg/Float64')
    assert reader.is_complete(tmp_path / 'a.mcap')
    with McapLog(tmp_path / 'b.mcap') as log:
        log.finish()                             # and __exit__ finishes again
    assert reader.is_complete(tmp_path / 'b.mcap')


def test_failed_writes_leave_the_file_intact(tmp_path):
    path = tmp_path / 'robust.mcap'
    with pytest.raises(RuntimeError, match='model blew up'):
        with McapLog(path, chunk_size=256) as log:
            log.add_topic(itf.KPI_MSE, 'std_msgs/msg/Float64')
            log.add_topic(itf.BIT_STATE, 'sensor_msgs/msg/JointState')
            log.write(itf.KPI_MSE, float64(1.0), 1)
            bad_calls = [
                lambda: log.write(itf.KPI_MSE, import_message_class(
                    'sensor_msgs/msg/JointState')(), 2),                    # wrong type
                lambda: log.write('/not/added', float64(0.0), 2),          # unknown topic
                lambda: log.write(itf.KPI_MSE, float64(0.0), -1),          # negative time
                lambda: log.write(itf.KPI_MSE, float64(0.0), 2 ** 64),     # too late
                lambda: log.write(itf.KPI_MSE, float64(0.0), 1.5),         # not integer ns
                lambda: log.write(itf.KPI_MSE, float64(0.0), 2, -5),       # bad publish time
                lambda: log.add_metadata('x', {'seed': 5}),                # non-str value
                lambda: log.add_topic(itf.KPI_MSE, 'std_msgs/msg/Int32'),  # type changed
                lambda: log.add_topic('relative', 'std_msgs/msg/Float64'),
                lambda: log.add_topic('/x', 'no_such_pkg/msg/Nothing'),
                lambda: log.write_serialized(itf.KPI_MSE, 'text', 2),
            ]
            for call in bad_calls:
                with pytest.raises((TypeError, ValueError, KeyError, LookupError,
                                    ImportError)):
                    call()
            assert log.add_topic(itf.KPI_MSE, 'std_msgs/Float64') >= 1   # same topic again
            msg = import_message_class('sensor_msgs/msg/JointState')(name=['a'], position=[1.0])
            for i in range(50):
                log.write(itf.BIT_STATE, msg, 100 + i)
            log.add_metadata('after_errors', {'ok': 'yes'})
            raise RuntimeError('model blew up')
    assert reader.is_complete(path)
    got = list(reader.iter_messages(path, strict=True))
    assert [m.topic for m in got] == [itf.KPI_MSE] + [itf.BIT_STATE] * 50
    assert list(got[1].message.position) == [1.0]
    assert reader.read_metadata(path) == {'after_errors': {'ok': 'yes'}}
    assert len(list(read_ros2_messages(str(path)))) == 51


def test_serialized_write_matches(tmp_path):
    from rclpy.serialization import serialize_message

    path = tmp_path / 'raw.mcap'
    with McapLog(path) as log:
        log.add_topic(itf.CLOCK, 'rosgraph_msgs/msg/Clock', itf.CLOCK_QOS)
        clock = import_message_class('rosgraph_msgs/msg/Clock')()
        clock.clock.sec = 7
        log.write_serialized(itf.CLOCK, serialize_message(clock), 5, 4)
    (item,) = reader.iter_messages(path)
    assert item.message == clock and (item.log_time_ns, item.publish_time_ns) == (5, 4)


def test_chunks_are_flushed_by_log_time_however_fast_the_writer(tmp_path):
    """
    A twin far faster than real time.

    One chunk per flush interval of log time, written within microseconds of wall time (so the
    wall clock alone would never flush).
    """
    from std_msgs.msg import Float64

    path = tmp_path / 'fast.mcap'
    with McapLog(path, flush_interval_s=0.25) as log:
        log.add_topic(itf.KPI_ROP, 'std_msgs/msg/Float64')
        for i in range(100):                                  # 0 ... 0.99 s at 100 Hz
            log.write(itf.KPI_ROP, Float64(data=float(i)), 10_000_000 * i)
    with open(path, 'rb') as stream:
        chunks = make_reader(stream).get_summary().chunk_indexes
    starts = sorted(chunk.message_start_time / 1e9 for chunk in chunks)
    assert starts == pytest.approx([0.0, 0.25, 0.5, 0.75])


KILLED_WRITER = """
import sys
from drill_twin.recording.mcap_log import McapLog
from std_msgs.msg import Float64
log = McapLog(sys.argv[1], chunk_size=2048, flush_interval_s=0.02)
log.add_topic('/drill_twin/kpi/rop_m_per_h', 'std_msgs/msg/Float64')
log.add_metadata('drill_twin', {'seed': '7'})
i = 0
while True:
    log.write('/drill_twin/kpi/rop_m_per_h', Float64(data=float(i)), 1_000_000 * i)
    i += 1
    if i % 500 == 0:
        log.flush()
        print(i, flush=True)
"""


def test_sigkill_leaves_a_readable_prefix(tmp_path):
    path = tmp_path / 'killed.mcap'
    process = subprocess.Popen([sys.executable, '-c', KILLED_WRITER, str(path)],
                               stdout=subprocess.PIPE, text=True, env=child_env(tmp_path))
    flushed = 0
    try:
        deadline = time.monotonic() + 30.0
        while flushed < 3000 and time.monotonic() < deadline:
            line = process.stdout.readline()
            if not line:
                break
            flushed = int(line)
        process.send_signal(signal.SIGKILL)
    finally:
        process.kill()
        process.wait()
        process.stdout.close()
    assert flushed >= 3000, 'the writer did not get going'
    assert not reader.is_complete(path)
    values = [m.message.data for m in reader.iter_messages(path)]
    assert len(values) >= flushed                         # everything flushed is there
    assert values == [float(i) for i in range(len(values))]
    with pytest.raises(reader.TruncatedLogError):
        list(reader.iter_messages(path, strict=True))
    assert reader.read_metadata(path) == {'drill_twin': {'seed': '7'}}
    assert reader.topics(path) == {'/drill_twin/kpi/rop_m_per_h': 'std_msgs/msg/Float64'}
    # mcap's own non-seeking reader reads the same prefix before hitting the cut
    prefix = non_seeking_prefix(path)
    assert len(prefix) >= flushed
    # and a recovered copy is a complete file for indexed readers
    recovered = tmp_path / 'recovered.mcap'
    assert recover_log(path, recovered) == len(values)
    assert reader.is_complete(recovered)
    assert len(list(read_ros2_messages(str(recovered)))) == len(values)
    assert reader.read_metadata(recovered) == {'drill_twin': {'seed': '7'}}


def test_importing_the_recording_layer_does_not_import_rclpy(tmp_path):
    code = ('import sys\n'
            'import drill_twin.recording.mcap_log, drill_twin.recording.reader\n'
            'import drill_twin.viz.rerun_view, drill_twin.recording.recovery\n'
            'import drill_twin.recording.topics\n'
            'assert "rclpy" not in sys.modules, "rclpy imported"\n'
            'assert "rerun" not in sys.modules, "rerun imported"\n')
    subprocess.run([sys.executable, '-c', code], check=True, env=child_env(tmp_path))


def test_per_message_cost_is_small(tmp_path):
    msg = import_message_class('sensor_msgs/msg/JointState')(
        name=['bit_axial', 'bit_rotation'], position=[1.0, 2.0], velocity=[3.0, 4.0],
        effort=[5.0, 6.0])
    n = 2000
    with McapLog(tmp_path / 'speed.mcap') as log:
        log.add_topic(itf.BIT_STATE, 'sensor_msgs/msg/JointState')
        start = time.perf_counter()
        for i in range(n):
            log.write(itf.BIT_STATE, msg, i)
        per_message = (time.perf_counter() - start) / n
    assert per_message < 300e-6, f'{per_message * 1e6:.0f} us per message'


@pytest.mark.parametrize('compression', ['zstd', 'lz4'])
def test_compressed_chunks_and_their_cut_prefix(tmp_path, compression):
    path = tmp_path / f'{compression}.mcap'
    with McapLog(path, compression=compression, chunk_size=2048) as log:
        log.add_topic(itf.KPI_MSE, 'std_msgs/msg/Float64')
        for i in range(2000):
            log.write(itf.KPI_MSE, float64(float(i)), i)
    assert [m.message.data for m in reader.iter_messages(path)] == [float(i) for i in
                                                                    range(2000)]
    assert len(list(read_ros2_messages(str(path)))) == 2000
    cut = tmp_path / 'cut.mcap'
    cut.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    values = [m.message.data for m in reader.iter_messages(cut)]
    assert 0 < len(values) < 2000 and values == [float(i) for i in range(len(values))]


def test_chunks_are_compressed_at_the_chosen_zstd_level(tmp_path):
    """
    Each zstd chunk is the frame zstd makes of its records at ZSTD_LEVEL (not mcap's level 3).

    The stand-in for mcap.writer's zstandard module is in effect.
    """
    import zstandard
    from mcap.records import Chunk
    from drill_twin.recording.mcap_log import ZSTD_LEVEL

    path = tmp_path / 'level.mcap'
    rng = np.random.default_rng(5)
    with McapLog(path, chunk_size=64 * 1024) as log:
        log.add_topic(itf.KPI_MSE, 'std_msgs/msg/Float64')
        for i, value in enumerate(np.cumsum(rng.normal(size=6000))):
            log.write(itf.KPI_MSE, float64(float(value)), i)
    chunks = [r for r in reader.iter_records(path, emit_chunks=True) if isinstance(r, Chunk)]
    assert chunks and all(c.compression == 'zstd' for c in chunks)
    sizes = {level: 0 for level in (3, ZSTD_LEVEL)}
    for chunk in chunks:
        raw = zstandard.ZstdDecompressor().decompress(chunk.data,
                                                      max_output_size=chunk.uncompressed_size)
        for level in sizes:
            sizes[level] += len(zstandard.ZstdCompressor(level=level).compress(raw))
    assert sizes[ZSTD_LEVEL] != sizes[3]               # the data tell the levels apart
    assert sum(len(c.data) for c in chunks) == sizes[ZSTD_LEVEL]
