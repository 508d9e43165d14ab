"""
QoS of a recorded topic: rosbag2's ``offered_qos_profiles`` YAML and the rclpy profile.

rosbag2 (metadata version 9, Jazzy) stores in each MCAP channel's metadata a YAML list of
the QoS profiles offered by the topic's publishers, one mapping per publisher::

    - history: keep_last
      depth: 10
      reliability: reliable
      durability: volatile
      deadline:
        sec: 0
        nsec: 0
      lifespan:
        sec: 0
        nsec: 0
      liveliness: automatic
      liveliness_lease_duration:
        sec: 0
        nsec: 0
      avoid_ros_namespace_conventions: false

Policies are spelled as ``rmw_qos_*_policy_to_str`` spells them; durations are
``{sec, nsec}`` and ``0, 0`` means "unspecified" (the rmw default, infinite).  rosbag2's
reader detects this string form and the older integer form by itself.  This module does not
import rclpy; :func:`rclpy_qos_profile` imports it when called.
"""
from __future__ import annotations

from typing import Any, Iterable

import yaml

from drill_twin.interface import QosSpec

HISTORY_POLICIES = ('keep_last', 'keep_all', 'system_default')
RELIABILITY_POLICIES = ('reliable', 'best_effort', 'system_default', 'best_available')
DURABILITY_POLICIES = ('volatile', 'transient_local', 'system_default', 'best_available')
LIVELINESS = 'automatic'
UNSPECIFIED_DURATION = {'sec': 0, 'nsec': 0}


def validate_qos_spec(spec: QosSpec) -> None:
    """Raise ValueError unless every policy of ``spec`` is one rmw knows."""
    for value, allowed, what in ((spec.history, HISTORY_POLICIES, 'history'),
                                 (spec.reliability, RELIABILITY_POLICIES, 'reliability'),
                                 (spec.durability, DURABILITY_POLICIES, 'durability')):
        if value not in allowed:
            raise ValueError(f'{what} {value!r} is not one of {allowed}')
    if isinstance(spec.depth, bool) or not isinstance(spec.depth, int) or spec.depth < 0:
        raise ValueError(f'depth must be a non-negative int, not {spec.depth!r}')
    if spec.history == 'keep_last' and spec.depth == 0:
        raise ValueError('keep_last history needs depth >= 1')


def qos_profile_dict(spec: QosSpec) -> dict[str, Any]:
    """One rosbag2 v9 QoS profile mapping (keys in rosbag2's order) for ``spec``."""
    validate_qos_spec(spec)
    return {
        'history': spec.history,
        'depth': spec.depth,
        'reliability': spec.reliability,
        'durability': spec.durability,
        'deadline': dict(UNSPECIFIED_DURATION),
        'lifespan': dict(UNSPECIFIED_DURATION),
        'liveliness': LIVELINESS,
        'liveliness_lease_duration': dict(UNSPECIFIED_DURATION),
        'avoid_ros_namespace_conventions': False,
    }


def offered_qos_profiles_yaml(specs: QosSpec | Iterable[QosSpec]) -> str:
    """
    Return the channel metadata ``offered_qos_profiles`` for one or more publishers.

    Block-style YAML without a trailing newline, as yaml-cpp's ``YAML::Dump`` writes it.
    """
    if isinstance(specs, QosSpec):
        specs = [specs]
    profiles = [qos_profile_dict(spec) for spec in specs]
    text = yaml.safe_dump(profiles, sort_keys=False, default_flow_style=False)
    return text.rstrip('\n')


def rclpy_qos_profile(spec: QosSpec):
    """Return the ``rclpy.qos.QoSProfile`` of ``spec`` (imports rclpy)."""
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

    validate_qos_spec(spec)
    return QoSProfile(
        history=HistoryPolicy[spec.history.upper()],
        depth=spec.depth,
        reliability=ReliabilityPolicy[spec.reliability.upper()],
        durability=DurabilityPolicy[spec.durability.upper()],
    )
