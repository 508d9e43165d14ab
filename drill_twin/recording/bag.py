"""
A rosbag2 bag on disk: a directory of MCAP split files and its ``metadata.yaml``.

Layout (what ``ros2 bag record -s mcap --max-bag-duration`` leaves)::

    drill_twin_20261201T120000Z/
        metadata.yaml
        drill_twin_20261201T120000Z_0.mcap
        drill_twin_20261201T120000Z_1.mcap
        ...

``metadata.yaml`` is rosbag2's version 9 form (``rosbag2_bagfile_information``): the split
files, every topic with its type, serialization format, offered QoS profiles (a YAML string,
as rosbag2 Jazzy writes it), type hash and message count, the start time and duration (ns),
and the compression fields. Chunk compression (zstd) is inside the MCAP files, so the bag's
``compression_format`` and ``compression_mode`` are empty, as rosbag2 writes them for its
``zstd_fast`` storage preset. It lists only complete splits: it is rewritten (atomically,
a temporary file renamed over it) each time a split is finished, so a killed recorder leaves a
bag whose listed splits all open; the split being written at the kill is on disk beside them,
readable by :mod:`drill_twin.recording.reader` up to its last complete chunk and made whole by
:func:`drill_twin.recording.recovery.recover_log`.

Nothing here imports rclpy.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import yaml

METADATA_FILE = 'metadata.yaml'
METADATA_VERSION = 9
STORAGE_IDENTIFIER = 'mcap'
ROS_DISTRO = 'jazzy'
SPLIT_SUFFIX = '.mcap'
_SPLIT_INDEX = re.compile(r'_(\d+)\.mcap$')


def split_name(bag_name: str, index: int) -> str:
    """File name of split ``index`` of the bag ``bag_name``: ``<bag_name>_<index>.mcap``."""
    return f'{bag_name}_{index}{SPLIT_SUFFIX}'


def is_bag(path: str | os.PathLike) -> bool:
    """Tell whether ``path`` is a directory holding a ``metadata.yaml`` or MCAP files."""
    path = Path(path)
    return path.is_dir() and ((path / METADATA_FILE).is_file()
                              or any(path.glob('*' + SPLIT_SUFFIX)))


@dataclass
class TopicEntry:
    """One topic of the bag: name, 'pkg/msg/Type', QoS YAML string, type hash, count."""

    name: str
    type_name: str
    offered_qos_profiles: str
    type_description_hash: str
    message_count: int = 0


@dataclass
class FileEntry:
    """One complete split: its file name, first log time (ns), duration (ns), count."""

    path: str
    starting_time_ns: int
    duration_ns: int
    message_count: int


@dataclass
class BagMetadata:
    """The content of ``metadata.yaml`` (rosbag2 v9); :meth:`to_yaml` renders it."""

    topics: dict[str, TopicEntry] = field(default_factory=dict)
    files: list[FileEntry] = field(default_factory=list)

    @property
    def message_count(self) -> int:
        return sum(f.message_count for f in self.files)

    @property
    def starting_time_ns(self) -> int:
        return min((f.starting_time_ns for f in self.files if f.message_count), default=0)

    @property
    def duration_ns(self) -> int:
        ends = [f.starting_time_ns + f.duration_ns for f in self.files if f.message_count]
        return max(ends) - self.starting_time_ns if ends else 0

    def to_dict(self) -> dict:
        """Return the ``rosbag2_bagfile_information`` mapping, keys in rosbag2's order."""
        return {'rosbag2_bagfile_information': {
            'version': METADATA_VERSION,
            'storage_identifier': STORAGE_IDENTIFIER,
            'duration': {'nanoseconds': self.duration_ns},
            'starting_time': {'nanoseconds_since_epoch': self.starting_time_ns},
            'message_count': self.message_count,
            'topics_with_message_count': [
                {'topic_metadata': {'name': t.name, 'type': t.type_name,
                                    'serialization_format': 'cdr',
                                    'offered_qos_profiles': t.offered_qos_profiles,
                                    'type_description_hash': t.type_description_hash},
                 'message_count': t.message_count}
                for t in self.topics.values()],
            'compression_format': '',
            'compression_mode': '',
            'relative_file_paths': [f.path for f in self.files],
            'files': [{'path': f.path,
                       'starting_time': {'nanoseconds_since_epoch': f.starting_time_ns},
                       'duration': {'nanoseconds': f.duration_ns},
                       'message_count': f.message_count} for f in self.files],
            'custom_data': None,
            'ros_distro': ROS_DISTRO}}

    def to_yaml(self) -> str:
        return yaml.safe_dump(self.to_dict(), sort_keys=False, default_flow_style=False)

    def write(self, directory: str | os.PathLike) -> None:
        """
        Write ``directory/metadata.yaml`` atomically (temporary file, fsync, rename).

        Raises OSError (e.g. ENOSPC) with the old file, if any, left in place.
        """
        target = Path(directory) / METADATA_FILE
        temporary = target.with_name(METADATA_FILE + '.tmp')
        data = self.to_yaml().encode('utf-8')
        try:
            fd = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
            try:
                view = memoryview(data)
                while view:
                    view = view[os.write(fd, view):]
                os.fsync(fd)
            finally:
                os.close(fd)
            os.replace(temporary, target)
        except OSError:
            try:
                os.unlink(temporary)
            except OSError:
                pass
            raise


def read_bag_metadata(directory: str | os.PathLike) -> dict:
    """Read a bag's ``rosbag2_bagfile_information`` mapping (OSError, ValueError)."""
    path = Path(directory) / METADATA_FILE
    try:
        content = yaml.safe_load(path.read_text(encoding='utf-8'))
        return dict(content['rosbag2_bagfile_information'])
    except (yaml.YAMLError, TypeError, KeyError, UnicodeDecodeError) as error:
        raise ValueError(f'{path}: not a rosbag2 metadata file ({error})') from None


def _split_order(path: Path) -> tuple:
    match = _SPLIT_INDEX.search(path.name)
    return (int(match.group(1)) if match else -1, path.name)


def listed_splits(directory: str | os.PathLike) -> list[Path]:
    """List the splits ``metadata.yaml`` lists (the complete ones), in order; [] without it."""
    directory = Path(directory)
    if not (directory / METADATA_FILE).is_file():
        return []
    info = read_bag_metadata(directory)
    return [directory / Path(name).name for name in info.get('relative_file_paths') or []]


def split_files(path: str | os.PathLike) -> list[Path]:
    """
    Every MCAP file of a log in recording order.

    ``path`` is a single ``.mcap`` file (-> [path]) or a bag directory: the splits its
    ``metadata.yaml`` lists, then any other ``.mcap`` file in it (a split being written, or
    cut by a crash) in split-index order.
    """
    path = Path(path)
    if not path.is_dir():
        return [path]
    listed = listed_splits(path)
    known = {p.name for p in listed}
    others = sorted((p for p in path.glob('*' + SPLIT_SUFFIX) if p.name not in known),
                    key=_split_order)
    return listed + others
