"""
The rig emulator: the model run as the truth, read as a rig's sensors read it.

One member (the mean model, or a germ given) under the schedule of set-points of the
settings: the top-drive speed and hook load commands change at their times (the initial ones
are the configuration's operating point). Every sensor samples its channels at its rate with
its noise, bias and delay (:mod:`.measurements`); the true downhole state is kept at
``rig.truth_rate_hz`` for scoring.
"""
from __future__ import annotations

import math

import numpy as np

from drill_twin.assimilation.measurements import (SENSOR_CHANNELS, channel_values, read,
                                                  sample_times)
from drill_twin.assimilation.rig_log import RigLog, SensorSamples, Truth
from drill_twin.assimilation.settings import AssimilationConfig
from drill_twin.config.schema import DrillStringConfig
from drill_twin.integrator.simulator import Simulator
from drill_twin.integrator.stepping import GuardedSimulator
from drill_twin.rig.rig import Rig


def schedule_commands(rig: Rig, settings: AssimilationConfig, duration_s: float):
    """
    Return (speed_commands, hook_commands) from the schedule.

    Each is a (c, 2) array of (time s, value), starting with the rig's initial commands at
    t = 0.
    """
    speed = [(0.0, rig.commands.top_speed_rad_per_s)]
    hook0 = rig.commands.hook_load_n
    hook = [(0.0, hook0)]
    for point in settings.rig.schedule:
        if point.time_s > duration_s:
            continue
        if point.top_drive_speed_hz is not None:
            speed.append((point.time_s, 2 * math.pi * point.top_drive_speed_hz))
        if point.hook_load_change_n is not None:
            hook.append((point.time_s, hook0 + point.hook_load_change_n))
    return np.array(speed, dtype=float), np.array(hook, dtype=float)


def run_rig(config: DrillStringConfig, settings: AssimilationConfig, duration_s: float,
            germ: np.ndarray | None = None, system=None, progress=None) -> RigLog:
    """
    Run the truth for ``duration_s`` and return its log.

    :param config: the truth's model.
    :param settings: sensors, channels, schedule, noise seed.
    :param germ: (2, 2) the truth's bit-rock germ, or None (its mean law).
    :param system: a prebuilt reduced system of ``config``.
    :param progress: called with the fraction done, or None.
    """
    sim = Simulator(config, 1, germs=None if germ is None else germ[None], system=system)
    rig = Rig(sim)
    guarded = GuardedSimulator(rig, first_member=0, name='the rig')
    rng = np.random.default_rng(settings.rig.seed)
    speed_commands, hook_commands = schedule_commands(rig, settings, duration_s)
    dt = sim.dt
    steps = int(round(duration_s / dt))
    duration_s = steps * dt
    stamps = {name: sample_times(getattr(settings.sensors, name).rate_hz, duration_s)
              for name in SENSOR_CHANNELS}
    sample_steps = {name: np.round(times / dt).astype(int) for name, times in stamps.items()}
    truth_steps = np.round(sample_times(settings.rig.truth_rate_hz, duration_s) / dt)
    truth_steps = set(truth_steps.astype(int).tolist())
    due = {}
    for name, indices in sample_steps.items():
        for index in indices.tolist():
            due.setdefault(index, []).append(name)
    readings = {name: {c: [] for c in SENSOR_CHANNELS[name]} for name in SENSOR_CHANNELS}
    truth_rows = []
    speed_index = hook_index = 0
    for step in range(1, steps + 1):
        start = (step - 1) * dt
        while speed_index < len(speed_commands) and speed_commands[speed_index, 0] <= start + 1e-9:
            rig.set_top_drive_speed(speed_commands[speed_index, 1])
            speed_index += 1
        while hook_index < len(hook_commands) and hook_commands[hook_index, 0] <= start + 1e-9:
            rig.set_hook_load(hook_commands[hook_index, 1])
            hook_index += 1
        guarded.step()
        if step in due or step in truth_steps:
            o = sim.observe()
        for name in due.get(step, ()):
            for channel in SENSOR_CHANNELS[name]:
                true_value = channel_values(o, channel, 1)[0]
                readings[name][channel].append(read(settings, channel, true_value, rng))
        if step in truth_steps:
            truth_rows.append((o.time_s, o.speed_rad_per_s[0], o.angle_rad[0],
                               o.rop_m_per_s[0], -o.torque_on_bit_nm[0],
                               -o.weight_on_bit_n[0], o.bit_depth_m[0], o.hole_depth_m[0]))
        if progress is not None and step % 200 == 0:
            progress(step * dt, duration_s)
    sensors = {}
    for name, times in stamps.items():
        delay = getattr(settings.sensors, name).delay_s
        values = {c: np.asarray(v, dtype=float) for c, v in readings[name].items()}
        arrival = times + delay
        keep = arrival <= duration_s + 1e-9            # what has arrived by the log's end
        sensors[name] = SensorSamples(stamp_s=times[keep], arrival_s=arrival[keep],
                                      values={c: v[keep] for c, v in values.items()})
    columns = np.array(truth_rows, dtype=float).reshape(-1, 8).T
    truth = Truth(*columns)
    return RigLog(duration_s=duration_s, sensors=sensors, speed_commands=speed_commands,
                  hook_commands=hook_commands, truth=truth)
