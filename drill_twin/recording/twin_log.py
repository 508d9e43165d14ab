"""The twin's MCAP log: every published topic, the commands as applied, metadata.

A failed write never stops the twin: the log is closed, the failure reported once, and the
twin runs on without it.
"""
from __future__ import annotations

from pathlib import Path

from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.topics import twin_topics

METADATA_NAME = 'drill_twin'


class TwinLog:
    """An open log of a twin run at ``path`` for the given stations.

    ``metadata``: string pairs stored in the ``drill_twin`` record with the model
    configuration (YAML) and the seed. Raises OSError if the file cannot be created.
    """

    def __init__(self, path: str | Path, stations_m, config_yaml: str, seed: int,
                 metadata: dict[str, str]):
        self.path = Path(path)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self._log = McapLog(self.path)
        self.error: str | None = None
        for topic, spec in twin_topics(stations_m).items():
            self._log.add_topic(topic, spec.type_name, spec.qos)
        self._log.add_twin_metadata(config_yaml, seed, metadata)

    @property
    def open(self) -> bool:
        return self.error is None and not self._log.closed

    def write(self, topic: str, message, time_ns: int) -> None:
        """Record ``message`` on ``topic`` at the twin's time (ns)."""
        self._guarded(self._log.write, topic, message, time_ns)

    def write_serialized(self, topic: str, data: bytes, time_ns: int) -> None:
        """Record an already CDR-serialized message on ``topic`` at the twin's time (ns)."""
        self._guarded(self._log.write_serialized, topic, data, time_ns)

    def _guarded(self, write, *args) -> None:
        if not self.open:
            return
        try:
            write(*args)
        except (OSError, ValueError) as error:
            self.error = f'writing {self.path} failed ({error}); the twin runs on without a log'
            self.close()                  # the caller reports self.error

    def flush(self) -> None:
        if self.open:
            try:
                self._log.flush()
            except OSError as error:
                self.error = f'flushing {self.path} failed ({error})'
                self.close()

    def close(self) -> None:
        """Complete the file (summary, footer); safe to call twice."""
        try:
            self._log.finish()
        except OSError:
            pass
