"""
The rig's measurements as the twin node takes them: the topics, and each sample to the filter.

With an ensemble filter (``assimilation_enabled``) the node subscribes to the rig's sensors
the filter uses (sensor_msgs/JointState, one topic a sensor) and to the channels that come as
std_msgs/Float64 on topics of their own. A message is logged as received and handed to the
engine as a :class:`~drill_twin.assimilation.sequential.Sample`; a malformed one, or one that
comes before the twin's clock started, is refused with a diagnostic.
"""
from __future__ import annotations

import math

from drill_twin.assimilation.measurements import SENSOR_CHANNELS, values_from_joint_state
from drill_twin.assimilation.sequential import Sample
from drill_twin.assimilation.settings import SENSOR_OF
from drill_twin.ros.clock import TwinClock
from drill_twin.ros.run_log import RunLog


def measurement_topics(engine) -> dict[str, str]:
    """{topic: sensor} of the rig's sensors the ensemble filter uses (empty: it is off)."""
    settings = engine.ensemble.assimilation
    if settings is None or not engine.assimilating:
        return {}
    used = [c for c in settings.filter.measurements if c not in settings.scalar_topics()]
    return {getattr(settings.sensors, sensor).topic: sensor
            for sensor, channels in SENSOR_CHANNELS.items()
            if any(c in used for c in channels)}


def scalar_measurement_topics(engine) -> dict[str, str]:
    """{topic: channel} of the filter's channels that come as std_msgs/Float64 alone."""
    settings = engine.ensemble.assimilation
    if settings is None or not engine.assimilating:
        return {}
    return {topic: channel for channel, topic in settings.scalar_topics().items()
            if channel in settings.filter.measurements}


class MeasurementIntake:
    """
    The rig's samples on their way to the ensemble filter (see the module docstring).

    :param engine: the twin's engine (it counts, checks and queues the samples).
    :param clock: the node's clock (the samples' stamps are in its time).
    :param run_log: the node's log (the messages are logged as received).
    """

    def __init__(self, engine, clock: TwinClock, run_log: RunLog):
        self.engine = engine
        self.clock = clock
        self.run_log = run_log
        settings = engine.ensemble.assimilation      # channels read on their own topics
        self.scalar_channels = frozenset(settings.scalar_topics() if settings else ())

    def received(self, topic: str, message) -> bool:
        """Log a rig message as received; whether the twin's clock runs (else it is refused)."""
        if self.clock.started:
            self.run_log.write(topic, message, self.clock.twin_time_ns())
        else:
            self.engine.refuse_measurement(f'{topic}: received before the twin\'s clock '
                                           f'started')
        return self.clock.started

    def scalar(self, channel: str, topic: str, message) -> None:
        """
        Hand a channel's std_msgs/Float64 to the ensemble filter and log it.

        Unstamped: taken as sampled now less its sensor's delay (``delay_s``).
        """
        if not self.received(topic, message):
            return
        value = float(message.data)
        if not math.isfinite(value):
            self.engine.refuse_measurement(f'{topic}: {channel} = {value} is not finite')
            return
        settings = self.engine.ensemble.assimilation
        stamp_s = self.engine.time_s - settings.sensor_of(channel).delay_s
        self.engine.offer_measurement(Sample(SENSOR_OF[channel], stamp_s, {channel: value}))

    def joint_state(self, sensor: str, topic: str, message) -> None:
        """
        Hand a rig sample (sensor_msgs/JointState) to the ensemble filter and log it.

        Its stamp: the header's, in the twin's clock (an unset stamp is taken as now); a bad
        sample is refused with a diagnostic.
        """
        if not self.received(topic, message):
            return
        try:
            values = values_from_joint_state(sensor, message.name, message.position,
                                             message.velocity, message.effort)
            values = {c: v for c, v in values.items()               # the others: on their own
                      if c not in self.scalar_channels}
        except ValueError as error:
            self.engine.refuse_measurement(f'{topic}: {error}')
            return
        stamp_ns = message.header.stamp.sec * 1_000_000_000 + message.header.stamp.nanosec
        stamp_s = (stamp_ns - self.clock.epoch_ns) * 1e-9 if stamp_ns else self.engine.time_s
        self.engine.offer_measurement(Sample(sensor, stamp_s, values))
