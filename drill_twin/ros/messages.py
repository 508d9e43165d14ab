"""
Twin snapshots as standard ROS messages (units and conventions: drill_twin.interface).

:func:`tick_messages` gives everything one tick publishes; the node only sends them.
``TFMessage`` is None where tf2_msgs is not installed (the PyPI ROS wheels lack it; every ROS
installation has it): the twin then publishes no TF.
"""
from __future__ import annotations

from dataclasses import dataclass
import importlib
import math

from builtin_interfaces.msg import Time
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus, KeyValue
from geometry_msgs.msg import Transform, TransformStamped, Vector3Stamped, WrenchStamped
from rcl_interfaces.msg import Log
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import Imu, JointState
from std_msgs.msg import (Float64, Float64MultiArray, Header, MultiArrayDimension,
                          MultiArrayLayout, String)

from drill_twin import interface as itf
from drill_twin.twin.engine import BitState, TwinEvent, TwinSnapshot
from drill_twin.twin.health import HealthReport

try:
    TFMessage = importlib.import_module('tf2_msgs.msg').TFMessage
except ImportError:
    TFMessage = None

LEVELS = {'info': DiagnosticStatus.OK, 'ok': DiagnosticStatus.OK,
          'warn': DiagnosticStatus.WARN, 'error': DiagnosticStatus.ERROR}
LOG_LEVELS = {'info': Log.INFO, 'warn': Log.WARN, 'error': Log.ERROR}


def stamp(time_ns: int) -> Time:
    """builtin_interfaces/Time of ``time_ns`` (ns)."""
    return Time(sec=int(time_ns // 1_000_000_000), nanosec=int(time_ns % 1_000_000_000))


def every_topic(topic: str) -> bool:
    """Want the message of every topic (the builders' default ``wanted``)."""
    return True


def header(time_ns: int, frame_id: str) -> Header:
    """std_msgs/Header stamped ``time_ns`` (ns) in ``frame_id``."""
    return Header(stamp=stamp(time_ns), frame_id=frame_id)


def bit_state(bit: BitState, time_ns: int) -> JointState:
    """bit_axial: depth, ROP, WOB; bit_rotation: angle, speed, TOB."""
    return JointState(header=header(time_ns, itf.FRAME_BIT),
                      name=[itf.BIT_AXIAL, itf.BIT_ROTATION],
                      position=[bit.depth_m, bit.angle_rad],
                      velocity=[bit.rop_m_per_s, bit.speed_rad_per_s],
                      effort=[bit.weight_on_bit_n, bit.torque_on_bit_nm])


def bit_wrench(bit: BitState, time_ns: int) -> WrenchStamped:
    """Force and torque of the rock on the bit along the string axis x (down)."""
    message = WrenchStamped(header=header(time_ns, itf.FRAME_BIT))
    message.wrench.force.x = bit.weight_on_bit_n
    message.wrench.torque.x = bit.torque_on_bit_nm
    return message


def top_state(snapshot: TwinSnapshot, time_ns: int) -> JointState:
    """top_drive: angle, speed, torque applied; hook: travel, its rate, hook load."""
    o = snapshot.observation
    return JointState(header=header(time_ns, itf.FRAME_TOP),
                      name=[itf.TOP_DRIVE, itf.HOOK],
                      position=[o.top_angle_rad, float(o.hook_position_m[0])],
                      velocity=[o.top_speed_rad_per_s, float(o.hook_velocity_m_per_s[0])],
                      effort=[float(o.top_torque_nm[0]), o.hook_load_n])


def station_messages(snapshot: TwinSnapshot, stations_m, time_ns: int, wanted=every_topic):
    """
    (topic, message) of every station (of the topics ``wanted`` keeps).

    Imu (accelerations m/s^2: axial, v, w; angular velocity rad/s: spin, theta_y', theta_z';
    orientation not provided) and the displacement (x axial, y = v, z = w, m).
    """
    o = snapshot.observation
    out = []
    for k, x_m in enumerate(stations_m):
        frame = itf.station_frame(x_m)
        topic = itf.vibration_imu_topic(x_m)
        if wanted(topic):
            imu = Imu(header=header(time_ns, frame))
            imu.orientation_covariance[0] = -1.0                  # REP 145: no orientation
            a = o.station_acceleration_m_per_s2[0, k]
            w = o.station_spin_rate_rad_per_s[0, k]
            imu.linear_acceleration.x, imu.linear_acceleration.y, imu.linear_acceleration.z = (
                float(a[0]), float(a[1]), float(a[2]))
            imu.angular_velocity.x, imu.angular_velocity.y, imu.angular_velocity.z = (
                float(w[0]), float(w[1]), float(w[2]))
            out.append((topic, imu))
        topic = itf.vibration_displacement_topic(x_m)
        if wanted(topic):
            d = o.station_displacement_m[0, k]
            displacement = Vector3Stamped(header=header(time_ns, frame))
            displacement.vector.x, displacement.vector.y, displacement.vector.z = (
                float(d[0]), float(d[1]), float(d[2]))
            out.append((topic, displacement))
    return out


def contact_forces(snapshot: TwinSnapshot) -> Float64MultiArray:
    """
    Radial wall force at every node, top to bottom (N).

    One dimension labelled :data:`~drill_twin.interface.CONTACT_FORCES_LABEL` (node depths:
    docs/ROS-INTERFACE.md).
    """
    forces = snapshot.observation.contact_force_n[0]
    message = Float64MultiArray(data=[float(f) for f in forces])
    message.layout.dim = [MultiArrayDimension(label=itf.CONTACT_FORCES_LABEL, size=forces.size,
                                              stride=forces.size)]
    message.layout.data_offset = 0
    return message


def transform(parent: str, child: str, x_m: float, time_ns: int,
              rotation=(0.0, 0.0, 0.0, 1.0)) -> TransformStamped:
    """
    Place ``child`` at ``x_m`` along ``parent``'s x axis.

    Turned by the quaternion ``rotation`` (x, y, z, w).
    """
    message = TransformStamped(header=header(time_ns, parent), child_frame_id=child,
                               transform=Transform())
    message.transform.translation.x = float(x_m)
    q = message.transform.rotation
    q.x, q.y, q.z, q.w = (float(c) for c in rotation)
    return message


def static_transforms(stations_m, time_ns: int) -> list[TransformStamped]:
    """
    Frames fixed for the run.

    The hole in the rig (x turned down) and each station on the string, its distance below the
    top.
    """
    return ([transform(itf.FRAME_RIG, itf.FRAME_HOLE, 0.0, time_ns, itf.HOLE_IN_RIG_QUATERNION)]
            + [transform(itf.FRAME_TOP, itf.station_frame(x_m), x_m, time_ns)
               for x_m in stations_m])


def moving_transforms(snapshot: TwinSnapshot, time_ns: int) -> list[TransformStamped]:
    """
    Frames that move with the string.

    The top at its axial displacement and the bit at its depth, along the hole frame's x (m,
    down).
    """
    top_m = float(snapshot.observation.hook_position_m[0])
    return [transform(itf.FRAME_HOLE, itf.FRAME_TOP, top_m, time_ns),
            transform(itf.FRAME_HOLE, itf.FRAME_BIT, snapshot.bit.depth_m, time_ns)]


def tf(transforms) -> 'TFMessage':
    """Wrap ``transforms`` in a tf2_msgs/TFMessage (requires tf2_msgs)."""
    if TFMessage is None:
        raise RuntimeError('tf2_msgs is not installed')
    return TFMessage(transforms=list(transforms))


def scalar(value: float) -> Float64:
    """Make a KPI message; only finite values (the node skips a KPI it cannot compute)."""
    if not math.isfinite(value):
        raise ValueError(f'a KPI must be finite, got {value}')
    return Float64(data=float(value))


@dataclass(frozen=True, slots=True)
class TickPlan:
    """
    What a tick publishes besides its every-tick messages.

    kpis: the KPIs and hole depth are due; ensemble_stamp_ns: stamp (ns) of the ensemble's
    mean and bounds if they are due (their own time, a tick behind), else None; clock: /clock
    (fast mode); tf: the moving TF frames are due (tf2_msgs installed).
    """

    kpis: bool = False
    ensemble_stamp_ns: int | None = None
    clock: bool = False
    tf: bool = False


def every_tick_topic(topic: str) -> bool:
    """
    Tell whether ``topic`` is one of the states every tick publishes.

    Those of :func:`state_messages`, the surface readings and the moving TF frames: the log
    thins them to the node's ``log_state_rate_hz``.
    """
    return (topic in (itf.BIT_STATE, itf.BIT_WRENCH, itf.TOP_STATE, itf.CONTACT_FORCES, itf.TF)
            or topic in itf.SURFACE_TOPICS or topic.startswith(VIBRATION_PREFIX))


VIBRATION_PREFIX = '/drill_twin/vibration/'
"""The stations' topics (interface.vibration_*_topic) start with it."""


def logged(topic: str, states_due: bool) -> bool:
    """
    Tell whether a tick's message on ``topic`` goes to the log.

    Everything but /clock (the log time is the twin's clock; a bag player makes /clock from
    it) and, when ``states_due`` is false, the every-tick states.
    """
    return topic != itf.CLOCK and (states_due or not every_tick_topic(topic))


def state_messages(snapshot: TwinSnapshot, stations_m, time_ns: int, wanted=every_topic):
    """
    (topic, message) of every tick.

    The bit state and wrench, the top, the wall contacts, the stations; only those of the
    topics ``wanted`` (topic -> bool) keeps: the others are not built.
    """
    states = ((itf.BIT_STATE, lambda: bit_state(snapshot.bit, time_ns)),
              (itf.BIT_WRENCH, lambda: bit_wrench(snapshot.bit, time_ns)),
              (itf.TOP_STATE, lambda: top_state(snapshot, time_ns)),
              (itf.CONTACT_FORCES, lambda: contact_forces(snapshot)))
    return ([(topic, build()) for topic, build in states if wanted(topic)]
            + station_messages(snapshot, stations_m, time_ns, wanted))


def tick_messages(snapshot: TwinSnapshot, stations_m, time_ns: int, plan: TickPlan,
                  wanted=every_topic):
    """
    (topic, message) of everything a tick publishes, in order.

    The states and surface readings, then what ``plan`` says is due (KPIs and the driller's
    view, ensemble, TF), the events, /clock; of these, the topics ``wanted`` (topic -> bool)
    keeps (the every-tick states of the others are not even built).
    """
    out = (state_messages(snapshot, stations_m, time_ns, wanted)
           + surface_messages(snapshot, wanted))
    due = []
    if plan.kpis:
        due += kpi_messages(snapshot) + driller_messages(snapshot)
    if plan.ensemble_stamp_ns is not None and snapshot.ensemble_mean is not None:
        due += ensemble_messages(snapshot, plan.ensemble_stamp_ns)
    if plan.tf:
        due.append((itf.TF, tf(moving_transforms(snapshot, time_ns))))
    if snapshot.events:
        due.append((itf.DIAGNOSTICS, events(snapshot.events, time_ns)))
    if plan.clock:
        due.append((itf.CLOCK, clock(time_ns)))
    return out + [(topic, message) for topic, message in due if wanted(topic)]


def kpi_messages(snapshot: TwinSnapshot):
    """(topic, message) of the KPIs that could be computed (a None KPI is not published)."""
    kpis = ((itf.KPI_STICK_SLIP, snapshot.stick_slip_severity), (itf.KPI_MSE, snapshot.mse_pa),
            (itf.KPI_ROP, snapshot.rop_m_per_h),
            (itf.HOLE_DEPTH, float(snapshot.observation.hole_depth_m[0])))
    return [(topic, scalar(value)) for topic, value in kpis if value is not None]


def surface_values(snapshot: TwinSnapshot) -> dict:
    """Return {surface topic: value (SI)} of the snapshot's surface readings."""
    s = snapshot.surface
    return {itf.SURFACE_SPEED: s.speed_rad_per_s, itf.SURFACE_TORQUE: s.torque_nm,
            itf.SURFACE_HOOK_LOAD: s.hook_load_n, itf.SURFACE_BLOCK_POSITION: s.block_position_m,
            itf.SURFACE_BIT_DEPTH: s.bit_depth_m, itf.SURFACE_HOLE_DEPTH: s.hole_depth_m,
            itf.SURFACE_ROP: s.rop_m_per_s, itf.SURFACE_WOB: s.weight_on_bit_n}


def surface_messages(snapshot: TwinSnapshot, wanted=every_topic):
    """(topic, Float64) of the surface readings in SI (none without readings; of ``wanted``)."""
    if snapshot.surface is None:
        return []
    return [(topic, Float64(data=value)) for topic, value in surface_values(snapshot).items()
            if wanted(topic)]


DRILLER_SCALE = {'rpm': 60.0 / (2.0 * math.pi), 'kN m': 1e-3, 'kN': 1e-3,
                 'klbf': 1.0 / itf.NEWTON_PER_KLBF, 'm/h': 3600.0, 'm': 1.0}
"""Drilling unit -> its value per SI unit (rad/s, N m, N, m/s, m)."""


def driller_messages(snapshot: TwinSnapshot):
    """(topic, Float64) of the driller's view: the readings in drilling units, WITS names."""
    if snapshot.surface is None:
        return []
    si = surface_values(snapshot)
    return [(itf.driller_topic(name), Float64(data=DRILLER_SCALE[unit] * si[source]))
            for name, (unit, source) in itf.DRILLER_TOPICS.items()]


def command_message(command_topic: str, value):
    """Return the command as its subscription receives it: String for a mode, else Float64."""
    if command_topic in itf.MODE_COMMANDS:
        return String(data=str(value))
    return Float64(data=float(value))


def command_applied(command_topic: str, value, time_ns: int) -> JointState:
    """
    Echo a command as applied (:func:`drill_twin.interface.cmd_applied_topic`).

    Stamped ``time_ns``, the twin time of the first step that used it. A Float64 command:
    name = [its short name], position = [the value]; a mode: name = ['<short name>=<mode>'],
    position = [the mode's index in :data:`drill_twin.interface.MODE_COMMANDS`]. velocity and
    effort are [0.0], unused (empty arrays after a non-empty one are padded by Fast-CDR in a
    way the rosbags reader refuses; NaN would not compare equal to itself).
    """
    name = itf.COMMANDS[command_topic]
    message = JointState(header=header(time_ns, ''), velocity=[0.0], effort=[0.0])
    if command_topic in itf.MODE_COMMANDS:
        message.name = [f'{name}={value}']
        message.position = [float(itf.MODE_COMMANDS[command_topic].index(value))]
    else:
        message.name = [name]
        message.position = [float(value)]
    return message


def ensemble_messages(snapshot: TwinSnapshot, time_ns: int):
    """(topic, message) of the ensemble's mean and bounds, stamped with its own time."""
    return [(topic, bit_state(state, time_ns))
            for topic, state in ((itf.ENSEMBLE_MEAN, snapshot.ensemble_mean),
                                 (itf.ENSEMBLE_LOWER, snapshot.ensemble_lower),
                                 (itf.ENSEMBLE_UPPER, snapshot.ensemble_upper))]


def _labelled_array(label: str, values) -> Float64MultiArray:
    """std_msgs/Float64MultiArray of ``values`` with one dimension labelled ``label``."""
    data = [float(v) for v in values]
    return Float64MultiArray(
        layout=MultiArrayLayout(dim=[MultiArrayDimension(label=label, size=len(data),
                                                         stride=len(data))]),
        data=data)


def germ_messages(record):
    """
    Return (topic, message) of an analysis's estimated germ.

    [G11, G12, G22] of the analysed members' mean, 2.5 % and 97.5 %
    (std_msgs/Float64MultiArray, one dimension labelled 'G11,G12,G22').
    """
    return [(topic, _labelled_array('G11,G12,G22', values)) for topic, values in (
        (itf.ASSIMILATION_GERM_MEAN, record.germ_mean),
        (itf.ASSIMILATION_GERM_LOWER, record.germ_lower),
        (itf.ASSIMILATION_GERM_UPPER, record.germ_upper))]


def law_messages(record):
    """
    Return (topic, message) of an analysis's estimated factors of the law's a1 ... a5.

    The analysed members' mean, 2.5 % and 97.5 % (std_msgs/Float64MultiArray, one dimension
    labelled 'a1,a2,a3,a4,a5'; 1 is the configured law); none when the filter does not
    estimate the law (parameters other than 'law').
    """
    if not all(math.isfinite(v) for v in record.law_mean):
        return []
    return [(topic, _labelled_array('a1,a2,a3,a4,a5', values)) for topic, values in (
        (itf.ASSIMILATION_LAW_MEAN, record.law_mean),
        (itf.ASSIMILATION_LAW_LOWER, record.law_lower),
        (itf.ASSIMILATION_LAW_UPPER, record.law_upper))]


def bias_messages(record):
    """
    Return (topic, message) of an analysis's estimated sensor biases.

    The analysed members' mean, 2.5 % and 97.5 % (std_msgs/Float64MultiArray, SI, one
    dimension labelled with the channels, e.g. 'top_torque'); none when no bias is estimated.
    """
    if not record.bias_channels:
        return []
    label = ','.join(record.bias_channels)
    return [(topic, _labelled_array(label, values)) for topic, values in (
        (itf.ASSIMILATION_BIAS_MEAN, record.bias_mean),
        (itf.ASSIMILATION_BIAS_LOWER, record.bias_lower),
        (itf.ASSIMILATION_BIAS_UPPER, record.bias_upper))]


def analysis_messages(record):
    """Return (topic, message) of an analysis's estimates: the germ, the law, the biases."""
    return germ_messages(record) + law_messages(record) + bias_messages(record)


def clock(time_ns: int) -> Clock:
    """rosgraph_msgs/Clock at ``time_ns`` (ns)."""
    return Clock(clock=stamp(time_ns))


def _status(level: str, name: str, message: str, values: dict) -> DiagnosticStatus:
    return DiagnosticStatus(level=LEVELS[level], name=f'drill_twin: {name}', message=message,
                            hardware_id='drill_twin',
                            values=[KeyValue(key=str(k), value=str(v)) for k, v in values.items()])


def events(events: tuple[TwinEvent, ...], time_ns: int) -> DiagnosticArray:
    """One status per event (impacts, lift-off, resets, rejected commands)."""
    return DiagnosticArray(header=header(time_ns, ''), status=[
        _status(e.level, e.kind.replace('_', ' '), e.message,
                {'sim_time_s': f'{e.time_s:.6f}', **e.values}) for e in events])


def health_report(report: HealthReport, time_ns: int) -> DiagnosticArray:
    """
    Return the health report as ``drill_twin: twin health``.

    Level and message of the report, its figures, and every reason as ``reason_1``,
    ``reason_2``, ... (so that no reason is only on /rosout).
    """
    values = dict(report.values)
    values.update({f'reason_{k}': text for k, text in enumerate(report.reasons, start=1)})
    return DiagnosticArray(header=header(time_ns, ''),
                           status=[_status(report.level, 'twin health', report.message, values)])


def log(level: str, text: str, name: str, time_ns: int) -> Log:
    """Make a /rosout record of the twin's own log line (for the MCAP log)."""
    return Log(stamp=stamp(time_ns), level=LOG_LEVELS[level], name=name, msg=text,
               file='', function='', line=0)


def publications(stations_m, *, ensemble: bool, clock: bool, tf: bool,
                 assimilation: bool = False) -> dict:
    """
    Map every topic the twin publishes (but /rosout) to its (message class, QosSpec).

    The ensemble topics with an ensemble, the estimated germ with assimilation, /clock in fast
    mode, /tf and /tf_static where tf2_msgs is installed.
    """
    state = itf.STATE_QOS
    topics = {itf.BIT_STATE: (JointState, state), itf.BIT_WRENCH: (WrenchStamped, state),
              itf.TOP_STATE: (JointState, state),
              itf.CONTACT_FORCES: (Float64MultiArray, state),
              itf.KPI_STICK_SLIP: (Float64, state), itf.KPI_MSE: (Float64, state),
              itf.KPI_ROP: (Float64, state), itf.HOLE_DEPTH: (Float64, state),
              itf.DIAGNOSTICS: (DiagnosticArray, itf.DIAGNOSTICS_QOS)}
    topics.update({topic: (Float64, state) for topic in itf.SURFACE_TOPICS})
    topics.update({itf.driller_topic(name): (Float64, state) for name in itf.DRILLER_TOPICS})
    topics.update({itf.cmd_applied_topic(command): (JointState, state)
                   for command in itf.COMMANDS})
    if ensemble:
        for topic in (itf.ENSEMBLE_MEAN, itf.ENSEMBLE_LOWER, itf.ENSEMBLE_UPPER):
            topics[topic] = (JointState, state)
    if assimilation:
        for topic in (itf.ASSIMILATION_GERM_MEAN, itf.ASSIMILATION_GERM_LOWER,
                      itf.ASSIMILATION_GERM_UPPER, itf.ASSIMILATION_LAW_MEAN,
                      itf.ASSIMILATION_LAW_LOWER, itf.ASSIMILATION_LAW_UPPER,
                      itf.ASSIMILATION_BIAS_MEAN, itf.ASSIMILATION_BIAS_LOWER,
                      itf.ASSIMILATION_BIAS_UPPER):
            topics[topic] = (Float64MultiArray, state)
    for x_m in stations_m:
        topics[itf.vibration_imu_topic(x_m)] = (Imu, state)
        topics[itf.vibration_displacement_topic(x_m)] = (Vector3Stamped, state)
    if clock:
        topics[itf.CLOCK] = (Clock, itf.CLOCK_QOS)
    if tf:
        topics[itf.TF] = (TFMessage, itf.TF_QOS)
        topics[itf.TF_STATIC] = (TFMessage, itf.TF_STATIC_QOS)
    return topics
