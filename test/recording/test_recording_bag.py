"""
Twin logs as rosbag2 bags.

Time-bounded MCAP splits and metadata.yaml, read back by the project's reader and by three
independent ones (mcap, mcap_ros2, rosbags), also after the writer was killed; ``drill-twin
recover``; the run description as one dataclass.
"""
from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
from pathlib import Path

import pytest
import yaml
from mcap.reader import make_reader
from mcap_ros2.reader import read_ros2_messages
from rosbags.highlevel import AnyReader
from rosbags.rosbag2 import Reader as Rosbag2Reader

from drill_twin import interface as itf
from drill_twin.recording import reader
from drill_twin.recording.bag import METADATA_FILE, split_files
from drill_twin.recording.bag_writer import BagWriter
from drill_twin.recording.log_metadata import (LogMetadataError, RECORD_NAME,
                                               TwinLogMetadata)
from drill_twin.recording.schemas import type_hash
from synthetic import synthetic_messages
from mcap_probe import non_seeking_prefix
from drill_twin.recording.topics import twin_topics

STATIONS_M = (700.0, 1590.0)
START_NS = 1_700_000_000_000_000_000
SPLIT_S = 1.0
DURATION_S = 3.5
REPO = Path(__file__).resolve().parents[2]
METADATA = TwinLogMetadata(config_yaml='drill_string: {}\n', seed=7, clock_epoch_ns=START_NS,
                           time_step_s=0.01, ensemble_members=2, ensemble_dispersion=0.01,
                           version='test')


def child_env(tmp_path: Path) -> dict:
    return dict(os.environ, RMW_IMPLEMENTATION='rmw_fastrtps_cpp',
                ROS_LOG_DIR=str(tmp_path / 'ros_log'), PYTHONPATH=str(REPO))


@pytest.fixture(scope='module')
def bag(tmp_path_factory):
    """
    Write a bag of every twin topic over 3.5 s split every second.

    Returns (path, expected messages).
    """
    path = tmp_path_factory.mktemp('bags') / 'drill_twin_test'
    expected = []
    with BagWriter(path, split_duration_s=SPLIT_S, chunk_size=4096) as writer:
        for topic, spec in twin_topics(STATIONS_M).items():
            writer.add_topic(topic, spec.type_name, spec.qos)
        writer.add_metadata(RECORD_NAME, METADATA.to_record())
        for item in synthetic_messages(DURATION_S, 20.0, STATIONS_M, START_NS):
            writer.write(item.topic, item.message, item.log_time_ns)
            expected.append(item)
    return path, expected


def test_a_bag_is_a_directory_of_whole_splits(bag):
    path, expected = bag
    names = {p.name for p in path.iterdir()}
    assert names == {METADATA_FILE} | {f'drill_twin_test_{i}.mcap' for i in range(4)}
    total = 0
    for split in split_files(path):
        with open(split, 'rb') as stream:           # the seeking reader needs the footer
            summary = make_reader(stream).get_summary()
        stats = summary.statistics
        assert stats.message_end_time - stats.message_start_time < SPLIT_S * 1e9
        assert {c.topic for c in summary.channels.values()} == set(twin_topics(STATIONS_M))
        assert summary.chunk_indexes and all(c.compression == 'zstd'
                                             for c in summary.chunk_indexes)
        decoded = list(read_ros2_messages(str(split)))
        assert len(decoded) == stats.message_count > 0
        assert reader.read_metadata(split)[RECORD_NAME] == METADATA.to_record()
        total += len(decoded)
    assert total == len(expected)
    assert reader.is_complete(path)


def test_metadata_yaml_is_rosbag2_v9(bag):
    path, expected = bag
    info = yaml.safe_load((path / METADATA_FILE).read_text())['rosbag2_bagfile_information']
    assert info['version'] == 9 and info['storage_identifier'] == 'mcap'
    assert info['compression_format'] == '' and info['compression_mode'] == ''
    assert info['relative_file_paths'] == [f'drill_twin_test_{i}.mcap' for i in range(4)]
    assert info['message_count'] == len(expected) == sum(f['message_count']
                                                         for f in info['files'])
    times = [m.log_time_ns for m in expected]
    assert info['starting_time']['nanoseconds_since_epoch'] == min(times)
    assert info['duration']['nanoseconds'] == max(times) - min(times)
    for entry, split in zip(info['files'], split_files(path)):
        split_times = [m.log_time_ns for m in reader.iter_messages(split)]
        assert entry['path'] == split.name and entry['message_count'] == len(split_times)
        assert entry['starting_time']['nanoseconds_since_epoch'] == min(split_times)
        assert entry['duration']['nanoseconds'] == max(split_times) - min(split_times)
    specs = twin_topics(STATIONS_M)
    for topic in info['topics_with_message_count']:
        meta = topic['topic_metadata']
        spec = specs[meta['name']]
        assert meta['type'] == spec.type_name and meta['serialization_format'] == 'cdr'
        assert meta['type_description_hash'] == type_hash(spec.type_name)
        qos = yaml.safe_load(meta['offered_qos_profiles'])     # a YAML string, as Jazzy
        assert qos[0]['reliability'] == spec.qos.reliability
        assert topic['message_count'] == sum(1 for m in expected if m.topic == meta['name'])


def test_rosbags_reads_every_message_of_the_bag(bag):
    """An independent rosbag2 reader opens the directory and deserialises every type."""
    path, expected = bag
    with AnyReader([path]) as anyreader:
        assert {c.topic for c in anyreader.connections} == set(twin_topics(STATIONS_M))
        got = []
        for connection, timestamp, raw in anyreader.messages():
            message = anyreader.deserialize(raw, connection.msgtype)
            got.append((connection.topic, timestamp, message))
    assert len(got) == len(expected)
    assert {t for t, _, _ in got} == {m.topic for m in expected}
    by_time = {(m.topic, m.log_time_ns): m.message for m in expected}
    for topic, timestamp, message in got:
        if topic == itf.BIT_STATE:
            assert list(message.velocity) == list(by_time[(topic, timestamp)].velocity)


def test_own_reader_reads_the_bag_in_order(bag):
    path, expected = bag
    got = list(reader.iter_messages(path, strict=True))
    assert [(m.topic, m.log_time_ns) for m in got] == [(m.topic, m.log_time_ns)
                                                       for m in expected]
    assert got[-1].message == expected[-1].message
    assert set(reader.topics(path)) == set(twin_topics(STATIONS_M))
    assert TwinLogMetadata.from_record(reader.read_metadata(path)[RECORD_NAME]) == METADATA


def test_a_split_that_is_not_mcap_is_refused_unless_it_is_an_unlisted_one(bag, tmp_path):
    """
    Every file of a log starts with the MCAP magic, else the log is refused (NotMcapError).

    Only an unlisted split (the one being written when the twin died) without the magic is left
    out: it holds nothing.
    """
    path, expected = bag
    copy = tmp_path / 'bag'
    shutil.copytree(path, copy)
    listed = split_files(copy)
    empty = copy / (copy.name + '_9.mcap')
    empty.write_bytes(b'')
    assert reader.log_files(copy) == listed
    assert len(list(reader.iter_raw(copy))) == len(expected)
    listed[1].write_bytes(b'')                                    # a listed split emptied
    with pytest.raises(reader.NotMcapError, match=f'{listed[1]}: not an MCAP file .empty.'):
        reader.log_files(copy)
    text = tmp_path / 'notes.mcap'
    text.write_text('not a log\n')
    with pytest.raises(reader.NotMcapError, match='no MCAP magic at its start'):
        reader.log_files(text)


KILLED_BAG_WRITER = """
import sys, time
from drill_twin.recording.bag_writer import BagWriter
from std_msgs.msg import Float64
bag = BagWriter(sys.argv[1], split_duration_s=0.5, chunk_size=1024, flush_interval_s=None)
bag.add_topic('/drill_twin/kpi/rop_m_per_h', 'std_msgs/msg/Float64')
bag.add_metadata('drill_twin', {'seed': '7'})
for i in range(1830):      # 1 ms apart: splits of 500 messages, the 4th holds 330 so far
    bag.write('/drill_twin/kpi/rop_m_per_h', Float64(data=float(i)), 1_000_000 * i)
    if i == 1799:
        bag.flush()
print(len(bag.completed_splits), flush=True)
time.sleep(600)            # killed here, the last 30 messages in an open chunk
"""


@pytest.fixture(scope='module')
def killed_bag(tmp_path_factory):
    """
    Kill a bag's writer (zstd chunks) mid-split after 3 complete splits.

    Returns (path, messages known flushed).
    """
    folder = tmp_path_factory.mktemp('killed')
    path = folder / 'killed_bag'
    process = subprocess.Popen([sys.executable, '-c', KILLED_BAG_WRITER, str(path)],
                               stdout=subprocess.PIPE, text=True, env=child_env(folder))
    try:
        line = process.stdout.readline()
        process.send_signal(signal.SIGKILL)
    finally:
        process.kill()
        process.wait()
        process.stdout.close()
    assert line.strip() == '3', 'the writer did not get going'
    return path, 1800


def test_killed_bag_lists_whole_splits_and_rosbags_opens_it(killed_bag):
    path, flushed = killed_bag
    files = split_files(path)
    listed = yaml.safe_load((path / METADATA_FILE).read_text())[
        'rosbag2_bagfile_information']['relative_file_paths']
    assert len(files) == len(listed) + 1 and [f.name for f in files[:-1]] == listed
    listed_count = 0
    for split in files[:-1]:
        with open(split, 'rb') as stream:
            listed_count += sum(1 for _ in make_reader(stream).iter_messages())
    with Rosbag2Reader(path) as bagreader:            # only the listed (whole) splits
        values = [t for _, t, _ in bagreader.messages()]
    assert len(values) == listed_count > 0
    assert not reader.is_complete(path)


def test_cut_split_is_read_up_to_its_last_complete_chunk(killed_bag):
    path, flushed = killed_bag
    cut = split_files(path)[-1]
    assert not reader.is_complete(cut)
    with open(cut, 'rb') as stream, pytest.raises(Exception):    # noqa: B017 - no footer
        list(make_reader(stream).iter_messages())
    prefix = non_seeking_prefix(cut)
    assert len(prefix) >= 300                 # the 4th split's messages 1500-1799, flushed
    ours = [m.log_time_ns for m in reader.iter_messages(cut)]
    assert ours == prefix
    # the whole bag through the project's reader: every message up to the cut, none twice
    values = [m.message.data for m in reader.iter_messages(path)]
    assert values == [float(i) for i in range(len(values))] and len(values) >= flushed
    with pytest.raises(reader.TruncatedLogError):
        list(reader.iter_messages(path, strict=True))


def run_cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', 'drill_twin.cli.main', *args],
                          capture_output=True, text=True, timeout=120,
                          env=child_env(cwd), cwd=REPO)


def test_recover_command_makes_the_cut_split_whole(killed_bag, tmp_path):
    path, _ = killed_bag
    cut = split_files(path)[-1]
    fixed = tmp_path / 'fixed.mcap'
    result = run_cli('recover', str(cut), '--out', str(fixed), cwd=tmp_path)
    assert result.returncode == 0, result.stderr
    expected = [m.log_time_ns for m in reader.iter_messages(cut)]
    assert f'recovered {len(expected)} messages' in result.stdout
    with open(fixed, 'rb') as stream:
        mcap = make_reader(stream)
        assert [m.log_time for _, _, m in mcap.iter_messages()] == expected
    decoded = list(read_ros2_messages(str(fixed)))
    assert [m.log_time_ns for m in decoded] == expected
    assert [m.ros_msg.data for m in decoded] == [float(t // 1_000_000) for t in expected]
    assert reader.read_metadata(fixed) == {'drill_twin': {'seed': '7'}}


def test_recover_bad_input_is_one_line(tmp_path, capsys):
    from drill_twin.cli.main import main

    text = tmp_path / 'notes.txt'
    text.write_text('not a log\n')
    cases = [((str(tmp_path / 'none.mcap'), '--out', str(tmp_path / 'a.mcap')),
              f'drill-twin: {tmp_path / "none.mcap"}: no such file'),
             ((str(text), '--out', str(tmp_path / 'b.mcap')),
              f'drill-twin: {text}: not an MCAP file (no MCAP magic at its start)'),
             ((str(text), '--out', str(text)),
              f'drill-twin: --out: {text} is the input file; write elsewhere'),
             ((str(text), '--out', str(tmp_path / 'no' / 'c.mcap')),
              f'drill-twin: --out: {tmp_path / "no"}: no such directory')]
    for args, line in cases:
        assert main(['recover', *args]) == 2
        captured = capsys.readouterr()
        assert captured.err.splitlines() == [line] and captured.out == ''
    assert not (tmp_path / 'b.mcap').exists()


# -- the run description -------------------------------------------------------------------

def test_log_metadata_round_trip_and_keys():
    record = METADATA.to_record()
    assert set(record) == {'config', 'seed', 'clock_epoch_ns', 'time_step_s', 'ensemble_members',
                           'ensemble_dispersion', 'ensemble_process', 'rate_hz', 'substeps',
                           'fast', 'kpi_window_s', 'version', 'assimilation'}
    assert all(isinstance(v, str) for v in record.values())
    assert record['fast'] == 'false' and record['time_step_s'] == '0.01'
    assert TwinLogMetadata.from_record(record) == METADATA
    older = {k: v for k, v in record.items()
             if k not in ('kpi_window_s', 'ensemble_process', 'assimilation')}
    assert TwinLogMetadata.from_record(older).kpi_window_s == 10.0
    assert TwinLogMetadata.from_record(older).assimilation is False


@pytest.mark.parametrize('change, message', [
    ({'seed': None}, "run.mcap: metadata 'drill_twin' has no 'seed'"),
    ({'time_step_s': 'fast'}, "run.mcap: metadata drill_twin.time_step_s: not a float: 'fast'"),
    ({'fast': 'yes'}, "run.mcap: metadata drill_twin.fast: not a bool: 'yes'"),
    ({'time_step_s': '-0.01'},
     'run.mcap: metadata drill_twin.time_step_s: must be a positive number, got -0.01'),
])
def test_bad_log_metadata_is_one_line(change, message):
    record = METADATA.to_record()
    for key, value in change.items():
        if value is None:
            del record[key]
        else:
            record[key] = value
    with pytest.raises(LogMetadataError) as error:
        TwinLogMetadata.from_record(record, source='run.mcap')
    assert str(error.value) == message
