"""
The twin log's run description: one frozen dataclass, written and read by the same code.

The twin node writes it into every split of its log as the MCAP metadata record
``drill_twin`` (string keys and values); ``drill-twin replay --resimulate`` reads it back with
:meth:`TwinLogMetadata.from_record` to rebuild the run. The keys are a contract:

| key | value |
|---|---|
| ``config`` | the model configuration as YAML text |
| ``seed`` | seed of the ensemble (decimal) |
| ``version`` | drill_twin's version |
| ``ensemble_members``, ``ensemble_dispersion``, ``ensemble_process`` | the ensemble |
| ``rate_hz``, ``substeps``, ``time_step_s``, ``fast`` | the pacing (Hz, steps a tick, s) |
| ``clock_epoch_ns`` | the twin clock's origin: ROS time (ns) at model time zero |
| ``kpi_window_s`` | moving window of the stick-slip severity and MSE (s) |
| ``assimilation`` | the ensemble assimilated the rig's measurements (it depended on them) |

Booleans are ``true``/``false``, floats ``repr`` (exact round trip). Nothing here imports
rclpy.
"""
from __future__ import annotations

import dataclasses
import math
import operator
from dataclasses import dataclass
from typing import Mapping

RECORD_NAME = 'drill_twin'
"""Name of the MCAP metadata record holding :class:`TwinLogMetadata`."""


class LogMetadataError(ValueError):
    """A ``drill_twin`` metadata record that is missing or has a bad value (one line)."""


@dataclass(frozen=True)
class TwinLogMetadata:
    """
    What a twin log needs to be re-simulated (see the module docstring for the keys).

    :param config_yaml: the model configuration as YAML text.
    :param seed: seed of the ensemble.
    :param clock_epoch_ns: ROS time (ns) of model time zero (0 in fast mode).
    :param time_step_s: model time step (s).
    :param ensemble_members: realizations of the random bit-rock law.
    :param ensemble_dispersion: dispersion delta of the ensemble's germs.
    :param ensemble_process: the ensemble ran in a worker process.
    :param rate_hz: tick rate of the node (Hz).
    :param substeps: model steps a tick.
    :param fast: the twin ran as fast as it could (publishing /clock).
    :param kpi_window_s: moving window of the KPIs (s).
    :param version: drill_twin's version that wrote the log.
    :param assimilation: the ensemble was an ensemble Kalman filter's (it depended on the
        rig's samples: a resimulation cannot reproduce it).
    """

    config_yaml: str
    seed: int
    clock_epoch_ns: int
    time_step_s: float
    ensemble_members: int
    ensemble_dispersion: float
    ensemble_process: bool = True
    rate_hz: float = 100.0
    substeps: int = 1
    fast: bool = False
    kpi_window_s: float = 10.0
    version: str = '?'
    assimilation: bool = False

    def __post_init__(self) -> None:
        for name in ('seed', 'clock_epoch_ns', 'ensemble_members', 'substeps'):
            value = getattr(self, name)
            if isinstance(value, bool) or operator.index(value) < 0:
                raise LogMetadataError(f'{name}: must be a non-negative integer, got {value!r}')
        for name in ('time_step_s', 'rate_hz', 'kpi_window_s'):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise LogMetadataError(f'{name}: must be a positive number, got {value!r}')
        if not (math.isfinite(self.ensemble_dispersion) and self.ensemble_dispersion >= 0):
            raise LogMetadataError(f'ensemble_dispersion: must be >= 0, got '
                                   f'{self.ensemble_dispersion!r}')

    @property
    def time_step_ns(self) -> int:
        """The model time step in integer nanoseconds (the log's stamps advance by it)."""
        return int(round(self.time_step_s * 1e9))

    def to_record(self) -> dict[str, str]:
        """Return the metadata record's string pairs (keys of the module docstring)."""
        record = {}
        for field in dataclasses.fields(self):
            value = getattr(self, field.name)
            record[_KEYS.get(field.name, field.name)] = _text(value)
        return record

    @classmethod
    def from_record(cls, record: Mapping[str, str], source: str = 'log'
                    ) -> TwinLogMetadata:
        """
        Parse a ``drill_twin`` record; raise :class:`LogMetadataError` naming the key.

        Keys added after the first logs (``ensemble_process``, ``rate_hz``, ``substeps``,
        ``fast``, ``kpi_window_s``, ``version``, ``assimilation``) take their defaults when
        missing.
        """
        values = {}
        for field in dataclasses.fields(cls):
            key = _KEYS.get(field.name, field.name)
            if key not in record:
                if field.default is dataclasses.MISSING:
                    raise LogMetadataError(f'{source}: metadata {RECORD_NAME!r} has no {key!r}')
                continue
            try:
                values[field.name] = _PARSERS[field.type](record[key])
            except ValueError:
                raise LogMetadataError(f'{source}: metadata {RECORD_NAME}.{key}: not a '
                                       f'{field.type}: {record[key]!r}') from None
        try:
            return cls(**values)
        except LogMetadataError as error:
            raise LogMetadataError(f'{source}: metadata {RECORD_NAME}.{error}') from None


_KEYS = {'config_yaml': 'config'}
"""Field names whose record key differs."""


def _text(value) -> str:
    if isinstance(value, bool):
        return 'true' if value else 'false'
    if isinstance(value, float):
        return repr(value)
    return str(value)


def _boolean(text: str) -> bool:
    if text not in ('true', 'false'):
        raise ValueError(text)
    return text == 'true'


_PARSERS = {'str': str, 'int': int, 'float': float, 'bool': _boolean}
