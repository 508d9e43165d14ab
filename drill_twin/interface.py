"""
The twin's ROS interface: topic names, message types, joint names and QoS.

This module imports nothing from ROS so that the recorder, the viewer, the tests and the
documentation share one definition with the node.

Sign conventions at the boundary (SI units):
- depth / axial positions are positive downwards (m), ROP > 0 while drilling (m/s);
- weight on bit (WOB) and torque on bit (TOB) follow the paper: the force and torque the rock
  applies to the bit, negative while drilling (compression, resisting torque) (N, N m);
- top-drive speed and bit speed are positive in the drilling direction (rad/s);
- hook load is the force the hook holds the string up with, positive (N).
"""
from __future__ import annotations

from dataclasses import dataclass
import re

NODE_NAME = 'drill_twin'
NAMESPACE_PREFIX = '/drill_twin'

# Commands (subscriptions)
CMD_TOP_DRIVE_SPEED = '/drill_twin/cmd/top_drive_speed'      # std_msgs/msg/Float64, rad/s
CMD_HOOK_LOAD = '/drill_twin/cmd/hook_load'                  # std_msgs/msg/Float64, N

# Publications
BIT_STATE = '/drill_twin/bit/state'                          # sensor_msgs/msg/JointState
BIT_WRENCH = '/drill_twin/bit/wrench'                        # geometry_msgs/msg/WrenchStamped
TOP_STATE = '/drill_twin/top/state'                          # sensor_msgs/msg/JointState
CONTACT_FORCES = '/drill_twin/contact/forces'                # std_msgs/msg/Float64MultiArray
KPI_STICK_SLIP = '/drill_twin/kpi/stick_slip_severity'       # std_msgs/msg/Float64, -
KPI_MSE = '/drill_twin/kpi/mechanical_specific_energy'       # std_msgs/msg/Float64, Pa
KPI_ROP = '/drill_twin/kpi/rop_m_per_h'                      # std_msgs/msg/Float64, m/h
HOLE_DEPTH = '/drill_twin/hole/depth'                        # std_msgs/msg/Float64, m
"""The hole's depth (m), where the bit has drilled to: the bit's depth (the bit state's
bit_axial position) is smaller while the bit is lifted off bottom."""
ENSEMBLE_MEAN = '/drill_twin/ensemble/bit_state/mean'        # sensor_msgs/msg/JointState
ENSEMBLE_LOWER = '/drill_twin/ensemble/bit_state/lower'      # 2.5 % quantile, JointState
ENSEMBLE_UPPER = '/drill_twin/ensemble/bit_state/upper'      # 97.5 % quantile, JointState
DIAGNOSTICS = '/diagnostics'                                 # diagnostic_msgs/msg/DiagnosticArray
CLOCK = '/clock'                                             # rosgraph_msgs/msg/Clock
TF = '/tf'                                                   # tf2_msgs/msg/TFMessage
TF_STATIC = '/tf_static'                                     # tf2_msgs/msg/TFMessage
ROSOUT = '/rosout'                                           # rcl_interfaces/msg/Log

# Joints of the JointState messages
BIT_AXIAL = 'bit_axial'        # position = depth (m), velocity = ROP (m/s), effort = WOB (N)
BIT_ROTATION = 'bit_rotation'  # position = angle (rad), velocity = speed (rad/s), effort = TOB
TOP_DRIVE = 'top_drive'        # position = angle (rad), velocity = speed, effort = torque (N m)
HOOK = 'hook'                  # position = block travel (m), velocity (m/s), effort = load (N)

# TF frames (REP-103/105; docs/ROS-INTERFACE.md, "Frames"). The rig frame is a world frame
# (x east, y north, z up) at the top's initial position; the hole frame has the same origin and
# x down along the hole (the paper's x: depth), y = the rig's y, z = the rig's x (the paper's
# lateral v and w). The top moves with the top's axial displacement and the bit with its depth
# (both along the hole frame's x); the stations sit on the string at their distance below the
# top. Frames have the hole frame's orientation (spin angles are in the joint states).
FRAME_RIG = 'drill_twin/rig'
FRAME_HOLE = 'drill_twin/hole'
FRAME_BIT = 'drill_twin/bit'
FRAME_TOP = 'drill_twin/top'
HOLE_IN_RIG_QUATERNION = (0.0, 0.5 ** 0.5, 0.0, 0.5 ** 0.5)
"""(x, y, z, w) of the hole frame in the rig frame: +90 degrees about y, x turned down."""


def station_name(x_m: float) -> str:
    """Topic-safe name of a measurement station at depth x, e.g. 700.0 -> 'x700m'."""
    return f'x{x_m:.0f}m' if abs(x_m - round(x_m)) < 1e-9 else f'x{x_m:.2f}m'.replace('.', 'p')


def station_label(x_m: float) -> str:
    """Human label of a station for views and tables, e.g. 700.0 -> '700 m'."""
    return f'{x_m:g} m'


_STATION_DISPLACEMENT = re.compile(r'^/drill_twin/vibration/x(\d+)(?:p(\d+))?m/displacement$')


def station_from_topic(topic: str) -> float | None:
    """
    Return the depth (m) of the station whose displacement topic this is.

    The inverse of :func:`vibration_displacement_topic`; None for any other topic.
    """
    match = _STATION_DISPLACEMENT.match(topic)
    if match is None:
        return None
    whole, fraction = match.groups()
    return float(f'{whole}.{fraction}' if fraction else whole)


def vibration_imu_topic(x_m: float) -> str:
    """sensor_msgs/msg/Imu of the station at x (accelerations m/s^2, angular speed rad/s)."""
    return f'/drill_twin/vibration/{station_name(x_m)}/imu'


def vibration_displacement_topic(x_m: float) -> str:
    """geometry_msgs/msg/Vector3Stamped: x = axial, y = v, z = w displacement (m)."""
    return f'/drill_twin/vibration/{station_name(x_m)}/displacement'


def station_frame(x_m: float) -> str:
    """frame_id of the station at x."""
    return f'drill_twin/{station_name(x_m)}'


@dataclass(frozen=True)
class QosSpec:
    """A QoS profile in plain words (the node and the MCAP metadata are built from it)."""

    reliability: str = 'reliable'     # 'reliable' or 'best_effort'
    durability: str = 'volatile'      # 'volatile' or 'transient_local'
    history: str = 'keep_last'
    depth: int = 10


STATE_QOS = QosSpec()
"""Publications: reliable, volatile, keep last 10 (reaches best-effort subscribers too)."""
COMMAND_QOS = QosSpec(depth=1000)
"""The command subscriptions, chosen for a controller: reliable (a setpoint is not lost on
the way; a controller's default reliable publisher matches, a best-effort one does not),
volatile (a setpoint from before the twin started is not replayed), keep last 1000: every
command that arrives between two ticks is taken and counted (only the last of them takes
effect, the others are counted as superseded); only a burst of more than 1000 commands within
one tick overflows the queue, and those are counted as dropped from the gaps in the
publisher's sequence numbers."""
DIAGNOSTICS_QOS = QosSpec()
CLOCK_QOS = QosSpec(reliability='best_effort', depth=1)
"""/clock as the twin publishes it (fast mode) and subscribes to it (use_sim_time): best
effort, so that a subscription matches reliable and best-effort clock publishers alike."""
TF_QOS = QosSpec(depth=100)
"""/tf as tf2's broadcaster offers it: reliable, volatile, keep last 100."""
TF_STATIC_QOS = QosSpec(durability='transient_local', depth=1)
"""/tf_static as tf2's static broadcaster offers it: reliable, transient local, keep last 1."""
CONTACT_FORCES_LABEL = 'node'
"""Label of the one dimension of /drill_twin/contact/forces: the finite-element nodes from the
top (x = 0) to the bit; their depths are in docs/ROS-INTERFACE.md."""
