"""rosbag2 v9 ``offered_qos_profiles`` YAML and rclpy profiles from QosSpec."""
import pytest
import yaml

from drill_twin.interface import CLOCK_QOS, QosSpec, STATE_QOS
from drill_twin.recording.qos import (
    offered_qos_profiles_yaml, qos_profile_dict, rclpy_qos_profile)

ROSBAG2_KEYS = ['history', 'depth', 'reliability', 'durability', 'deadline', 'lifespan',
                'liveliness', 'liveliness_lease_duration', 'avoid_ros_namespace_conventions']


def test_yaml_is_a_list_of_v9_profiles():
    text = offered_qos_profiles_yaml(CLOCK_QOS)
    assert not text.endswith('\n')            # as yaml-cpp's YAML::Dump writes it
    profiles = yaml.safe_load(text)
    assert isinstance(profiles, list) and len(profiles) == 1
    profile = profiles[0]
    assert list(profile) == ROSBAG2_KEYS
    assert profile['history'] == 'keep_last' and profile['depth'] == 1
    assert profile['reliability'] == 'best_effort' and profile['durability'] == 'volatile'
    assert profile['liveliness'] == 'automatic'
    for key in ('deadline', 'lifespan', 'liveliness_lease_duration'):
        assert profile[key] == {'sec': 0, 'nsec': 0}
    assert profile['avoid_ros_namespace_conventions'] is False


def test_several_publishers():
    profiles = yaml.safe_load(offered_qos_profiles_yaml([STATE_QOS, CLOCK_QOS]))
    assert [p['reliability'] for p in profiles] == ['reliable', 'best_effort']
    assert text_starts_like_rosbag2(offered_qos_profiles_yaml(STATE_QOS))


def text_starts_like_rosbag2(text: str) -> bool:
    return text.startswith('- history: keep_last\n  depth: 10\n  reliability: reliable\n')


@pytest.mark.parametrize('spec', [
    QosSpec(reliability='sometimes'), QosSpec(durability='forever'),
    QosSpec(history='keep_some'), QosSpec(depth=-1), QosSpec(depth=0)])
def test_invalid_specs_are_rejected(spec):
    with pytest.raises(ValueError):
        qos_profile_dict(spec)


def test_rclpy_profile():
    from rclpy.qos import DurabilityPolicy, HistoryPolicy, ReliabilityPolicy

    profile = rclpy_qos_profile(QosSpec(durability='transient_local', depth=3))
    assert profile.history == HistoryPolicy.KEEP_LAST and profile.depth == 3
    assert profile.reliability == ReliabilityPolicy.RELIABLE
    assert profile.durability == DurabilityPolicy.TRANSIENT_LOCAL
    assert rclpy_qos_profile(CLOCK_QOS).reliability == ReliabilityPolicy.BEST_EFFORT
