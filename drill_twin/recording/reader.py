"""
Read a twin log back: messages deserialized with rclpy, topics and metadata records.

A log is a rosbag2 bag directory (``metadata.yaml`` and MCAP splits, see
:mod:`drill_twin.recording.bag`) or a single MCAP file. A bag is read split after split:
those ``metadata.yaml`` lists, then any unlisted split (the one being written, or cut by a
crash). Every file must start with the MCAP magic (:class:`NotMcapError` otherwise), but
an unlisted split without it (opened, then cut before its first bytes) holds nothing and is
left out. Each file is read front to back with mcap's streaming reader (no index needed), so a
file cut short yields every message of its complete chunks and stops quietly at the first
record it cannot read (pass ``strict=True`` to get :class:`TruncatedLogError` instead).
Chunk CRCs are checked, so a half-written chunk is never decoded.

rclpy is imported by :func:`iter_messages` only.
"""
from __future__ import annotations

import os
import struct
from pathlib import Path
from typing import Any, Iterable, Iterator, NamedTuple

from mcap.exceptions import McapError
from mcap.opcode import Opcode
from mcap.reader import make_reader
from mcap.records import Channel, Message, Metadata, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import MCAP0_MAGIC

from drill_twin.recording.bag import listed_splits, METADATA_FILE, split_files
from drill_twin.recording.message_types import import_message_class

try:
    from zstandard import ZstdError
except ImportError:                        # pragma: no cover - zstandard comes with mcap
    ZstdError = McapError

# What reading a cut-off or damaged file raises: EndOfFile and friends (McapError), chunk
# CRC mismatches (ValueError), short fixed-size fields (struct.error), decompression errors
# (ZstdError, and RuntimeError from lz4).
_FOOTER_RECORD_SIZE = 1 + 8 + 8 + 8 + 4   # opcode, length, summary_start, offset_start, crc
_DAMAGE = (McapError, ValueError, struct.error, EOFError, ZstdError, RuntimeError)


class TruncatedLogError(McapError):
    """The log ends (or is damaged) before its footer; raised only with ``strict=True``."""


class NotMcapError(ValueError):
    """A file given as a log that does not start with the MCAP magic (one line)."""


def require_mcap(path: str | os.PathLike) -> None:
    """Raise :class:`NotMcapError` unless the file ``path`` starts with the MCAP magic."""
    with open(path, 'rb') as stream:
        start = stream.read(len(MCAP0_MAGIC))
    if start != MCAP0_MAGIC:
        raise NotMcapError(f'{path}: not an MCAP file ('
                           + ('empty' if not start else 'no MCAP magic at its start') + ')')


def _is_mcap(path: Path) -> bool:
    try:
        require_mcap(path)
    except NotMcapError:
        return False
    return True


class LogMessage(NamedTuple):
    """One message of a log; times in integer nanoseconds."""

    topic: str
    type_name: str
    message: Any
    log_time_ns: int
    publish_time_ns: int


def iter_records(path: str | os.PathLike, *, emit_chunks: bool = False,
                 strict: bool = False) -> Iterator[Any]:
    """
    Yield the MCAP records (``mcap.records``) of a log in file order.

    Records inside chunks are yielded unless ``emit_chunks``.  Stops (or, if ``strict``,
    raises :class:`TruncatedLogError`) at the first unreadable record.
    """
    with open(path, 'rb') as stream:
        reader = StreamReader(stream, emit_chunks=emit_chunks, validate_crcs=True)
        records = reader.records
        while True:
            try:
                record = next(records)
            except StopIteration:
                return
            except _DAMAGE as error:
                if strict:
                    raise TruncatedLogError(f'{path}: unreadable from here on: {error!r}'
                                            ) from error
                return
            yield record


def log_files(path: str | os.PathLike) -> list[Path]:
    """
    List the MCAP files of a log (a bag directory or one file) in recording order.

    Raises FileNotFoundError (one line) if ``path`` does not exist, is a directory without
    MCAP files, or a split its ``metadata.yaml`` lists is missing; :class:`NotMcapError` (a
    ValueError) if ``path`` or a listed split is not an MCAP file; ValueError if that
    ``metadata.yaml`` is unreadable. An unlisted split that is not MCAP is left out.
    """
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f'{path}: no such file')
    files = split_files(path)
    for file in files:
        if not file.is_file():
            raise FileNotFoundError(f'{file}: listed in {METADATA_FILE} but missing')
    if path.is_dir():
        listed = set(listed_splits(path))
        files = [file for file in files if file in listed or _is_mcap(file)]
    if not files:
        raise FileNotFoundError(f'{path}: no MCAP files in it (not a log)')
    for file in files:
        require_mcap(file)
    return files


def iter_raw(path: str | os.PathLike, topics: Iterable[str] | None = None, *,
             strict: bool = False) -> Iterator[tuple[Schema | None, Channel, Message]]:
    """
    Yield (schema, channel, message) records of the readable part of a log in order.

    Every split of a bag in turn.
    """
    for file in log_files(path):
        yield from _iter_raw_file(file, topics, strict)


def _iter_raw_file(path, topics, strict: bool):
    wanted = None if topics is None else set(topics)
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    for record in iter_records(path, emit_chunks=False, strict=strict):
        if isinstance(record, Message):
            channel = channels.get(record.channel_id)
            if channel is None:
                if strict:
                    raise TruncatedLogError(f'{path}: message on unknown channel '
                                            f'{record.channel_id}')
                continue
            if wanted is None or channel.topic in wanted:
                yield schemas.get(channel.schema_id), channel, record
        elif isinstance(record, Schema):
            schemas[record.id] = record
        elif isinstance(record, Channel):
            channels[record.id] = record


def iter_messages(path: str | os.PathLike, topics: Iterable[str] | None = None, *,
                  strict: bool = False) -> Iterator[LogMessage]:
    """
    Messages of a log deserialized with rclpy, in file order (= write order).

    :param topics: only these topics (default: all).
    :param strict: raise :class:`TruncatedLogError` instead of stopping at damage.
    """
    from rclpy.serialization import deserialize_message

    for schema, channel, record in iter_raw(path, topics, strict=strict):
        if schema is None:
            raise McapError(f'{path}: topic {channel.topic} has no schema')
        message = deserialize_message(record.data, import_message_class(schema.name))
        yield LogMessage(channel.topic, schema.name, message, record.log_time,
                         record.publish_time)


def _has_footer(stream) -> bool:
    """Tell whether the file ends with a Footer record and the closing magic."""
    tail = len(MCAP0_MAGIC) + _FOOTER_RECORD_SIZE
    if stream.seek(0, os.SEEK_END) < len(MCAP0_MAGIC) + tail:
        return False
    stream.seek(-tail, os.SEEK_END)
    data = stream.read(tail)
    return data[0] == Opcode.FOOTER and data[-len(MCAP0_MAGIC):] == MCAP0_MAGIC


def _summary(path: str | os.PathLike):
    """Return the summary section, or None if the file is unfinished or has none."""
    try:
        with open(path, 'rb') as stream:
            if not _has_footer(stream):
                return None
            stream.seek(0)
            return make_reader(stream).get_summary()
    except _DAMAGE:
        return None


def topics(path: str | os.PathLike) -> dict[str, str]:
    """{topic: 'pkg/msg/Type'} of a log (every split's summary, else by scanning it)."""
    found: dict[str, str] = {}
    for file in log_files(path):
        found.update(_file_topics(file))
    return found


def _file_topics(path) -> dict[str, str]:
    summary = _summary(path)
    if summary is not None and summary.channels:
        return {channel.topic: getattr(summary.schemas.get(channel.schema_id), 'name', '')
                for channel in summary.channels.values()}
    schemas: dict[int, str] = {}
    found: dict[str, str] = {}
    for record in iter_records(path, emit_chunks=False, strict=False):
        if isinstance(record, Schema):
            schemas[record.id] = record.name
        elif isinstance(record, Channel):
            found[record.topic] = schemas.get(record.schema_id, '')
    return found


def read_metadata(path: str | os.PathLike) -> dict[str, dict[str, str]]:
    """
    {record name: {key: value}} of the metadata records of a log (later ones win).

    Every split of a bag carries the same records: the first split is read.
    """
    result: dict[str, dict[str, str]] = {}
    for record in iter_records(log_files(path)[0], emit_chunks=True, strict=False):
        if isinstance(record, Metadata):
            result[record.name] = dict(record.metadata)
    return result


def is_complete(path: str | os.PathLike) -> bool:
    """
    Tell whether the log was finished.

    A file with a readable footer and summary, or a bag whose ``metadata.yaml`` lists every one
    of its MCAP files, each complete.
    """
    path = Path(path)
    if path.is_dir():
        if not (path / METADATA_FILE).is_file():
            return False
        try:
            listed = listed_splits(path)
        except ValueError:
            return False
        return (bool(listed) and split_files(path) == listed
                and all(_summary(f) is not None for f in listed))
    return _summary(path) is not None
