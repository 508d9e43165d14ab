"""A synthetic log of every twin topic, for tests, demos and trying the viewer.

The numbers look like a drill string in stick-slip (bit speed oscillating between 0 and about
twice the top-drive speed, WOB and TOB negative while drilling) but come from closed-form
signals, not from the physics core.  Header stamps and log times are the same simulated
time: ``start_ns`` plus the elapsed time (ns).
"""
from __future__ import annotations

import math
import os
from typing import Any, Iterable, Iterator, NamedTuple

from drill_twin import interface as itf
from drill_twin.recording.log_metadata import RECORD_NAME
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.message_types import import_message_class
from drill_twin.recording.topics import BIT_JOINTS, TOP_JOINTS, twin_topics

DEFAULT_START_NS = 1_700_000_000_000_000_000
"""2023-11-14T22:13:20Z, an arbitrary epoch for synthetic logs."""
DEFAULT_STATIONS_M = (500.0, 1000.0)
N_CONTACTS = 4


class TimedMessage(NamedTuple):
    """A message to write: topic, message, log time (ns)."""

    topic: str
    message: Any
    log_time_ns: int


def _stamp(message: Any, t_ns: int, frame_id: str) -> None:
    message.header.stamp.sec = t_ns // 1_000_000_000
    message.header.stamp.nanosec = t_ns % 1_000_000_000
    message.header.frame_id = frame_id


def _joint_state(t_ns: int, frame_id: str, names, position, velocity, effort) -> Any:
    message = import_message_class('sensor_msgs/msg/JointState')()
    _stamp(message, t_ns, frame_id)
    message.name = list(names)
    message.position = [float(v) for v in position]
    message.velocity = [float(v) for v in velocity]
    message.effort = [float(v) for v in effort]
    return message


def _float64(value: float) -> Any:
    return import_message_class('std_msgs/msg/Float64')(data=float(value))


def synthetic_messages(duration_s: float = 10.0, rate_hz: float = 100.0,
                       stations_m: Iterable[float] = DEFAULT_STATIONS_M,
                       start_ns: int = DEFAULT_START_NS) -> Iterator[TimedMessage]:
    """Yield messages of every twin topic in time order.

    State topics come at ``rate_hz``, diagnostics and commands at 1 Hz, a /rosout line
    every 2 s.
    """
    stations = [float(x) for x in stations_m]
    n_steps = int(round(duration_s * rate_hz))
    period_ns = int(round(1e9 / rate_hz))
    every_second = max(1, int(round(rate_hz)))
    top_speed = 10.0            # rad/s
    hook_load = 1.2e6           # N
    depth0 = 1500.0             # m
    clock_cls = import_message_class('rosgraph_msgs/msg/Clock')
    wrench_cls = import_message_class('geometry_msgs/msg/WrenchStamped')
    imu_cls = import_message_class('sensor_msgs/msg/Imu')
    vector_cls = import_message_class('geometry_msgs/msg/Vector3Stamped')
    array_cls = import_message_class('std_msgs/msg/Float64MultiArray')
    dimension_cls = import_message_class('std_msgs/msg/MultiArrayDimension')
    diag_array_cls = import_message_class('diagnostic_msgs/msg/DiagnosticArray')
    diag_status_cls = import_message_class('diagnostic_msgs/msg/DiagnosticStatus')
    key_value_cls = import_message_class('diagnostic_msgs/msg/KeyValue')
    log_cls = import_message_class('rcl_interfaces/msg/Log')
    angle = 0.0
    depth = depth0
    for step in range(n_steps):
        t = step / rate_hz
        t_ns = start_ns + step * period_ns
        phase = 2.0 * math.pi * 0.25 * t                       # stick-slip at 0.25 Hz
        bit_speed = max(0.0, top_speed * (1.0 + 1.1 * math.sin(phase)))
        rop = 0.004 + 0.002 * math.sin(0.5 * phase)             # m/s
        wob = -1.0e5 * (1.0 + 0.1 * math.sin(3.0 * phase))      # N
        tob = -6.0e3 * (0.8 + 0.4 * math.cos(phase))            # N m
        angle += bit_speed / rate_hz
        depth += rop / rate_hz
        if step % every_second == 0:
            yield TimedMessage(itf.CMD_TOP_DRIVE_SPEED, _float64(top_speed), t_ns)
            yield TimedMessage(itf.CMD_HOOK_LOAD, _float64(hook_load), t_ns)
        clock = clock_cls()
        clock.clock.sec, clock.clock.nanosec = t_ns // 1_000_000_000, t_ns % 1_000_000_000
        yield TimedMessage(itf.CLOCK, clock, t_ns)
        yield TimedMessage(itf.BIT_STATE, _joint_state(
            t_ns, itf.FRAME_BIT, BIT_JOINTS, (depth, angle), (rop, bit_speed), (wob, tob)),
            t_ns)
        wrench = wrench_cls()
        _stamp(wrench, t_ns, itf.FRAME_BIT)
        wrench.wrench.force.x, wrench.wrench.torque.x = wob, tob
        yield TimedMessage(itf.BIT_WRENCH, wrench, t_ns)
        top_torque = -tob + 2.0e3 * math.sin(phase + 0.5)
        yield TimedMessage(itf.TOP_STATE, _joint_state(
            t_ns, itf.FRAME_TOP, TOP_JOINTS,
            (top_speed * t, depth - depth0), (top_speed, rop),
            (top_torque, hook_load + wob)), t_ns)
        contacts = array_cls()
        contacts.layout.dim = [dimension_cls(label='contact', size=N_CONTACTS,
                                             stride=N_CONTACTS)]
        contacts.data = [max(0.0, 5e3 * math.sin(phase * (k + 1) + k)) for k in
                         range(N_CONTACTS)]
        yield TimedMessage(itf.CONTACT_FORCES, contacts, t_ns)
        severity = 1.1 * (1.0 + 0.05 * math.sin(0.1 * phase))
        yield TimedMessage(itf.KPI_STICK_SLIP, _float64(severity), t_ns)
        yield TimedMessage(itf.KPI_MSE, _float64(abs(wob) / 0.05 + 2.0 * math.pi * abs(tob)
                                                 * bit_speed / (0.05 * max(rop, 1e-4))), t_ns)
        yield TimedMessage(itf.KPI_ROP, _float64(rop * 3600.0), t_ns)
        yield TimedMessage(itf.HOLE_DEPTH, _float64(depth), t_ns)
        spread = (0.05 * abs(wob), 0.3 * top_speed, 0.2 * rop)
        for topic, sign in ((itf.ENSEMBLE_MEAN, 0.0), (itf.ENSEMBLE_LOWER, -1.96),
                            (itf.ENSEMBLE_UPPER, 1.96)):
            yield TimedMessage(topic, _joint_state(
                t_ns, itf.FRAME_BIT, BIT_JOINTS, (depth, angle),
                (rop + sign * spread[2], bit_speed + sign * spread[1]),
                (wob + sign * spread[0], tob)), t_ns)
        for x_m in stations:
            frame = itf.station_frame(x_m)
            scale = x_m / 1000.0
            imu = imu_cls()
            _stamp(imu, t_ns, frame)
            imu.orientation_covariance[0] = -1.0          # orientation not provided
            imu.linear_acceleration.x = 0.5 * scale * math.sin(7.0 * phase)
            imu.linear_acceleration.y = 2.0 * scale * math.sin(3.0 * phase + x_m)
            imu.linear_acceleration.z = 2.0 * scale * math.cos(3.0 * phase + x_m)
            imu.angular_velocity.x = bit_speed * (1.0 - 0.3 * scale)
            yield TimedMessage(itf.vibration_imu_topic(x_m), imu, t_ns)
            displacement = vector_cls()
            _stamp(displacement, t_ns, frame)
            displacement.vector.x = 1e-4 * math.sin(7.0 * phase)
            displacement.vector.y = 0.02 * scale * math.sin(3.0 * phase + x_m)
            displacement.vector.z = 0.02 * scale * math.cos(3.0 * phase + x_m)
            yield TimedMessage(itf.vibration_displacement_topic(x_m), displacement, t_ns)
        if step % every_second == 0:
            diagnostics = diag_array_cls()
            _stamp(diagnostics, t_ns, '')
            status = diag_status_cls(level=diag_status_cls.OK, name='drill_twin: solver',
                                     message='ok', hardware_id='drill_twin')
            status.values = [key_value_cls(key='step', value=str(step)),
                             key_value_cls(key='real_time_factor', value='1.00')]
            diagnostics.status = [status]
            yield TimedMessage(itf.DIAGNOSTICS, diagnostics, t_ns)
        if step % (2 * every_second) == 0:
            log = log_cls(level=log_cls.INFO, name=itf.NODE_NAME,
                          msg=f'synthetic step {step}: bit speed {bit_speed:.2f} rad/s',
                          file='synthetic.py', function='synthetic_messages', line=step)
            log.stamp.sec, log.stamp.nanosec = t_ns // 1_000_000_000, t_ns % 1_000_000_000
            yield TimedMessage(itf.ROSOUT, log, t_ns)


def write_synthetic_log(path: str | os.PathLike, duration_s: float = 10.0,
                        rate_hz: float = 100.0,
                        stations_m: Iterable[float] = DEFAULT_STATIONS_M,
                        start_ns: int = DEFAULT_START_NS) -> dict[str, int]:
    """Write :func:`synthetic_messages` to an MCAP log; returns messages per topic."""
    stations = [float(x) for x in stations_m]
    with McapLog(path) as log:
        for topic, spec in twin_topics(stations).items():
            log.add_topic(topic, spec.type_name, spec.qos)
        log.add_metadata(RECORD_NAME, {'config': 'synthetic: true\n', 'seed': '0',
                                       'stations_m': ','.join(f'{x:g}' for x in stations)})
        for item in synthetic_messages(duration_s, rate_hz, stations, start_ns):
            log.write(item.topic, item.message, item.log_time_ns)
        return log.message_counts
