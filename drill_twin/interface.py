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
# The rig's drives (docs/DRIVES.md): mode switches as std_msgs/msg/String.
CMD_TOP_DRIVE_MODE = '/drill_twin/cmd/top_drive_mode'        # String: kinematic | dynamic
CMD_TOP_DRIVE_CONTROLLER = '/drill_twin/cmd/top_drive_controller'
"""std_msgs/msg/String: stiff | soft_torque | impedance (the dynamic drive's controller)."""
CMD_TOP_DRIVE_TORQUE_LIMIT = '/drill_twin/cmd/top_drive_torque_limit'   # Float64, N m, > 0
CMD_AXIAL_MODE = '/drill_twin/cmd/axial_mode'
"""std_msgs/msg/String: hook_load | block_velocity | autodriller (the drawworks' input)."""
CMD_BLOCK_VELOCITY = '/drill_twin/cmd/block_velocity'        # Float64, m/s, down > 0
CMD_WOB_SETPOINT = '/drill_twin/cmd/wob_setpoint'            # Float64, N, compression > 0

TOP_DRIVE_MODES = ('kinematic', 'dynamic')
TOP_DRIVE_CONTROLLERS = ('stiff', 'soft_torque', 'impedance')
AXIAL_MODES = ('hook_load', 'block_velocity', 'autodriller')

COMMANDS = {
    CMD_TOP_DRIVE_SPEED: 'top_drive_speed', CMD_HOOK_LOAD: 'hook_load',
    CMD_TOP_DRIVE_MODE: 'top_drive_mode', CMD_TOP_DRIVE_CONTROLLER: 'top_drive_controller',
    CMD_TOP_DRIVE_TORQUE_LIMIT: 'top_drive_torque_limit', CMD_AXIAL_MODE: 'axial_mode',
    CMD_BLOCK_VELOCITY: 'block_velocity', CMD_WOB_SETPOINT: 'wob_setpoint'}
"""Every command topic -> its short name (the name of its echo, :func:`cmd_applied_topic`)."""
MODE_COMMANDS = {CMD_TOP_DRIVE_MODE: TOP_DRIVE_MODES,
                 CMD_TOP_DRIVE_CONTROLLER: TOP_DRIVE_CONTROLLERS, CMD_AXIAL_MODE: AXIAL_MODES}
"""The std_msgs/msg/String commands and the values they accept; the others are Float64."""


def cmd_applied_topic(command_topic: str) -> str:
    """
    Return the echo topic of a command, e.g. '/drill_twin/cmd_applied/top_drive_speed'.

    sensor_msgs/msg/JointState: header.stamp = the twin time of the first model step that used
    the command; name = [the command's short name], position = [the value] (Float64 commands,
    SI) or, for a mode, name = ['<short name>=<mode>'], position = [the mode's index in
    MODE_COMMANDS], e.g. ['top_drive_mode=dynamic'], [1.0]; velocity and effort [0.0] (unused).
    """
    return f'/drill_twin/cmd_applied/{COMMANDS[command_topic]}'


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
bit_axial position) is smaller while the bit is lifted off bottom, and WOB / k larger while it
presses the rock on bottom (``bit_rock.contact_stiffness_n_per_m`` = k; 1 mm at 100 kN)."""
# Surface measurements as a rig reads them (SI, std_msgs/msg/Float64, every tick).
SURFACE_SPEED = '/drill_twin/surface/speed'                  # rad/s, the top's speed
SURFACE_TORQUE = '/drill_twin/surface/torque'                # N m, the string's top torque
SURFACE_HOOK_LOAD = '/drill_twin/surface/hook_load'          # N, what the hook holds
SURFACE_BLOCK_POSITION = '/drill_twin/surface/block_position'
"""m, down > 0 from the start: the travelling block (the drawworks' x_b), or the top's axial
displacement when the hook force is the input (hook_load mode, the block follows the top)."""
SURFACE_BIT_DEPTH = '/drill_twin/surface/bit_depth'          # m
SURFACE_HOLE_DEPTH = '/drill_twin/surface/hole_depth'        # m
SURFACE_ROP = '/drill_twin/surface/rop'                      # m/s, the hole's deepening rate
SURFACE_WOB = '/drill_twin/surface/weight_on_bit'
"""N, compression > 0: the surface WOB a rig computes, off-bottom hook load minus hook load
(the off-bottom hook load is the string's weight as the model counts it)."""
SURFACE_TOPICS = (SURFACE_SPEED, SURFACE_TORQUE, SURFACE_HOOK_LOAD, SURFACE_BLOCK_POSITION,
                  SURFACE_BIT_DEPTH, SURFACE_HOLE_DEPTH, SURFACE_ROP, SURFACE_WOB)
# The driller's view in drilling units, WITS record 1 mnemonics (std_msgs/msg/Float64, at
# kpi_rate_hz): rpm, kN m, kN and klbf, m/h, m.
DRILLER_PREFIX = '/drill_twin/driller/'
DRILLER_TOPICS = {
    'RPMA': ('rpm', SURFACE_SPEED), 'TQA': ('kN m', SURFACE_TORQUE),
    'HKLA': ('kN', SURFACE_HOOK_LOAD), 'HKLA_klbf': ('klbf', SURFACE_HOOK_LOAD),
    'WOBA': ('kN', SURFACE_WOB), 'WOBA_klbf': ('klbf', SURFACE_WOB),
    'ROPA': ('m/h', SURFACE_ROP), 'DBTM': ('m', SURFACE_BIT_DEPTH),
    'DMEA': ('m', SURFACE_HOLE_DEPTH)}
"""WITS name -> (unit, the SI topic it is converted from); topic DRILLER_PREFIX + name."""
NEWTON_PER_KLBF = 4448.2216152605
"""1 klbf in N (1000 lbf, 1 lbf = 4.4482216152605 N exactly)."""


def driller_topic(wits_name: str) -> str:
    """Return the topic of a driller's-view value, e.g. 'RPMA' -> '/drill_twin/driller/RPMA'."""
    return DRILLER_PREFIX + wits_name


ENSEMBLE_MEAN = '/drill_twin/ensemble/bit_state/mean'        # sensor_msgs/msg/JointState
ENSEMBLE_LOWER = '/drill_twin/ensemble/bit_state/lower'      # 2.5 % quantile, JointState
ENSEMBLE_UPPER = '/drill_twin/ensemble/bit_state/upper'      # 97.5 % quantile, JointState
ASSIMILATION_PREFIX = '/drill_twin/assimilation'
ASSIMILATION_GERM_MEAN = ASSIMILATION_PREFIX + '/germ/mean'    # std_msgs/Float64MultiArray
ASSIMILATION_GERM_LOWER = ASSIMILATION_PREFIX + '/germ/lower'  # [G11, G12, G22], 2.5 %
ASSIMILATION_GERM_UPPER = ASSIMILATION_PREFIX + '/germ/upper'  # 97.5 %
ASSIMILATION_LAW_MEAN = ASSIMILATION_PREFIX + '/law/mean'      # std_msgs/Float64MultiArray
ASSIMILATION_LAW_LOWER = ASSIMILATION_PREFIX + '/law/lower'    # factors of [a1 .. a5], 2.5 %
ASSIMILATION_LAW_UPPER = ASSIMILATION_PREFIX + '/law/upper'    # 97.5 % (parameters: law)
ASSIMILATION_BIT_STATE = ASSIMILATION_PREFIX + '/bit_state'   # EST.mcap: + /mean, /lower, /upper
ASSIMILATION_OPEN_LOOP_BIT_STATE = ASSIMILATION_PREFIX + '/open_loop/bit_state'   # the same
RIG_TRUTH_BIT_STATE = '/rig/truth/bit_state'   # the rig emulator's true bit state (scoring)
ESTIMATE_METADATA = 'drill_twin_estimate'   # EST.mcap's metadata record: clock_epoch_ns (0)
ASSIMILATION_BIAS_MEAN = ASSIMILATION_PREFIX + '/bias/mean'    # std_msgs/Float64MultiArray
ASSIMILATION_BIAS_LOWER = ASSIMILATION_PREFIX + '/bias/lower'  # estimated sensor biases (SI),
ASSIMILATION_BIAS_UPPER = ASSIMILATION_PREFIX + '/bias/upper'  # labelled by channel
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
MEASUREMENT_QOS = QosSpec(reliability='best_effort', depth=100)
"""The rig's sensor subscriptions (assimilation): best effort, so that they match reliable and
best-effort sensor publishers alike; keep last 100 (a few ticks of several sensors)."""
TF_QOS = QosSpec(depth=100)
"""/tf as tf2's broadcaster offers it: reliable, volatile, keep last 100."""
TF_STATIC_QOS = QosSpec(durability='transient_local', depth=1)
"""/tf_static as tf2's static broadcaster offers it: reliable, transient local, keep last 1."""
CONTACT_FORCES_LABEL = 'node'
"""Label of the one dimension of /drill_twin/contact/forces: the finite-element nodes from the
top (x = 0) to the bit; their depths are in docs/ROS-INTERFACE.md."""
