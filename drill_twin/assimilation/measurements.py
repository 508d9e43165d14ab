"""
What a rig measures, read off the model's :class:`Observation`, and how a sensor samples it.

Channels (SI, the sign a driller reads):

- top_speed (rad/s): the top drive's speed; top_torque (N m, > 0 driving): the torque the top
  drive applies to the string;
- hook_load (N): the hook load; block_position (m, down): the travelling block's
  displacement from the prestressed state (the top's axial displacement);
- bit_speed (rad/s), torque_on_bit (N m, > 0 while cutting: minus the model's t_bit),
  weight_on_bit (N, > 0 in compression: minus the model's f_bit): downhole, as mud-pulse
  telemetry sends them.

A sensor samples its channels at ``rate_hz`` (stamps k / rate_hz) and each sample arrives
``delay_s`` later; a reading is the value plus the bias plus Gaussian noise of standard
deviation hypot(noise_std, noise_relative |value|).
"""
from __future__ import annotations

import math

import numpy as np

from drill_twin.assimilation.settings import SENSOR_OF, AssimilationConfig
from drill_twin.integrator.simulator import Observation

CHANNELS = tuple(SENSOR_OF)
SENSORS = ('top_drive', 'hook', 'downhole')
SENSOR_CHANNELS = {sensor: tuple(c for c in CHANNELS if SENSOR_OF[c] == sensor)
                   for sensor in SENSORS}
"""The channels of each sensor, in message order."""
MEMBER_DEPENDENT = ('top_torque', 'block_position', 'bit_speed', 'torque_on_bit',
                    'weight_on_bit')
"""Channels that differ between members (top_speed and hook_load are the commands' in force
with the top drive and hook of the model: the same for all members)."""


MOTION_OF = {'top_speed': 'torsional', 'top_torque': 'torsional', 'bit_speed': 'torsional',
             'torque_on_bit': 'torsional', 'hook_load': 'axial', 'block_position': 'axial',
             'weight_on_bit': 'axial'}
"""The motion each channel measures, for localisation by motion (``localisation: motion``):
its samples analyse that motion's block of the state only."""


def channel_values(observation: Observation, channel: str, members: int) -> np.ndarray:
    """
    Return the channel's true value for the first ``members`` members, shape (members,).

    The observation must have the top quantities (``detailed``) for those members.
    """
    o = observation
    if channel == 'top_speed':
        return np.full(members, float(o.top_speed_rad_per_s))
    if channel == 'hook_load':
        return np.full(members, float(o.hook_load_n))
    value = {'top_torque': lambda: o.top_torque_nm,
             'block_position': lambda: o.hook_position_m,
             'bit_speed': lambda: o.speed_rad_per_s,
             'torque_on_bit': lambda: -o.torque_on_bit_nm,
             'weight_on_bit': lambda: -o.weight_on_bit_n}[channel]()
    return np.asarray(value[:members], dtype=float)


def sample_times(rate_hz: float, duration_s: float) -> np.ndarray:
    """Stamps k / rate_hz in (0, duration_s] (s)."""
    count = int(np.floor(duration_s * rate_hz + 1e-9))
    return np.arange(1, count + 1) / rate_hz


def read(settings: AssimilationConfig, channel: str, value, rng: np.random.Generator):
    """
    Return a noisy, biased reading of ``value`` (any shape).

    The noise and bias are as ``settings`` describe the channel.
    """
    spec = settings.channel(channel)
    value = np.asarray(value, dtype=float)
    return value + spec.bias + spec.std(value) * rng.standard_normal(value.shape)


SENSOR_JOINTS = {
    'top_drive': (('top_drive', {'velocity': 'top_speed', 'effort': 'top_torque'}),),
    'hook': (('hook', {'position': 'block_position', 'effort': 'hook_load'}),),
    'downhole': (('bit_rotation', {'velocity': 'bit_speed', 'effort': 'torque_on_bit'}),
                 ('bit_axial', {'effort': 'weight_on_bit'})),
}
"""
A sensor's sensor_msgs/JointState layout: its joints in order, and which field of each joint
carries which channel (a field no channel uses is NaN). The rig emulator writes it, the log
reader and the twin's subscriptions read it.
"""
JOINT_FIELDS = ('position', 'velocity', 'effort')


def joint_state_fields(sensor: str, values: dict) -> tuple[list, list, list, list]:
    """
    (names, position, velocity, effort) of a sensor's JointState for channel ``values``.

    A field that carries no channel, or a channel missing from ``values``, is NaN (a field is
    left empty when no joint of the sensor uses it).
    """
    joints = SENSOR_JOINTS[sensor]
    names = [name for name, _ in joints]
    columns = []
    for field in JOINT_FIELDS:
        if not any(field in carried for _, carried in joints):
            columns.append([])
            continue
        columns.append([float(values.get(carried[field], math.nan)) if field in carried
                        else math.nan for _, carried in joints])
    return (names, *columns)


def values_from_joint_state(sensor: str, names, position, velocity, effort) -> dict:
    """
    {channel: value} a sensor's JointState carries (the channels it has; NaN ones included).

    ``names``: the joints' names, or None to take the joints in the layout's order (a reader
    that skips the names). Raises ValueError naming what is missing.
    """
    joints = SENSOR_JOINTS[sensor]
    fields = dict(zip(JOINT_FIELDS, (position, velocity, effort)))
    values = {}
    for order, (joint, carried) in enumerate(joints):
        if names is None:
            index = order
        elif joint in names:
            index = list(names).index(joint)
        else:
            continue
        for field, channel in carried.items():
            if index < len(fields[field]):
                values[channel] = float(fields[field][index])
    if not values:
        expected = '; '.join(f"joint '{joint}' " + ', '.join(carried)
                             for joint, carried in joints)
        raise ValueError(f'a {sensor} message carries none of its measurements (expected '
                         f'{expected})')
    return values
