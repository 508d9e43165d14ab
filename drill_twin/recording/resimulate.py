"""
Re-run a logged twin on its recorded commands and seed, and compare the bit state.

The log is a bag directory or one of its MCAP files, read by :mod:`drill_twin.recording.reader`
beside this module. Its
``drill_twin`` metadata (:class:`~drill_twin.recording.log_metadata.TwinLogMetadata`, read
with the code the node writes it with) holds the model configuration, the seed, the ensemble
and the time step; the accepted commands are recorded at the twin time at which they took
effect (the start of the next model step). Stepping a new engine and applying each command
before the step that starts at its time reproduces the run: the mean model's bit state and the
ensemble's mean and 2.5 % / 97.5 % bounds (drawn again from the recorded seed). With the same
version of drill_twin both are identical bit for bit, whether the ensemble ran in the node's
process or in a worker process (the re-run integrates it in this process).
"""
from __future__ import annotations

from dataclasses import dataclass

import yaml
from threadpoolctl import threadpool_limits

from drill_twin import interface as itf
from drill_twin.config import build_config
from drill_twin.recording.log_metadata import RECORD_NAME, TwinLogMetadata
from drill_twin.recording.reader import iter_messages, read_metadata
from drill_twin.twin.engine import CommandLimits, EnsembleSettings, TwinEngine
from drill_twin.twin.ensemble import BIT_FIELDS as FIELDS

ENSEMBLE_TOPICS = {itf.ENSEMBLE_MEAN: 'ensemble_mean', itf.ENSEMBLE_LOWER: 'ensemble_lower',
                   itf.ENSEMBLE_UPPER: 'ensemble_upper'}


@dataclass(frozen=True)
class Resimulation:
    """
    The outcome of a re-simulation.

    compared: bit-state messages compared; max_difference: per field, the largest absolute
    difference (SI units); ensemble_compared / ensemble_max_difference: the same over the
    ensemble mean and bound messages; recorded_version: drill_twin's version in the log;
    commands: commands replayed; assimilated: the logged ensemble assimilated the rig's
    samples (it is not resimulated).
    """

    compared: int
    max_difference: dict
    recorded_version: str
    commands: int
    ensemble_compared: int = 0
    ensemble_max_difference: dict | None = None
    assimilated: bool = False

    @property
    def identical(self) -> bool:
        differences = list(self.max_difference.values())
        differences += list((self.ensemble_max_difference or {}).values())
        return self.compared > 0 and all(v == 0.0 for v in differences)


def _stamp_ns(message) -> int:
    stamp = message.header.stamp
    return stamp.sec * 1_000_000_000 + stamp.nanosec


def _values(message) -> tuple:
    return (message.position[0], message.velocity[0], message.effort[0],
            message.position[1], message.velocity[1], message.effort[1])


PROGRESS_EVERY_STEPS = 1000
"""Model steps between two calls of the progress callback."""


def resimulate(path, progress=None) -> Resimulation:
    """
    Re-run the twin of the log at ``path`` and compare its recorded bit states.

    :param progress: called as ``progress(done_s, total_s)`` (simulated seconds) every
        :data:`PROGRESS_EVERY_STEPS` steps and at the end, e.g. a
        :class:`~drill_twin.cli.progress.ProgressBar`.
    """
    record = read_metadata(path).get(RECORD_NAME)
    if not record:
        raise ValueError(f'{path}: no {RECORD_NAME} metadata record (not a twin log?)')
    metadata = TwinLogMetadata.from_record(record, source=str(path))
    config = build_config(yaml.safe_load(metadata.config_yaml), source=str(path))
    epoch = metadata.clock_epoch_ns
    dt_ns = metadata.time_step_ns
    commands, recorded, ensemble_recorded = [], {}, {}
    # An assimilating twin's ensemble followed the rig's samples: only its mean model is
    # resimulated.
    members = 0 if metadata.assimilation else metadata.ensemble_members
    topics = [itf.CMD_TOP_DRIVE_SPEED, itf.CMD_HOOK_LOAD, itf.BIT_STATE,
              *(ENSEMBLE_TOPICS if members else ())]
    for item in iter_messages(path, topics=topics):
        if item.topic == itf.BIT_STATE:
            recorded[_stamp_ns(item.message)] = item.message
        elif item.topic in ENSEMBLE_TOPICS:
            ensemble_recorded.setdefault(_stamp_ns(item.message), []).append(
                (ENSEMBLE_TOPICS[item.topic], item.message))
        else:
            commands.append((item.log_time_ns, item.topic, item.message.data))
    commands.sort(key=lambda c: c[0])
    with threadpool_limits(limits=1, user_api='blas'):
        engine = TwinEngine(
            config, EnsembleSettings(members=members,
                                     dispersion=metadata.ensemble_dispersion,
                                     seed=metadata.seed),
            CommandLimits(top_drive_speed_max_rad_per_s=float('inf'),
                          hook_load_min_n=-float('inf'), hook_load_max_n=float('inf')),
            kpi_window_s=metadata.kpi_window_s)
        try:
            last = max(recorded) if recorded else epoch
            steps = (last - epoch) // dt_ns
            differences = {field: 0.0 for field in FIELDS}
            ensemble_differences = {field: 0.0 for field in FIELDS}
            compared = ensemble_compared = 0
            pending = 0
            for k in range(steps + 1):
                now = epoch + k * dt_ns
                while pending < len(commands) and commands[pending][0] <= now:
                    _, topic, value = commands[pending]
                    (engine.set_top_drive_speed if topic == itf.CMD_TOP_DRIVE_SPEED
                     else engine.set_hook_load)(value)
                    pending += 1
                snapshot = engine.snapshot()
                if now in recorded:
                    bit = snapshot.bit
                    ours = tuple(getattr(bit, field) for field in FIELDS)
                    for field, a, b in zip(FIELDS, ours, _values(recorded[now])):
                        differences[field] = max(differences[field], abs(a - b))
                    compared += 1
                if snapshot.ensemble_step is not None:
                    stamp = epoch + snapshot.ensemble_step * dt_ns
                    for name, message in ensemble_recorded.pop(stamp, ()):
                        state = getattr(snapshot, name)
                        ours = tuple(getattr(state, field) for field in FIELDS)
                        for field, a, b in zip(FIELDS, ours, _values(message)):
                            ensemble_differences[field] = max(ensemble_differences[field],
                                                              abs(a - b))
                        ensemble_compared += 1
                if k < steps:
                    engine.advance(1)
                if progress is not None and (k % PROGRESS_EVERY_STEPS == 0 or k == steps):
                    progress(k * dt_ns * 1e-9, steps * dt_ns * 1e-9)
        finally:
            engine.close()
    return Resimulation(compared=compared, max_difference=differences,
                        recorded_version=metadata.version, commands=len(commands),
                        ensemble_compared=ensemble_compared,
                        ensemble_max_difference=ensemble_differences if ensemble_compared
                        else None, assimilated=metadata.assimilation)
