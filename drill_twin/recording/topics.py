"""
The twin's topics as the recorder sees them: topic -> (message type, offered QoS).

Built from the names in :mod:`drill_twin.interface`; the vibration topics depend on the
measurement stations (depths in m along the string).
"""
from __future__ import annotations

from typing import Iterable, NamedTuple

from drill_twin import interface as itf
from drill_twin.interface import QosSpec

BIT_JOINTS = (itf.BIT_AXIAL, itf.BIT_ROTATION)
"""Joint order of the bit-state and ensemble JointState messages (the rerun layout and the
synthetic log rely on it)."""
TOP_JOINTS = (itf.TOP_DRIVE, itf.HOOK)
"""Joint order of the top-state JointState messages."""

ROSOUT_QOS = QosSpec(reliability='reliable', durability='transient_local', depth=1000)
"""What rcl's /rosout publisher offers (its 10 s lifespan is not expressible in QosSpec)."""

JOINT_STATE = 'sensor_msgs/msg/JointState'
WRENCH_STAMPED = 'geometry_msgs/msg/WrenchStamped'
IMU = 'sensor_msgs/msg/Imu'
VECTOR3_STAMPED = 'geometry_msgs/msg/Vector3Stamped'
FLOAT64_MULTI_ARRAY = 'std_msgs/msg/Float64MultiArray'
FLOAT64 = 'std_msgs/msg/Float64'
STRING = 'std_msgs/msg/String'
DIAGNOSTIC_ARRAY = 'diagnostic_msgs/msg/DiagnosticArray'
CLOCK = 'rosgraph_msgs/msg/Clock'
LOG = 'rcl_interfaces/msg/Log'
TF_MESSAGE = 'tf2_msgs/msg/TFMessage'


class TopicSpec(NamedTuple):
    """Message type ('pkg/msg/Type') and offered QoS of one topic."""

    type_name: str
    qos: QosSpec


def twin_topics(stations_m: Iterable[float] = (), *, tf: bool = False,
                measurement_topics: Iterable[str] = (),
                scalar_measurement_topics: Iterable[str] = ()) -> dict[str, TopicSpec]:
    """
    List every topic the twin publishes or subscribes.

    :param stations_m: depths (m) of the measurement stations (one IMU and one
        displacement topic each).
    :param tf: include /tf and /tf_static (published where tf2_msgs is installed).
    :param measurement_topics: the rig's sensor topics the twin assimilates (JointState).
    :param scalar_measurement_topics: its channels on topics of their own (Float64).
    """
    state, diagnostics, clock = itf.STATE_QOS, itf.DIAGNOSTICS_QOS, itf.CLOCK_QOS
    result = {command: TopicSpec(STRING if command in itf.MODE_COMMANDS else FLOAT64, state)
              for command in itf.COMMANDS}
    result.update({itf.cmd_applied_topic(command): TopicSpec(JOINT_STATE, state)
                   for command in itf.COMMANDS})
    result.update({topic: TopicSpec(FLOAT64, state) for topic in itf.SURFACE_TOPICS})
    result.update({itf.driller_topic(name): TopicSpec(FLOAT64, state)
                   for name in itf.DRILLER_TOPICS})
    result.update({
        itf.BIT_STATE: TopicSpec(JOINT_STATE, state),
        itf.BIT_WRENCH: TopicSpec(WRENCH_STAMPED, state),
        itf.TOP_STATE: TopicSpec(JOINT_STATE, state),
        itf.CONTACT_FORCES: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.KPI_STICK_SLIP: TopicSpec(FLOAT64, state),
        itf.KPI_MSE: TopicSpec(FLOAT64, state),
        itf.KPI_ROP: TopicSpec(FLOAT64, state),
        itf.HOLE_DEPTH: TopicSpec(FLOAT64, state),
        itf.ENSEMBLE_MEAN: TopicSpec(JOINT_STATE, state),
        itf.ENSEMBLE_LOWER: TopicSpec(JOINT_STATE, state),
        itf.ENSEMBLE_UPPER: TopicSpec(JOINT_STATE, state),
        itf.ASSIMILATION_GERM_MEAN: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_GERM_LOWER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_GERM_UPPER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_LAW_MEAN: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_LAW_LOWER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_LAW_UPPER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_BIAS_MEAN: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_BIAS_LOWER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.ASSIMILATION_BIAS_UPPER: TopicSpec(FLOAT64_MULTI_ARRAY, state),
        itf.DIAGNOSTICS: TopicSpec(DIAGNOSTIC_ARRAY, diagnostics),
        itf.CLOCK: TopicSpec(CLOCK, clock),
        itf.ROSOUT: TopicSpec(LOG, ROSOUT_QOS),
    })
    for x_m in stations_m:
        result[itf.vibration_imu_topic(x_m)] = TopicSpec(IMU, state)
        result[itf.vibration_displacement_topic(x_m)] = TopicSpec(VECTOR3_STAMPED, state)
    for topic in measurement_topics:
        result[topic] = TopicSpec(JOINT_STATE, state)
    for topic in scalar_measurement_topics:
        result[topic] = TopicSpec(FLOAT64, state)
    if tf:
        result[itf.TF] = TopicSpec(TF_MESSAGE, itf.TF_QOS)
        result[itf.TF_STATIC] = TopicSpec(TF_MESSAGE, itf.TF_STATIC_QOS)
    return result
