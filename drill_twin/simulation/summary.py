"""The JSON summary of a run over its stationary window."""
from __future__ import annotations

from drill_twin.analysis import kpi
from drill_twin.simulation.history import SimulationResult


def summarize(result: SimulationResult, window_s: float, bit_diameter_m: float,
              member: int = 0) -> dict:
    """Statistics of the last ``window_s`` seconds (docs/OUTPUTS.md, "--summary FILE.json")."""
    mask = result.window(window_s)
    ch = result.channels
    window = float(result.time_s[mask][-1] - result.time_s[mask][0])

    def series(name):
        return ch[name][member, mask]

    impacts = _events_in_window(series('impacts_so_far'))
    lift_offs = _events_in_window(series('lift_offs_so_far'))
    return {
        'window_s': window,
        'rop_m_per_s': kpi.describe(series('rop_m_per_s')),
        'bit_speed_rad_per_s': kpi.describe(series('bit_speed_rad_per_s')),
        'weight_on_bit_n': kpi.describe(series('weight_on_bit_n')),
        'torque_on_bit_nm': kpi.describe(series('torque_on_bit_nm')),
        'stick_slip_severity': float(kpi.stick_slip_severity(series('bit_speed_rad_per_s'))),
        'mse_pa': float(kpi.mechanical_specific_energy(
            series('weight_on_bit_n'), series('torque_on_bit_nm'),
            series('bit_speed_rad_per_s'), series('rop_m_per_s'), bit_diameter_m)),
        'impact_count': impacts,
        'lift_off_count': lift_offs,
        'impact_rate_per_s': _rate(impacts, window),
        'lift_off_rate_per_s': _rate(lift_offs, window),
        'landing_count': _events_in_window(series('landings_so_far')),
        'impact_count_whole_run': int(result.impact_count[member]),
        'lift_off_count_whole_run': int(result.lift_off_count[member]),
        'retries_whole_run': int(result.retries),
        'real_time_factor': float(result.real_time_factor),
        'time_step_s': float(result.time_step_s),
    }


def _events_in_window(running_count) -> int:
    """Events (episodes: integrator/contact_events.py) that started inside the window."""
    return int(running_count[-1] - running_count[0])


def _rate(count: int, window_s: float) -> float:
    """Events per second in the window (0 for a window of one sample)."""
    return float(count / window_s) if window_s > 0 else 0.0
