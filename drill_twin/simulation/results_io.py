"""
Result files that numpy and pandas users open directly: CSV and NPZ with named columns.

One row per recorded instant of one member. Column names carry their units; COLUMNS
describes each (docs/OUTPUTS.md prints the same table). Station columns are named after the
station, e.g. ``x700m_v_m`` for the lateral displacement v at x = 700 m.
"""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from drill_twin.interface import station_name
from drill_twin.simulation.history import SimulationResult

COLUMNS = {
    'time_s': 'simulated time (s)',
    'bit_depth_m': 'bit position along the string, down from the top\'s initial position (m)',
    'hole_depth_m': ('depth of the hole bottom (same reference), the rock\'s undeformed surface: '
                     'the deepest the bit has been less the depth WOB / k by which it presses '
                     'the rock (m)'),
    'bit_on_bottom': ('1 when the bit is on the hole bottom (less than 1 um above it, or '
                      'pressing the rock), 0 off bottom'),
    'rop_m_per_s': 'rate of penetration: the rate the hole deepens, 0 off bottom (m/s)',
    'bit_axial_velocity_m_per_s': 'axial velocity of the bit, du_bit/dt, > 0 down (m/s)',
    'bit_angle_rad': 'bit rotation angle (rad)',
    'bit_speed_rad_per_s': 'bit rotation speed (rad/s)',
    'weight_on_bit_n': 'axial force of the rock on the bit, f_bit; negative = compression (N)',
    'torque_on_bit_nm': 'torque of the rock on the bit, t_bit; negative = resisting (N m)',
    'depth_of_cut_m_per_rad': 'regularised depth of cut ROP omega / (omega^2 + e^2) (m/rad)',
    'bit_lifted_off': '1 when the rock does not push on the bit (off bottom, or it would pull)',
    'top_torque_nm': 'torque the top drive applies to the string (N m)',
    'top_speed_rad_per_s': 'top-drive rotation speed (rad/s)',
    'hook_load_n': 'hook load applied at the top (N)',
    'hook_position_m': 'axial displacement of the top from the prestressed state (m)',
    'contact_nodes': 'number of nodes touching the borehole wall',
    'max_contact_force_n': 'largest radial wall force over the nodes (N)',
    'impacts_so_far': 'borehole impacts (wall-contact episodes, all nodes) since the start',
    'lift_offs_so_far': 'bit lift-off episodes since the start',
    'landings_so_far': 'landings of the bit on the hole bottom since the start',
}
STATION_COLUMNS = {
    'u_m': 'axial displacement (m)', 'v_m': 'lateral displacement v, along y (m)',
    'w_m': 'lateral displacement w, along z (m)', 'radial_m': 'radial position sqrt(v^2+w^2) (m)',
    'v_rate_m_per_s': 'lateral velocity dv/dt (m/s)',
    'w_rate_m_per_s': 'lateral velocity dw/dt (m/s)',
    'v_acceleration_m_per_s2': 'lateral acceleration (m/s^2)',
    'w_acceleration_m_per_s2': 'lateral acceleration (m/s^2)',
    'axial_acceleration_m_per_s2': 'axial acceleration (m/s^2)',
    'spin_rate_rad_per_s': 'rotation speed of the section about x (rad/s)',
}


def columns(result: SimulationResult, member: int = 0) -> dict[str, np.ndarray]:
    """Ordered name -> 1-D array of one member's record."""
    out = {'time_s': result.time_s}
    for name in COLUMNS:
        if name == 'time_s':
            continue
        source = result.shared.get(name)
        if source is None:
            source = result.channels[name][member]
        out[name] = source.astype(float) if source.dtype == bool else source
    d = result.station_displacement_m[member]
    v = result.station_velocity_m_per_s[member]
    a = result.station_acceleration_m_per_s2[member]
    spin = result.station_spin_rate_rad_per_s[member]
    for s, x in enumerate(result.stations_m):
        prefix = station_name(x)
        out[f'{prefix}_u_m'] = d[s, 0]
        out[f'{prefix}_v_m'] = d[s, 1]
        out[f'{prefix}_w_m'] = d[s, 2]
        out[f'{prefix}_radial_m'] = np.hypot(d[s, 1], d[s, 2])
        out[f'{prefix}_v_rate_m_per_s'] = v[s, 1]
        out[f'{prefix}_w_rate_m_per_s'] = v[s, 2]
        out[f'{prefix}_v_acceleration_m_per_s2'] = a[s, 1]
        out[f'{prefix}_w_acceleration_m_per_s2'] = a[s, 2]
        out[f'{prefix}_axial_acceleration_m_per_s2'] = a[s, 0]
        out[f'{prefix}_spin_rate_rad_per_s'] = spin[s, 0]
    return out


def write_results(result: SimulationResult, path: str | Path, member: int = 0,
                  metadata: dict | None = None) -> Path:
    """
    Write one member's record as ``.csv`` or ``.npz``; the extension chooses.

    ``.csv`` with a header row, ``.npz`` with named arrays plus a ``metadata`` JSON string.
    """
    path = Path(path)
    data = columns(result, member)
    if path.suffix == '.csv':
        table = np.column_stack(list(data.values()))
        np.savetxt(path, table, delimiter=',', header=','.join(data), comments='', fmt='%.9g')
    elif path.suffix == '.npz':
        np.savez_compressed(path, metadata=json.dumps(metadata or {}), **data)
    else:
        raise ValueError(f'{path}: unknown result format {path.suffix!r} (use .csv or .npz)')
    return path
