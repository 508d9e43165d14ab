"""Observations recorded at a fixed interval into arrays (time on the last axis)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from drill_twin.integrator.observed_bit import (FLAG_RECORDS, FLOAT_RECORDS, MAX_CONTACT_FORCE,
                                                STATION_RECORDS, ObservedArrays)
from drill_twin.integrator.simulator import Observation

# Per-member channels: name -> (Observation attribute, unit) (arrays (m, n_t)).
BIT_CHANNELS = {
    'bit_depth_m': 'bit_depth_m',
    'hole_depth_m': 'hole_depth_m',
    'bit_on_bottom': 'on_bottom',
    'bit_axial_velocity_m_per_s': 'bit_axial_velocity_m_per_s',
    'rop_m_per_s': 'rop_m_per_s',
    'bit_angle_rad': 'angle_rad',
    'bit_speed_rad_per_s': 'speed_rad_per_s',
    'weight_on_bit_n': 'weight_on_bit_n',
    'torque_on_bit_nm': 'torque_on_bit_nm',
    'depth_of_cut_m_per_rad': 'depth_of_cut_m_per_rad',
    'bit_lifted_off': 'lifted',
    'top_torque_nm': 'top_torque_nm',
    'hook_position_m': 'hook_position_m',
    'impacts_so_far': 'impacts_so_far',
    'lift_offs_so_far': 'lift_offs_so_far',
    'landings_so_far': 'landings_so_far',
}
SHARED_CHANNELS = {'top_speed_rad_per_s': 'top_speed_rad_per_s', 'hook_load_n': 'hook_load_n'}
"""Channels shared by the members: name -> Observation attribute (the state's, by the same
name)."""
STATION_FIELDS = ('axial', 'v', 'w')


@dataclass
class SimulationResult:
    """
    A recorded run of m members.

    time_s: (n_t,). channels: name -> (m, n_t) (see BIT_CHANNELS, plus 'contact_nodes' and
    'max_contact_force_n'); shared: name -> (n_t,); stations_m: (n_s,);
    station_displacement_m, station_velocity_m_per_s, station_acceleration_m_per_s2:
    (m, n_s, 3, n_t) for (axial, v, w); station_spin_rate_rad_per_s: (m, n_s, 3, n_t) for
    (theta_x', theta_y', theta_z'); impact_count, lift_off_count: (m,) episodes
    (Simulator.impact_count);
    time_step_s, steps, iterations, wall_time_s; retries: member-steps integrated again on
    sub-steps (Simulator.retries).
    """

    time_s: np.ndarray
    channels: dict
    shared: dict
    stations_m: np.ndarray
    station_displacement_m: np.ndarray
    station_velocity_m_per_s: np.ndarray
    station_acceleration_m_per_s2: np.ndarray
    station_spin_rate_rad_per_s: np.ndarray
    impact_count: np.ndarray
    lift_off_count: np.ndarray
    time_step_s: float
    steps: int = 0
    iterations: int = 0
    wall_time_s: float = 0.0
    metadata: dict = field(default_factory=dict)
    retries: int = 0

    @property
    def members(self) -> int:
        return self.channels['rop_m_per_s'].shape[0]

    @property
    def real_time_factor(self) -> float:
        """Simulated seconds per wall-clock second."""
        simulated = self.steps * self.time_step_s
        return simulated / self.wall_time_s if self.wall_time_s > 0 else float('inf')

    def radial_displacement_m(self) -> np.ndarray:
        """sqrt(v^2 + w^2) at every station, (m, n_s, n_t)."""
        d = self.station_displacement_m
        return np.hypot(d[:, :, 1], d[:, :, 2])

    def window(self, seconds: float) -> np.ndarray:
        """Boolean mask of the last ``seconds`` of the record."""
        return self.time_s >= self.time_s[-1] - seconds - 1e-9


class History:
    """
    Preallocated recorder of observations for ``n_records`` samples.

    Recorded time first (a sample is one contiguous row of each buffer: a quarter of the cost
    of a strided column), handed out time last by :meth:`result`. The buffers are an
    :class:`~drill_twin.integrator.observed_bit.ObservedArrays` with a record per sample:
    :meth:`record_simulator` has the simulator observe straight into them (one compiled
    call), :meth:`record` copies an :class:`Observation` there.
    """

    def __init__(self, members: int, n_stations: int, n_records: int, time_step_s: float,
                 stations_m):
        self.count = 0
        self.time_step_s = time_step_s
        self.time_s = np.zeros(n_records)
        self.observed = ObservedArrays(n_records, members, n_stations, fill=np.zeros)
        floats, flags = self.observed.floats, self.observed.flags
        self._channels = {
            name: (flags[FLAG_RECORDS.index(attribute)] if attribute in FLAG_RECORDS
                   else floats[FLOAT_RECORDS.index(attribute)])
            for name, attribute in BIT_CHANNELS.items()}
        self._channels['contact_nodes'] = self.observed.touching_nodes
        self._channels['max_contact_force_n'] = floats[MAX_CONTACT_FORCE]
        self._shared = {name: np.zeros(n_records) for name in SHARED_CHANNELS}
        self._shared_copied = [(self._shared[name], attribute)
                               for name, attribute in SHARED_CHANNELS.items()]
        self._copied = [(self._channels[name], attribute)
                        for name, attribute in BIT_CHANNELS.items()] + self._shared_copied
        self.stations_m = np.asarray(stations_m, dtype=float)
        self._stations = dict(zip(STATION_RECORDS, self.observed.stations))

    def record(self, observation: Observation) -> None:
        """Record an observation (from any source) as the next sample."""
        k = self.count
        self.time_s[k] = observation.time_s
        for buffer, attribute in self._copied:
            buffer[k] = getattr(observation, attribute)
        self._channels['contact_nodes'][k] = observation.in_contact.sum(axis=1)
        self._channels['max_contact_force_n'][k] = observation.contact_force_n.max(axis=1)
        for name, buffer in self._stations.items():
            buffer[k] = getattr(observation, name)
        self.count += 1

    def record_simulator(self, simulator) -> None:
        """
        Record the simulator's observation now as the next sample.

        What :meth:`record` of its ``observe()`` records, written in one compiled call.
        """
        k = self.count
        state = simulator.state
        self.time_s[k] = state.time_s
        simulator.observe_into(self.observed, k)
        for buffer, attribute in self._shared_copied:
            buffer[k] = getattr(state, attribute)
        self.count += 1

    def result(self, impact_count, lift_off_count, steps, iterations, wall_time_s,
               metadata=None, retries: int = 0) -> SimulationResult:
        n = self.count

        def stations(name):
            return np.ascontiguousarray(np.moveaxis(self._stations[name][:n], 0, -1))

        return SimulationResult(
            time_s=self.time_s[:n].copy(),
            channels={k: np.ascontiguousarray(v[:n].T) for k, v in self._channels.items()},
            shared={k: v[:n].copy() for k, v in self._shared.items()},
            stations_m=self.stations_m,
            station_displacement_m=stations('station_displacement_m'),
            station_velocity_m_per_s=stations('station_velocity_m_per_s'),
            station_acceleration_m_per_s2=stations('station_acceleration_m_per_s2'),
            station_spin_rate_rad_per_s=stations('station_spin_rate_rad_per_s'),
            impact_count=np.asarray(impact_count).copy(),
            lift_off_count=np.asarray(lift_off_count).copy(),
            time_step_s=self.time_step_s, steps=steps, iterations=iterations,
            wall_time_s=wall_time_s, metadata=dict(metadata or {}), retries=int(retries))
