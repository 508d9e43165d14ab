"""Republish a recorded twin log on its topics with its timing (``drill-twin replay``)."""
from __future__ import annotations

import time

import rclpy
from rclpy.executors import ExternalShutdownException
from rclpy.node import Node

from drill_twin import interface as itf
from drill_twin.recording.qos import rclpy_qos_profile
from drill_twin.recording.reader import iter_messages, topics as log_topics
from drill_twin.recording.topics import twin_topics

SKIPPED = (itf.ROSOUT,)
"""Not republished: a replaying node logs to /rosout itself."""


class ReplayNode(Node):
    """Publishers for every recorded topic (the types and QoS the twin offers)."""

    def __init__(self, path, stations_m):
        super().__init__('drill_twin_replay')
        specs = twin_topics(stations_m)
        self.publishers_by_topic = {}
        for topic, type_name in log_topics(path).items():
            if topic in SKIPPED:
                continue
            spec = specs.get(topic)
            qos = rclpy_qos_profile(spec.qos if spec else itf.STATE_QOS)
            message_class = _message_class(type_name)
            self.publishers_by_topic[topic] = self.create_publisher(message_class, topic, qos)


def _message_class(type_name: str):
    from drill_twin.recording.message_types import import_message_class

    return import_message_class(type_name)


def replay(path, rate: float, ros_args: list[str], delay_s: float = 1.0, report=print) -> int:
    """
    Publish the log's messages, paced by their log times divided by ``rate``.

    Publishing starts after ``delay_s`` seconds, for subscribers to discover the publishers
    (FastDDS: 1-2 s).
    """
    from drill_twin.viz.rerun_view import stations_from_topics

    rclpy.init(args=ros_args)
    node = None
    count = 0
    try:
        node = ReplayNode(path, stations_from_topics(log_topics(path)))
        time.sleep(delay_s)
        start_wall = time.monotonic()
        first = None
        for item in iter_messages(path):
            if item.topic not in node.publishers_by_topic:
                continue
            if first is None:
                first = item.log_time_ns
            due = start_wall + (item.log_time_ns - first) * 1e-9 / rate
            delay = due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
            if not rclpy.ok():
                break
            node.publishers_by_topic[item.topic].publish(item.message)
            count += 1
        report(f'replayed {count} messages from {path} at {rate:g}x')
    except (KeyboardInterrupt, ExternalShutdownException):
        report(f'replay interrupted after {count} messages')
    finally:
        if node is not None:
            node.destroy_node()
        rclpy.try_shutdown()
    return 0
