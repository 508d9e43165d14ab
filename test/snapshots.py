"""Twin snapshots made by hand (closed-form signals), for the live view and console tests."""
import math

import numpy as np

from drill_twin.integrator.simulator import Observation
from drill_twin.twin.engine import BitState, TwinSnapshot
from drill_twin.integrator.stepping import TwinEvent

N_NODES = 57


def snapshot(t: float, *, stations: int = 2, events=(), depth0: float = 1600.0,
             ensemble: bool = True, ensemble_lag_s: float = 0.01) -> TwinSnapshot:
    """
    Return the twin at time t (s).

    Bit speed 5 + 4 sin(t) rad/s, ROP 2 mm/s, WOB -100 kN, TOB -3 kN m, station k at (v, w) =
    (0.01 (k + 1) cos t, 0.01 (k + 1) sin t) m, node 10 on the wall with 2.5 kN.
    """
    speed = 5.0 + 4.0 * math.sin(t)
    bit = BitState(depth0 + 2e-3 * t, 2e-3, -1e5, 5.0 * t, speed, -3e3)
    displacement = np.zeros((1, stations, 3))
    for k in range(stations):
        displacement[0, k] = (0.0, 0.01 * (k + 1) * math.cos(t), 0.01 * (k + 1) * math.sin(t))
    forces = np.zeros((1, N_NODES))
    forces[0, 10] = 2500.0
    one = np.ones(1)
    observation = Observation(
        time_s=t, depth_m=one * bit.depth_m, rop_m_per_s=one * 2e-3, angle_rad=one * 5 * t,
        speed_rad_per_s=one * speed, weight_on_bit_n=one * -1e5, torque_on_bit_nm=one * -3e3,
        depth_of_cut_m_per_rad=one * 4e-4, lifted=np.zeros(1, bool), top_torque_nm=one * 4e3,
        top_speed_rad_per_s=5.0, top_angle_rad=5.0 * t, hook_load_n=1.1e6,
        hook_position_m=one * 2e-3 * t, hook_velocity_m_per_s=one * 2e-3,
        station_displacement_m=displacement, station_velocity_m_per_s=np.zeros_like(displacement),
        station_acceleration_m_per_s2=np.zeros_like(displacement),
        station_spin_rate_rad_per_s=np.zeros_like(displacement), contact_force_n=forces,
        in_contact=forces > 0, impacts_so_far=np.zeros(1, int),
        lift_offs_so_far=np.zeros(1, int))
    mean = lower = upper = step = ensemble_t = None
    if ensemble:
        ensemble_t = max(t - ensemble_lag_s, 0.0)
        mean = BitState(bit.depth_m, 2e-3, -1e5, 5.0 * t, speed, -3e3)
        lower = BitState(bit.depth_m, 1.8e-3, -1.1e5, 5.0 * t, 0.9 * speed, -3.3e3)
        upper = BitState(bit.depth_m, 2.2e-3, -0.9e5, 5.0 * t, 1.1 * speed, -2.7e3)
        step = int(round(ensemble_t / 0.01))
    return TwinSnapshot(
        time_s=t, step=int(round(t / 0.01)), bit=bit, ensemble_mean=mean, ensemble_lower=lower,
        ensemble_upper=upper, ensemble_step=step, ensemble_time_s=ensemble_t,
        observation=observation, stick_slip_severity=0.8, mse_pa=1.5e8, rop_m_per_h=7.2,
        events=tuple(events),
        health={'members': 5, 'tick_wall_time_s': 2e-3, 'tick_wall_time_max_s': 5e-3,
                'iterations_per_step': 2.0, 'ensemble_iterations_per_step': 2.5, 'resets': 0,
                'rejected_commands': 0, 'ensemble_members_touching_wall': 0,
                'ensemble_members_lifted_off': 0})


def impact(t: float) -> TwinEvent:
    return TwinEvent('impact', 'warn', t,
                     f'borehole impact at x = 700.0 m, force 2.5e+03 N',  # noqa: F541
                     {'x_m': '700.000'})
