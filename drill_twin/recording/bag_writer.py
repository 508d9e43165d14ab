"""
Write a rosbag2 bag whose MCAP files each hold a bounded span of log time.

:class:`BagWriter` is :class:`~drill_twin.recording.mcap_log.McapLog` split by time, as
rosbag2's ``max_bag_duration``: when a message's log time is ``split_duration_s`` or more past
the first message of the current split, the split is finished (summary, footer: a whole file
any MCAP reader opens), listed in ``metadata.yaml`` (rewritten atomically) and the next split
begins with the same schemas, channels and metadata records. Only the split being written
can be cut by a crash or a full disk. Layout: :mod:`drill_twin.recording.bag`.
"""
from __future__ import annotations

import os
import threading
from pathlib import Path
from typing import Mapping

from drill_twin.interface import QosSpec, STATE_QOS
from drill_twin.recording.bag import BagMetadata, FileEntry, split_name, TopicEntry
from drill_twin.recording.mcap_log import (
    DEFAULT_CHUNK_SIZE, DEFAULT_COMPRESSION, DEFAULT_FLUSH_INTERVAL_S, McapLog)
from drill_twin.recording.message_types import canonical_type_name
from drill_twin.recording.qos import offered_qos_profiles_yaml
from drill_twin.recording.schemas import type_hash

DEFAULT_SPLIT_DURATION_S = 300.0
"""Log time (s) a split holds at most by default (5 minutes)."""


class BagWriter:
    """
    A rosbag2 bag directory of MCAP splits; a context manager, safe to finish twice.

    Usage::

        with BagWriter('runs/drill_twin_X', split_duration_s=300) as bag:
            bag.add_topic(BIT_STATE, 'sensor_msgs/msg/JointState', STATE_QOS)
            bag.add_metadata('drill_twin', record)
            bag.write(BIT_STATE, joint_state, log_time_ns=t_ns)

    :param directory: the bag directory, created (with its parents); must not hold a bag.
    :param split_duration_s: log time (s) after which a new split begins (> 0).
    :param chunk_size, flush_interval_s, compression: as :class:`McapLog`.

    Raises OSError when a file cannot be written (the bag then stays as it was after the
    last complete split, plus the cut current split).
    """

    def __init__(self, directory: str | os.PathLike, *,
                 split_duration_s: float = DEFAULT_SPLIT_DURATION_S,
                 chunk_size: int = DEFAULT_CHUNK_SIZE,
                 flush_interval_s: float | None = DEFAULT_FLUSH_INTERVAL_S,
                 compression: str = DEFAULT_COMPRESSION) -> None:
        if not split_duration_s > 0:
            raise ValueError(f'split_duration_s must be positive, got {split_duration_s!r}')
        self.path = Path(directory)
        self.name = self.path.name
        self._split_ns = int(round(split_duration_s * 1e9))
        self._options = dict(chunk_size=chunk_size, flush_interval_s=flush_interval_s,
                             compression=compression)
        self._lock = threading.RLock()
        self._topics: dict[str, tuple[str, QosSpec]] = {}
        self._records: list[tuple[str, dict[str, str]]] = []
        self._bag = BagMetadata()
        self._index = 0
        self._first_ns: int | None = None     # log-time span of the current split
        self._last_ns: int | None = None
        self._finished = False
        self._split_listed = False            # the current split is in self._bag.files
        self.path.mkdir(parents=True, exist_ok=True)
        if any(self.path.iterdir()):
            raise FileExistsError(f'{self.path} is not empty')
        self._bag.write(self.path)            # an empty bag until the first split is done
        self._log = McapLog(self.path / split_name(self.name, 0), **self._options)

    # -- context manager -------------------------------------------------------------------

    def __enter__(self) -> BagWriter:
        return self

    def __exit__(self, exc_type, exc, traceback) -> None:
        self.finish()

    # -- properties ------------------------------------------------------------------------

    @property
    def closed(self) -> bool:
        return self._finished

    @property
    def split_path(self) -> Path:
        """The split being written (or the last one, once finished)."""
        return Path(self._log.path)

    @property
    def completed_splits(self) -> list[str]:
        """File names of the finished splits (those ``metadata.yaml`` lists)."""
        return [f.path for f in self._bag.files]

    @property
    def message_counts(self) -> dict[str, int]:
        """Messages written so far per topic, over all splits."""
        counts = {topic: entry.message_count for topic, entry in self._bag.topics.items()}
        if not self._split_listed:
            for topic, count in self._log.message_counts.items():
                counts[topic] = counts.get(topic, 0) + count
        return counts

    # -- registration ----------------------------------------------------------------------

    def add_topic(self, topic: str, type_name: str, qos: QosSpec = STATE_QOS) -> None:
        """Register a topic in this and every later split (see :meth:`McapLog.add_topic`)."""
        with self._lock:
            self._check_open()
            self._log.add_topic(topic, type_name, qos)
            canonical = canonical_type_name(type_name)
            if topic not in self._topics:
                self._topics[topic] = (canonical, qos)
                self._bag.topics[topic] = TopicEntry(topic, canonical,
                                                     offered_qos_profiles_yaml(qos),
                                                     type_hash(canonical))

    def add_metadata(self, name: str, data: Mapping[str, str]) -> None:
        """Write a metadata record into this and every later split."""
        with self._lock:
            self._check_open()
            self._log.add_metadata(name, data)
            self._records.append((name, dict(data)))

    # -- messages --------------------------------------------------------------------------

    def write(self, topic: str, msg, log_time_ns: int, publish_time_ns: int | None = None
              ) -> None:
        """Serialize and write ``msg`` (see :meth:`McapLog.write`), splitting when due."""
        with self._lock:
            self._split_if_due(log_time_ns)
            self._log.write(topic, msg, log_time_ns, publish_time_ns)
            self._note(log_time_ns)

    def write_serialized(self, topic: str, data: bytes, log_time_ns: int,
                         publish_time_ns: int | None = None) -> None:
        """Write a CDR-serialized message (see :meth:`McapLog.write_serialized`)."""
        with self._lock:
            self._split_if_due(log_time_ns)
            self._log.write_serialized(topic, data, log_time_ns, publish_time_ns)
            self._note(log_time_ns)

    def flush(self) -> None:
        """Write out the open chunk of the current split."""
        with self._lock:
            self._check_open()
            self._log.flush()

    def _note(self, log_time_ns: int) -> None:
        if self._first_ns is None:
            self._first_ns = self._last_ns = log_time_ns
        else:
            self._first_ns = min(self._first_ns, log_time_ns)
            self._last_ns = max(self._last_ns, log_time_ns)

    def _split_if_due(self, log_time_ns) -> None:
        self._check_open()
        if (self._first_ns is not None and isinstance(log_time_ns, int)
                and log_time_ns - self._first_ns >= self._split_ns):
            self._complete_split()
            self._index += 1
            self._log = McapLog(self.path / split_name(self.name, self._index), **self._options)
            self._first_ns = self._last_ns = None
            self._split_listed = False
            for topic, (type_name, qos) in self._topics.items():
                self._log.add_topic(topic, type_name, qos)
            for name, record in self._records:
                self._log.add_metadata(name, record)

    def _complete_split(self) -> None:
        """
        Finish the current split and list it in ``metadata.yaml``.

        Lists it again if writing ``metadata.yaml`` failed the last time.
        """
        if not self._split_listed:
            self._log.finish()
            counts = self._log.message_counts
            for topic, count in counts.items():
                self._bag.topics[topic].message_count += count
            first = self._first_ns if self._first_ns is not None else 0
            last = self._last_ns if self._last_ns is not None else first
            self._bag.files.append(FileEntry(self.split_path.name, first, last - first,
                                             sum(counts.values())))
            self._split_listed = True
        self._bag.write(self.path)

    # -- ending ----------------------------------------------------------------------------

    def finish(self) -> None:
        """
        Finish the current split and write the final ``metadata.yaml``.

        Later calls do nothing. Raises OSError if that fails (the current split is then not
        listed).
        """
        with self._lock:
            if self._finished:
                return
            self._finished = True
            self._complete_split()

    close = finish

    def _check_open(self) -> None:
        if self._finished:
            raise ValueError(f'bag {self.path} is already finished')
