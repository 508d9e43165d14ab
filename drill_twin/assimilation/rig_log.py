"""
A rig's log as arrays: sensor samples, commands, and (from the emulator) the truth.

The rig emulator produces it, the MCAP layer writes and reads it, the offline filter
consumes it. Times in seconds of model time from the start of the log.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass(frozen=True)
class SensorSamples:
    """
    One sensor's samples.

    stamp_s (k,) when sampled, arrival_s (k,) when received, values {channel: (k,)} in SI.
    """

    stamp_s: np.ndarray
    arrival_s: np.ndarray
    values: dict[str, np.ndarray]


@dataclass(frozen=True)
class Truth:
    """
    The true downhole state at time_s (k,).

    Bit speed (rad/s), bit angle (rad), ROP (m/s), TOB and WOB (N m, N; > 0 cutting /
    compressed), bit and hole depth (m).
    """

    time_s: np.ndarray
    bit_speed_rad_per_s: np.ndarray
    bit_angle_rad: np.ndarray
    rop_m_per_s: np.ndarray
    torque_on_bit_nm: np.ndarray
    weight_on_bit_n: np.ndarray
    bit_depth_m: np.ndarray
    hole_depth_m: np.ndarray


@dataclass(frozen=True)
class RigLog:
    """
    A rig log: its length, sensor samples, commands, truth and metadata.

    duration_s: the log's length (s); sensors: {name: SensorSamples} of the sensors'
    JointStates; scalars: {channel: SensorSamples} of the channels that came as
    std_msgs/Float64 on topics of their own (``channels.<c>.topic``; values {channel: (k,)});
    speed_commands and hook_commands: (c, 2) rows (time s, value: rad/s or N), in time order,
    the first at 0; truth: or None; metadata: strings about the run (the truth's
    configuration...).
    """

    duration_s: float
    sensors: dict[str, SensorSamples]
    speed_commands: np.ndarray
    hook_commands: np.ndarray
    truth: Truth | None = None
    metadata: dict[str, str] = field(default_factory=dict)
    scalars: dict[str, SensorSamples] = field(default_factory=dict)


def command_at(commands: np.ndarray, time_s: float) -> float:
    """Return the command in force at ``time_s``: the last with a time <= time_s (+ 1 ns)."""
    index = np.searchsorted(commands[:, 0], time_s + 1e-9, side='right') - 1
    return float(commands[max(index, 0), 1])
