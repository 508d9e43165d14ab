"""
The twin's log.

A rosbag2 bag of every published topic, the commands as applied, and the run description
(:class:`~drill_twin.recording.log_metadata.TwinLogMetadata`).

A failed write (full disk, file-size limit, ...) never raises into the twin: the log is closed
as far as it can be (the last complete split stays listed in ``metadata.yaml``), ``error``
says what happened, and the caller decides (``on_log_error``).
"""
from __future__ import annotations

from pathlib import Path

from drill_twin.recording.bag_writer import BagWriter, DEFAULT_SPLIT_DURATION_S
from drill_twin.recording.log_metadata import RECORD_NAME, TwinLogMetadata
from drill_twin.recording.topics import twin_topics


class TwinLog:
    """
    An open log of a twin run: the bag directory ``path`` for the given stations.

    :param path: the bag directory (created; must not exist or be empty).
    :param stations_m: depths of the measurement stations (m).
    :param metadata: the run description, written into every split.
    :param split_duration_s: log time (s) a split holds at most.
    :param compression: chunk compression ('zstd', 'lz4', 'none').
    :param tf: record /tf and /tf_static too (needs tf2_msgs).
    :param measurement_topics: the rig's sensor topics the twin assimilates (JointState).
    :param scalar_measurement_topics: its channels on topics of their own (Float64).

    Raises OSError if the bag cannot be created.
    """

    def __init__(self, path: str | Path, stations_m, metadata: TwinLogMetadata, *,
                 split_duration_s: float = DEFAULT_SPLIT_DURATION_S,
                 compression: str = 'zstd', tf: bool = False, measurement_topics=(),
                 scalar_measurement_topics=()):
        self.path = Path(path)
        self.error: str | None = None
        self._bag = BagWriter(self.path, split_duration_s=split_duration_s,
                              compression=compression)
        try:
            for topic, spec in twin_topics(
                    stations_m, tf=tf, measurement_topics=measurement_topics,
                    scalar_measurement_topics=scalar_measurement_topics).items():
                self._bag.add_topic(topic, spec.type_name, spec.qos)
            self._bag.add_metadata(RECORD_NAME, metadata.to_record())
        except BaseException:
            self.close()
            raise

    @property
    def open(self) -> bool:
        return self.error is None and not self._bag.closed

    @property
    def split_path(self) -> Path:
        """The split file being written."""
        return self._bag.split_path

    def write(self, topic: str, message, time_ns: int) -> None:
        """Record ``message`` on ``topic`` at the twin's time (ns)."""
        self._guarded(self._bag.write, topic, message, time_ns)

    def write_serialized(self, topic: str, data: bytes, time_ns: int) -> None:
        """Record an already CDR-serialized message on ``topic`` at the twin's time (ns)."""
        self._guarded(self._bag.write_serialized, topic, data, time_ns)

    def flush(self) -> None:
        """Write out the open chunk (it then survives a crash)."""
        self._guarded(self._bag.flush)

    def _guarded(self, call, *args) -> None:
        if not self.open:
            return
        try:
            call(*args)
        except (OSError, ValueError) as error:
            self.error = f'writing the log {self._bag.split_path} failed ({_describe(error)})'
            self.close()                  # the caller reports self.error

    def close(self) -> None:
        """
        Complete the current split and ``metadata.yaml``.

        Safe to call twice. A failure here (e.g. the disk is full) is recorded in ``error`` if
        none is yet.
        """
        try:
            self._bag.finish()
        except OSError as error:
            if self.error is None:
                self.error = (f'completing the log {self._bag.split_path} failed '
                              f'({_describe(error)})')


def _describe(error: Exception) -> str:
    if isinstance(error, OSError) and error.strerror:
        return f'[Errno {error.errno}] {error.strerror}'
    return str(error)
