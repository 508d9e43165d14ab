"""
What the twin node sends: its publishers, gated by their subscribers, and the log beside them.

A volatile topic no subscription matches is not published (the middleware would drop the
message: a subscriber hears a topic from its matching on, published or not); a durable one
always is (kept for late joiners). A message is serialised once, for the wire and the log.
A tick's every-tick states are built only for a subscriber or for the log.
"""
from __future__ import annotations

from rclpy._rclpy_pybind11 import RCLError
from rclpy.serialization import serialize_message

from drill_twin.ros import messages
from drill_twin.ros.run_log import RunLog


class Outputs:
    """
    The node's publishers and its log, as one place to send a message.

    :param topics: {topic: (message class, QosSpec)} of the node's publishers
        (:func:`drill_twin.ros.messages.publications`).
    :param publishers: {topic: rclpy publisher} of those topics.
    :param run_log: the node's log.
    :param context: the node's rclpy context (a signal can shut it down mid-tick).
    """

    def __init__(self, topics: dict, publishers: dict, run_log: RunLog, context):
        self.topics = topics
        self.publishers = publishers
        self.durable = {topic for topic, (_, qos) in topics.items()
                        if qos.durability == 'transient_local'}
        self._run_log = run_log
        self._context = context

    def publish(self, topic: str, message, time_ns: int, log: bool = True) -> None:
        """
        Send ``message`` to the subscribers of ``topic`` and, if ``log``, to the log.

        Only where it goes somewhere (see the module docstring).
        """
        log = log and self._run_log.taking
        heard = self.heard(topic)
        if not (heard or log):
            return
        data = serialize_message(message)           # once, for the wire and for the log
        if heard:
            try:
                self.publishers[topic].publish(data)
            except RCLError:
                if self._context.ok():
                    raise
                return                              # a signal shut the context down mid-tick
        if log:
            self._run_log.write_serialized(topic, data, time_ns)

    def heard(self, topic: str) -> bool:
        """Whether a message on ``topic`` reaches a subscriber (matched, or a late joiner)."""
        if topic in self.durable:
            return True
        try:
            return self.publishers[topic].get_subscription_count() > 0
        except RCLError:
            if self._context.ok():
                raise
            return False                            # a signal shut the context down mid-tick

    def publish_tick(self, snapshot, stations_m, time_ns: int, plan: messages.TickPlan,
                     states_logged: bool) -> None:
        """
        Send a tick's messages (:func:`~drill_twin.ros.messages.tick_messages`).

        The every-tick states go to the log only if ``states_logged``; a message nobody
        hears and the log does not take is not even built.
        """
        logging = self._run_log.taking

        def wanted(topic):
            return logging and messages.logged(topic, states_logged) or self.heard(topic)

        for topic, message in messages.tick_messages(snapshot, stations_m, time_ns, plan,
                                                     wanted):
            self.publish(topic, message, time_ns, log=messages.logged(topic, states_logged))
