"""
A synthetic log of every twin topic, for the recording and viewer tests (a test helper).

The messages are built by the node's own code (:mod:`drill_twin.ros.messages`) from
closed-form signals that look like a drill string in stick-slip (bit speed oscillating
between 0 and about twice the top-drive speed, WOB and TOB negative while drilling), not from
the physics core. Header stamps and log times are the same simulated time: ``start_ns`` plus
the elapsed time (ns).
"""
from __future__ import annotations

import math
import os
from types import SimpleNamespace
from typing import Any, Iterable, Iterator, NamedTuple

import numpy as np

from drill_twin import interface as itf
from drill_twin.assimilation.sequential import AnalysisRecord
from drill_twin.recording.log_metadata import RECORD_NAME
from drill_twin.recording.mcap_log import McapLog
from drill_twin.recording.topics import twin_topics
from drill_twin.ros import messages
from drill_twin.twin.engine import BitState
from drill_twin.integrator.stepping import TwinEvent
from drill_twin.rig.surface import SurfaceReadings

DEFAULT_START_NS = 1_700_000_000_000_000_000
"""2023-11-14T22:13:20Z, an arbitrary epoch for synthetic logs."""
DEFAULT_STATIONS_M = (500.0, 1000.0)
N_CONTACTS = 4


class TimedMessage(NamedTuple):
    """A message to write: topic, message, log time (ns)."""

    topic: str
    message: Any
    log_time_ns: int


def _snapshot(t: float, step: int, stations, state: dict) -> SimpleNamespace:
    """Make a stand-in for TwinSnapshot with the fields :mod:`drill_twin.ros.messages` reads."""
    top_speed, hook_load, depth0 = 10.0, 1.2e6, 1500.0      # rad/s, N, m
    phase = 2.0 * math.pi * 0.25 * t                        # stick-slip at 0.25 Hz
    bit_speed = max(0.0, top_speed * (1.0 + 1.1 * math.sin(phase)))
    rop = 0.004 + 0.002 * math.sin(0.5 * phase)              # m/s
    wob = -1.0e5 * (1.0 + 0.1 * math.sin(3.0 * phase))       # N
    tob = -6.0e3 * (0.8 + 0.4 * math.cos(phase))             # N m
    state['angle'] += bit_speed * state['dt']
    state['depth'] += rop * state['dt']
    depth, angle = state['depth'], state['angle']
    spread = (0.05 * abs(wob), 0.3 * top_speed, 0.2 * rop)

    def bit(sign):
        return BitState(depth_m=depth, rop_m_per_s=rop + sign * spread[2],
                        weight_on_bit_n=wob + sign * spread[0], angle_rad=angle,
                        speed_rad_per_s=bit_speed + sign * spread[1], torque_on_bit_nm=tob)

    n = len(stations)
    scale = np.array([x / 1000.0 for x in stations])
    offset = np.array(stations, dtype=float)
    acceleration = np.zeros((1, n, 3))
    acceleration[0, :, 0] = 0.5 * scale * math.sin(7.0 * phase)
    acceleration[0, :, 1] = 2.0 * scale * np.sin(3.0 * phase + offset)
    acceleration[0, :, 2] = 2.0 * scale * np.cos(3.0 * phase + offset)
    spin = np.zeros((1, n, 3))
    spin[0, :, 0] = bit_speed * (1.0 - 0.3 * scale)
    displacement = np.zeros((1, n, 3))
    displacement[0, :, 0] = 1e-4 * math.sin(7.0 * phase)
    displacement[0, :, 1] = 0.02 * scale * np.sin(3.0 * phase + offset)
    displacement[0, :, 2] = 0.02 * scale * np.cos(3.0 * phase + offset)
    observation = SimpleNamespace(
        top_angle_rad=top_speed * t, hook_position_m=np.array([depth - depth0]),
        top_speed_rad_per_s=top_speed, hook_velocity_m_per_s=np.array([rop]),
        top_torque_nm=np.array([-tob + 2.0e3 * math.sin(phase + 0.5)]),
        hook_load_n=hook_load + wob, hole_depth_m=np.array([depth]),
        station_acceleration_m_per_s2=acceleration, station_spin_rate_rad_per_s=spin,
        station_displacement_m=displacement,
        contact_force_n=np.array([[max(0.0, 5e3 * math.sin(phase * (k + 1) + k))
                                   for k in range(N_CONTACTS)]]))
    events = ()
    if step % state['every_second'] == 0:
        events = (TwinEvent(kind='impact', level='warn', time_s=t,
                            message=f'synthetic impact at step {step}',
                            values={'x_m': '700.0'}),)
    return SimpleNamespace(
        time_s=t, step=step, bit=bit(0.0), ensemble_mean=bit(0.0), ensemble_lower=bit(-1.96),
        ensemble_upper=bit(1.96), ensemble_step=step, observation=observation,
        stick_slip_severity=1.1 * (1.0 + 0.05 * math.sin(0.1 * phase)),
        mse_pa=abs(wob) / 0.05 + 2.0 * math.pi * abs(tob) * bit_speed / (0.05 * max(rop, 1e-4)),
        rop_m_per_h=rop * 3600.0, events=events, top_speed=top_speed, hook_load=hook_load,
        surface=SurfaceReadings(
            speed_rad_per_s=top_speed, torque_nm=float(observation.top_torque_nm[0]),
            hook_load_n=observation.hook_load_n, block_position_m=depth - depth0,
            bit_depth_m=depth, hole_depth_m=depth, rop_m_per_s=rop, weight_on_bit_n=-wob))


SYNTHETIC_COMMANDS = {itf.CMD_TOP_DRIVE_MODE: 'dynamic', itf.CMD_TOP_DRIVE_CONTROLLER: 'stiff',
                      itf.CMD_TOP_DRIVE_TORQUE_LIMIT: 60e3, itf.CMD_AXIAL_MODE: 'hook_load',
                      itf.CMD_BLOCK_VELOCITY: 2e-3, itf.CMD_WOB_SETPOINT: 1e5}
"""The drive commands of the synthetic log (besides the speed and the hook load)."""


def synthetic_messages(duration_s: float = 10.0, rate_hz: float = 100.0,
                       stations_m: Iterable[float] = DEFAULT_STATIONS_M,
                       start_ns: int = DEFAULT_START_NS) -> Iterator[TimedMessage]:
    """
    Yield messages of every twin topic in time order.

    State topics, KPIs, the ensemble and /clock come at ``rate_hz``; commands, an estimated
    germ and law and an event (/diagnostics) at 1 Hz; a /rosout line every 2 s.
    """
    stations = [float(x) for x in stations_m]
    n_steps = int(round(duration_s * rate_hz))
    period_ns = int(round(1e9 / rate_hz))
    state = {'angle': 0.0, 'depth': 1500.0, 'dt': 1.0 / rate_hz,
             'every_second': max(1, int(round(rate_hz)))}
    for step in range(n_steps):
        t_ns = start_ns + step * period_ns
        snapshot = _snapshot(step / rate_hz, step, stations, state)
        if step % state['every_second'] == 0:
            yield TimedMessage(itf.CMD_TOP_DRIVE_SPEED, messages.scalar(snapshot.top_speed),
                               t_ns)
            yield TimedMessage(itf.CMD_HOOK_LOAD, messages.scalar(snapshot.hook_load), t_ns)
            values = dict(SYNTHETIC_COMMANDS, **{itf.CMD_TOP_DRIVE_SPEED: snapshot.top_speed,
                                                 itf.CMD_HOOK_LOAD: snapshot.hook_load})
            for topic, value in values.items():
                if topic in SYNTHETIC_COMMANDS:
                    yield TimedMessage(topic, messages.command_message(topic, value), t_ns)
                yield TimedMessage(itf.cmd_applied_topic(topic),
                                   messages.command_applied(topic, value, t_ns), t_ns)
            analysis = AnalysisRecord(time_s=step / rate_hz, nis=1.0, measurements=2,
                                      germ_mean=(1.0, 0.01 * step, 1.1),
                                      germ_lower=(0.9, -0.1, 1.0), germ_upper=(1.1, 0.1, 1.2),
                                      law_mean=(1.0, 1.0, 1.0, 1.0 + 0.001 * step, 1.0),
                                      law_lower=(0.9,) * 5, law_upper=(1.1,) * 5,
                                      bias_channels=('top_torque',),
                                      bias_mean=(100.0 + step,), bias_lower=(50.0 + step,),
                                      bias_upper=(150.0 + step,))
            for topic, message in (messages.germ_messages(analysis)
                                   + messages.law_messages(analysis)
                                   + messages.bias_messages(analysis)):
                yield TimedMessage(topic, message, t_ns)
        plan = messages.TickPlan(kpis=True, ensemble_stamp_ns=t_ns, clock=True)
        for topic, message in messages.tick_messages(snapshot, stations, t_ns, plan):
            yield TimedMessage(topic, message, t_ns)
        if step % (2 * state['every_second']) == 0:
            line = (f'synthetic step {step}: bit speed '
                    f'{snapshot.bit.speed_rad_per_s:.2f} rad/s')
            yield TimedMessage(itf.ROSOUT, messages.log('info', line, itf.NODE_NAME, t_ns),
                               t_ns)


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
