"""
Turn a log cut short (killed recorder, full disk) into a complete MCAP file.

The readable prefix (every complete chunk, see :mod:`drill_twin.recording.reader`) is copied
record by record into a new file with a summary and footer, so that tools that need the
index (rosbag2, rerun's importer, seeking readers) can open it.
"""
from __future__ import annotations

import os

from mcap.records import Channel, Header, Message, Metadata, Schema
from mcap.writer import CompressionType, Writer

from drill_twin.recording.mcap_log import (DEFAULT_CHUNK_SIZE, library_string, PROFILE,
                                           use_zstd_level)
from drill_twin.recording.reader import iter_records, require_mcap


def recover_log(source: str | os.PathLike, destination: str | os.PathLike) -> int:
    """
    Copy the readable records of ``source`` into a complete MCAP ``destination``.

    Schemas, channels (with their metadata), messages (times unchanged) and metadata
    records are kept; the header's profile is kept; chunks are zstd-compressed.  Returns
    the number of messages copied.  Raises
    :class:`~drill_twin.recording.reader.NotMcapError` if ``source`` is not an MCAP file
    (nothing is written then).
    """
    if os.path.realpath(source) == os.path.realpath(destination):
        raise ValueError('recover_log needs a destination different from the source')
    require_mcap(source)
    schema_ids: dict[int, int] = {}
    channel_ids: dict[int, int] = {}
    schemas: dict[int, Schema] = {}
    pending_channels: dict[int, Channel] = {}
    copied = 0
    use_zstd_level()
    with open(destination, 'wb') as stream:
        writer = Writer(stream, chunk_size=DEFAULT_CHUNK_SIZE, compression=CompressionType.ZSTD)
        started = False
        for record in iter_records(source):
            if isinstance(record, Header):
                writer.start(profile=record.profile or PROFILE,
                             library=f'{library_string()} (recovered from {record.library})')
                started = True
                continue
            if not started:
                writer.start(profile=PROFILE, library=library_string() + ' (recovered)')
                started = True
            if isinstance(record, Schema):
                schemas[record.id] = record
            elif isinstance(record, Channel):
                pending_channels[record.id] = record
            elif isinstance(record, Metadata):
                writer.add_metadata(record.name, dict(record.metadata))
            elif isinstance(record, Message):
                channel_id = _channel_id(writer, record.channel_id, pending_channels, schemas,
                                         schema_ids, channel_ids)
                if channel_id is None:
                    continue
                writer.add_message(channel_id=channel_id, log_time=record.log_time,
                                   data=record.data, publish_time=record.publish_time,
                                   sequence=record.sequence)
                copied += 1
        if not started:
            writer.start(profile=PROFILE, library=library_string() + ' (recovered)')
        for old_id in list(pending_channels):            # channels that had no messages
            _channel_id(writer, old_id, pending_channels, schemas, schema_ids, channel_ids)
        writer.finish()
    return copied


def _channel_id(writer: Writer, old_id: int, pending: dict[int, Channel],
                schemas: dict[int, Schema], schema_ids: dict[int, int],
                channel_ids: dict[int, int]) -> int | None:
    """Return the new id of channel ``old_id``; register it and its schema on first use."""
    if old_id in channel_ids:
        return channel_ids[old_id]
    channel = pending.pop(old_id, None)
    if channel is None:
        return None
    new_schema_id = 0
    if channel.schema_id != 0:
        if channel.schema_id not in schema_ids:
            schema = schemas.get(channel.schema_id)
            if schema is None:
                return None
            schema_ids[channel.schema_id] = writer.register_schema(
                name=schema.name, encoding=schema.encoding, data=schema.data)
        new_schema_id = schema_ids[channel.schema_id]
    channel_ids[old_id] = writer.register_channel(
        topic=channel.topic, message_encoding=channel.message_encoding,
        schema_id=new_schema_id, metadata=dict(channel.metadata))
    return channel_ids[old_id]
