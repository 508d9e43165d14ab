"""
Write the twin's topics to an MCAP file that rosbag2 and rerun read.

The file has what ``rosbag2_storage_mcap`` (Jazzy) writes:

- profile ``ros2``, message encoding ``cdr``, one schema per message type named
  'pkg/msg/Type' with encoding ``ros2msg`` (see :mod:`drill_twin.recording.schemas`);
- per channel the metadata ``offered_qos_profiles`` (rosbag2 v9 YAML) and ``topic_type_hash``;
- a summary with Statistics, chunk and metadata indexes.

It has no ``rosbag2`` metadata record: rosbag2 then builds the topic list from the channels
(a partial ``rosbag2`` record would break ``ros2 bag info``).

Data go out in zstd-compressed chunks (level :data:`ZSTD_LEVEL`, 256 KiB of messages at
most) and, at least once a second
of wall time, the open chunk is written out, so a killed process leaves a readable prefix: all
but the last second or so of messages (each chunk is compressed on its own and carries the CRC
of its content, so a reader stops cleanly at the first incomplete one).  Each chunk reaches
the operating system with plain ``write`` calls (no user-space buffer), so SIGKILL loses only
the chunk in progress.

Times are integer nanoseconds.  ``log_time`` is when the message was recorded (what rosbag2
plays back by); ``publish_time`` defaults to it.
"""
from __future__ import annotations

import contextlib
import importlib.metadata
import operator
import os
import signal
import threading
import time
from typing import Mapping

import mcap.writer
from mcap.writer import CompressionType, LIBRARY_IDENTIFIER, Writer
import zstandard

from drill_twin.interface import QosSpec, STATE_QOS
from drill_twin.recording.message_types import canonical_type_name, import_message_class
from drill_twin.recording.qos import offered_qos_profiles_yaml
from drill_twin.recording.schemas import (
    MESSAGE_ENCODING, ros2msg_schema, SCHEMA_ENCODING, type_hash)

PROFILE = 'ros2'
DEFAULT_CHUNK_SIZE = 256 * 1024
"""Bytes of messages gathered before a chunk is written (rosbag2's default is 768 KiB; the
twin's second of data is 100-200 KiB, and larger chunks compress only 1 % better)."""
DEFAULT_COMPRESSION = 'zstd'
"""Chunk compression: zstd stores the twin's data in about a fifth of the space."""
ZSTD_LEVEL = 6
"""zstd level of the chunks. Measured on a 120 s fast run of the shipped twin (1 s chunks):
level 3 (zstd's default) 116 MB/h, 5 to 9 108.5 MB/h (the message indexes excluded), at
about 1 % of a core; 19 would save 4 % more for 25 % of a core."""
DEFAULT_FLUSH_INTERVAL_S = 1.0
"""Seconds, of the wall clock or of log time whichever passes first, after which an open
chunk is written out even if not full: a crash loses at most that much of the log, also when
the twin runs faster than real time."""

_UINT64_END = 1 << 64
_COMPRESSION = {'none': CompressionType.NONE, 'zstd': CompressionType.ZSTD,
                'lz4': CompressionType.LZ4}


def library_string() -> str:
    """Return the MCAP header's library field: drill_twin and mcap writer versions."""
    try:
        ours = importlib.metadata.version('drill_twin')
    except importlib.metadata.PackageNotFoundError:
        ours = 'unknown'
    return f'drill_twin {ours}; {LIBRARY_IDENTIFIER}'


class _LeveledZstd:
    """
    Stands in for the ``zstandard`` module inside :mod:`mcap.writer`.

    mcap's Writer compresses a chunk with ``zstandard.compress(data)`` (zstd's default level 3)
    and has no option for the level; this object gives it the same call at ``level``. A new
    compressor per chunk: a ``ZstdCompressor`` must not be shared between threads.
    """

    def __init__(self, level: int) -> None:
        self.level = level

    def compress(self, data: bytes) -> bytes:
        """Compress ``data`` into one zstd frame at this level."""
        return zstandard.ZstdCompressor(level=self.level).compress(data)


def use_zstd_level(level: int = ZSTD_LEVEL) -> None:
    """Make every mcap Writer of this process compress its zstd chunks at ``level``."""
    mcap.writer.zstandard = _LeveledZstd(level)


class _KernelFile:
    """
    A write-only file whose every ``write`` reaches the kernel in full.

    The mcap writer calls ``write`` only when a record or a whole chunk is complete, so no
    user-space buffer is needed and none can be lost when the process is killed.  (Not an
    ``io.RawIOBase``: the mcap Writer would wrap that in a BufferedWriter.)
    """

    def __init__(self, path: str | os.PathLike) -> None:
        self._fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        self._position = 0

    def write(self, data) -> int:
        view = memoryview(data).cast('B')
        total = len(view)
        while view:
            view = view[os.write(self._fd, view):]
        self._position += total
        return total

    def tell(self) -> int:
        return self._position

    def flush(self) -> None:
        """Nothing to do: nothing is buffered."""

    def close(self) -> None:
        if self._fd >= 0:
            fd, self._fd = self._fd, -1
            os.close(fd)


def _check_time(value, what: str) -> int:
    value = operator.index(value)
    if not 0 <= value < _UINT64_END:
        raise ValueError(f'{what} must be in [0, 2**64) ns, got {value}')
    return value


_STOP_SIGNALS = {signal.SIGINT, signal.SIGTERM}


@contextlib.contextmanager
def _signals_deferred():
    """
    Hold SIGINT and SIGTERM back from this thread while the writer writes records.

    A Python handler (KeyboardInterrupt) raised between two bytes of a chunk would leave half
    a record in the file, and the summary that ``finish`` then writes after it would make a
    complete-looking file no reader can read through. The signal is delivered when the block
    is left.
    """
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, _STOP_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


class McapLog:
    """
    A rosbag2-compatible MCAP log; a context manager, safe to finish twice.

    Usage::

        with McapLog('run.mcap') as log:
            log.add_topic(BIT_STATE, 'sensor_msgs/msg/JointState', STATE_QOS)
            log.add_metadata('drill_twin', TwinLogMetadata(...).to_record())
            log.write(BIT_STATE, joint_state, log_time_ns=t_ns)

    ``write`` is thread safe.  An exception raised by ``write`` (bad message, bad time,
    unknown topic) leaves the file unchanged.

    :param path: file to create (overwritten if it exists).
    :param chunk_size: bytes of messages per chunk; smaller loses less on a crash.
    :param flush_interval_s: seconds of the wall clock or of log time (whichever passes
        first) after which an open chunk is written out; ``None`` writes chunks only when
        full.
    :param compression: 'zstd' (default), 'lz4' or 'none' per chunk.
    """

    def __init__(self, path: str | os.PathLike, *, chunk_size: int = DEFAULT_CHUNK_SIZE,
                 flush_interval_s: float | None = DEFAULT_FLUSH_INTERVAL_S,
                 compression: str = DEFAULT_COMPRESSION) -> None:
        from rclpy.serialization import serialize_message

        if compression not in _COMPRESSION:
            raise ValueError(f'compression must be one of {sorted(_COMPRESSION)}')
        if chunk_size < 1:
            raise ValueError('chunk_size must be positive')
        self._serialize = serialize_message
        self.path = os.fspath(path)
        self._lock = threading.Lock()
        self._schema_ids: dict[str, int] = {}
        self._channels: dict[str, tuple[int, type, str]] = {}  # topic -> (id, class, type)
        self._counts: dict[str, int] = {}
        self._flush_interval_ns = (None if flush_interval_s is None
                                   else int(flush_interval_s * 1e9))
        use_zstd_level()
        self._raw = _KernelFile(self.path)
        try:
            self._writer = Writer(self._raw, chunk_size=chunk_size,
                                  compression=_COMPRESSION[compression])
            self._writer.start(profile=PROFILE, library=library_string())
        except BaseException:
            self._raw.close()
            raise
        self._last_flush_ns = time.monotonic_ns()
        self._last_flush_log_ns: int | None = None     # log time of the open chunk's start
        self._finished = False

    # -- context manager -------------------------------------------------------------------

    def __enter__(self) -> McapLog:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.finish()

    # -- properties ------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        """True once :meth:`finish` (or :meth:`close`) has run."""
        return self._finished

    @property
    def topics(self) -> dict[str, str]:
        """Registered topics and their types, {'/topic': 'pkg/msg/Type'}."""
        return {topic: entry[2] for topic, entry in self._channels.items()}

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far per topic."""
        return dict(self._counts)

    # -- registration ----------------------------------------------------------------------

    def add_topic(self, topic: str, type_name: str, qos: QosSpec = STATE_QOS) -> int:
        """
        Register a topic (schema and channel); returns its MCAP channel id.

        Registering the same topic again with the same type returns the existing channel.

        :param topic: absolute topic name, e.g. '/drill_twin/bit/state'.
        :param type_name: 'pkg/msg/Type' (or 'pkg/Type').
        :param qos: the QoS the topic's publisher offers (stored for rosbag2 playback).
        """
        if not topic.startswith('/'):
            raise ValueError(f'topic must be absolute, got {topic!r}')
        canonical = canonical_type_name(type_name)
        with self._lock:
            self._check_open()
            if topic in self._channels:
                channel_id, _, existing = self._channels[topic]
                if existing != canonical:
                    raise ValueError(f'{topic} is already registered as {existing}')
                return channel_id
            # Everything that can fail comes before the writer is touched.
            cls = import_message_class(canonical)
            metadata = {'offered_qos_profiles': offered_qos_profiles_yaml(qos),
                        'topic_type_hash': type_hash(canonical)}
            schema_id = self._schema_ids.get(canonical)
            if schema_id is None:
                schema_text = ros2msg_schema(canonical).encode('utf-8')
                schema_id = self._writer.register_schema(
                    name=canonical, encoding=SCHEMA_ENCODING, data=schema_text)
                self._schema_ids[canonical] = schema_id
            channel_id = self._writer.register_channel(
                topic=topic, message_encoding=MESSAGE_ENCODING, schema_id=schema_id,
                metadata=metadata)
            self._channels[topic] = (channel_id, cls, canonical)
            self._counts[topic] = 0
            return channel_id

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a metadata record (string keys and values), e.g. name 'drill_twin'."""
        if not isinstance(name, str):
            raise TypeError('metadata name must be a str')
        record = dict(data)
        for key, value in record.items():
            if not isinstance(key, str) or not isinstance(value, str):
                raise TypeError(f'metadata {name!r}: keys and values must be str, '
                                f'got {key!r}: {type(value).__name__}')
        with self._lock:
            self._check_open()
            self._writer.add_metadata(name, record)

    # -- messages --------------------------------------------------------------------------

    def write(self, topic: str, msg, log_time_ns: int, publish_time_ns: int | None = None
              ) -> None:
        """
        Serialize ``msg`` (CDR, rclpy) and write it on ``topic``.

        :param log_time_ns: receive/record time, ns (rosbag2 plays back by it).
        :param publish_time_ns: send time, ns; defaults to ``log_time_ns``.
        """
        entry = self._channels.get(topic)
        if entry is None:
            raise KeyError(f'topic {topic!r} was not added (call add_topic first)')
        if type(msg) is not entry[1]:
            raise TypeError(f'{topic} carries {entry[2]}, got {type(msg).__name__}')
        data = self._serialize(msg)
        self._write(topic, entry[0], data, log_time_ns, publish_time_ns)

    def write_serialized(self, topic: str, data: bytes, log_time_ns: int,
                         publish_time_ns: int | None = None) -> None:
        """Write an already CDR-serialized message (e.g. from a generic subscription)."""
        entry = self._channels.get(topic)
        if entry is None:
            raise KeyError(f'topic {topic!r} was not added (call add_topic first)')
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise TypeError('data must be bytes')
        self._write(topic, entry[0], bytes(data), log_time_ns, publish_time_ns)

    def _write(self, topic: str, channel_id: int, data: bytes, log_time_ns,
               publish_time_ns) -> None:
        log_time_ns = _check_time(log_time_ns, 'log_time_ns')
        publish_time_ns = (log_time_ns if publish_time_ns is None
                           else _check_time(publish_time_ns, 'publish_time_ns'))
        with self._lock:
            self._check_open()
            if (self._flush_interval_ns is not None and self._last_flush_log_ns is not None
                    and log_time_ns - self._last_flush_log_ns >= self._flush_interval_ns):
                self._flush_locked()                 # a chunk spans one interval of log time
            with _signals_deferred():               # a full chunk is written here
                self._writer.add_message(channel_id=channel_id, log_time=log_time_ns,
                                         data=data, publish_time=publish_time_ns, sequence=0)
            self._counts[topic] += 1
            if self._flush_interval_ns is not None:
                if self._last_flush_log_ns is None:
                    self._last_flush_log_ns = log_time_ns
                if time.monotonic_ns() - self._last_flush_ns >= self._flush_interval_ns:
                    self._flush_locked()

    # -- ending ----------------------------------------------------------------------------

    def flush(self) -> None:
        """Write out the open chunk now (the data then survive a crash)."""
        with self._lock:
            self._check_open()
            self._flush_locked()

    def _flush_locked(self) -> None:
        with _signals_deferred():
            self._writer.flush()
        self._last_flush_ns = time.monotonic_ns()
        self._last_flush_log_ns = None

    def finish(self) -> None:
        """Write the summary and footer and close the file; later calls do nothing."""
        with self._lock:
            if self._finished:
                return
            self._finished = True
            try:
                with _signals_deferred():
                    self._writer.finish()
            finally:
                self._raw.close()

    close = finish

    def _check_open(self) -> None:
        if self._finished:
            raise ValueError(f'MCAP log {self.path} is already finished')
