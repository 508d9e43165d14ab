"""
What an observer measures after a step: :class:`Observation`, and the rows it reads them with.

:class:`ObserverRows` holds the observer's rows on the reduced coordinates (the hook, the
stations, the torque balance of the whole string, the bit), built once per reduced system;
:meth:`~drill_twin.integrator.simulator.Simulator.observe` reads the state with them in one
compiled pass (:mod:`~drill_twin.integrator.observed_bit`), and
:meth:`ObserverRows.string_torque_nm` reads the torque the string takes at its top for one
member with the same rows and the same balance (the rig's dynamic top drive measures it so).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from drill_twin.integrator import observed_bit


@dataclass(frozen=True)
class Observation:
    """
    What the rig and the sensors see after a step, per member (arrays of shape (m,)).

    Bit: depth_m (measured along the string, down from the top's initial position; the same
    as bit_depth_m), rop_m_per_s (the rate the hole deepens: the bit's axial velocity while
    it cuts on bottom, 0 otherwise), angle_rad, speed_rad_per_s, weight_on_bit_n (f_bit, < 0
    in compression), torque_on_bit_nm (t_bit), depth_of_cut_m_per_rad (regularised, ROP
    omega / (omega^2 + e^2)), lifted (no axial force of the rock on the bit: off bottom, or
    touching it without load). Hole: bit_depth_m, hole_depth_m (the deepest the bit has been,
    same reference; never decreases), on_bottom (the bit within 1 um of the hole bottom),
    bit_axial_velocity_m_per_s (du_bit/dt, < 0 moving up). Top: top_torque_nm (the torque
    the top drive applies, > 0 when driving), top_speed_rad_per_s, top_angle_rad (shared),
    hook_load_n (shared, or (m,) per member), hook_position_m, hook_velocity_m_per_s (the
    top's axial displacement and velocity). Stations (m, n_stations, 3) for the fields (u, v, w):
    station_displacement_m, station_velocity_m_per_s, station_acceleration_m_per_s2;
    station_spin_rate_rad_per_s (m, n_stations, 3) for
    (theta_x', theta_y', theta_z'). Wall: contact_force_n (m, n_nodes) radial force,
    in_contact (m, n_nodes). Events since the start: impacts_so_far (wall-contact episodes
    over all nodes: one per episode, not per step touching, integrator/contact_events.py),
    lift_offs_so_far (lift-off episodes of the bit) and landings_so_far (the bit tags the hole
    bottom after being off bottom), (m,).
    """

    time_s: float
    depth_m: np.ndarray
    rop_m_per_s: np.ndarray
    angle_rad: np.ndarray
    speed_rad_per_s: np.ndarray
    weight_on_bit_n: np.ndarray
    torque_on_bit_nm: np.ndarray
    depth_of_cut_m_per_rad: np.ndarray
    lifted: np.ndarray
    top_torque_nm: np.ndarray
    top_speed_rad_per_s: float
    top_angle_rad: float
    hook_load_n: float | np.ndarray
    hook_position_m: np.ndarray
    hook_velocity_m_per_s: np.ndarray
    station_displacement_m: np.ndarray
    station_velocity_m_per_s: np.ndarray
    station_acceleration_m_per_s2: np.ndarray
    station_spin_rate_rad_per_s: np.ndarray
    contact_force_n: np.ndarray
    in_contact: np.ndarray
    impacts_so_far: np.ndarray
    lift_offs_so_far: np.ndarray
    bit_depth_m: np.ndarray | None = None
    hole_depth_m: np.ndarray | None = None
    on_bottom: np.ndarray | None = None
    bit_axial_velocity_m_per_s: np.ndarray | None = None
    landings_so_far: np.ndarray | None = None


def observation_of(arrays: observed_bit.ObservedArrays, keep: int, state,
                   forces, impacts: np.ndarray, lift_offs: np.ndarray,
                   landings: np.ndarray) -> Observation:
    """
    Return the :class:`Observation` in record 0 of ``arrays`` (views of its arrays).

    ``keep``: the detailed members; state, forces: the simulator's (the contact's arrays are
    the forces' own); impacts, lift_offs, landings (m,): the event counts (copied).
    """
    floats, flags, stations = arrays.floats[:, 0], arrays.flags[:, 0], arrays.stations[:, 0, :keep]
    depth = floats[observed_bit.BIT_DEPTH]
    return Observation(
        time_s=state.time_s,
        depth_m=depth,
        rop_m_per_s=floats[observed_bit.ROP],
        angle_rad=floats[observed_bit.ANGLE],
        speed_rad_per_s=floats[observed_bit.SPEED],
        weight_on_bit_n=floats[observed_bit.WOB],
        torque_on_bit_nm=floats[observed_bit.TOB],
        depth_of_cut_m_per_rad=floats[observed_bit.DEPTH_OF_CUT],
        lifted=flags[observed_bit.LIFTED],
        top_torque_nm=floats[observed_bit.TOP_TORQUE, :keep],
        top_speed_rad_per_s=state.top_speed_rad_per_s,
        top_angle_rad=state.top_angle_rad,
        hook_load_n=state.hook_load_n,
        hook_position_m=floats[observed_bit.HOOK_POSITION, :keep],
        hook_velocity_m_per_s=floats[observed_bit.HOOK_VELOCITY, :keep],
        station_displacement_m=stations[0],
        station_velocity_m_per_s=stations[1],
        station_acceleration_m_per_s2=stations[2],
        station_spin_rate_rad_per_s=stations[3],
        contact_force_n=forces.contact.radial_force_n,
        in_contact=forces.contact.in_contact,
        impacts_so_far=impacts.copy(),
        lift_offs_so_far=lift_offs.copy(),
        bit_depth_m=depth,
        hole_depth_m=floats[observed_bit.HOLE_DEPTH],
        on_bottom=flags[observed_bit.ON_BOTTOM],
        bit_axial_velocity_m_per_s=floats[observed_bit.AXIAL_VELOCITY],
        landings_so_far=landings.copy(),
    )


class ObserverRows:
    """
    What an observation measures, as rows on the reduced coordinates.

    A row r of the field-wise DOFs reads r . (Phi q) = (Phi^T r) . q, plus r . psi theta' for
    the rates and accelerations (the driven rotation moves the theta_x DOFs).

    Columns of ``q @ operator``: hook (the top's axial DOF), the stations' (u, v, w) (``fields``,
    station-major), their (theta_x, theta_y, theta_z) (``spins``), the torque balance's mass
    and damping rows, the bit's axial displacement and rotation. ``columns``: those last four
    (``observed_bit.derive``'s); ``torsion``: the torsional field's DOFs; ``no_hole``: the
    hole :func:`observed_bit.observe_into` is handed when the state has none.
    """

    def __init__(self, system):
        n_dofs = system.n_dofs
        rows = [np.eye(1, n_dofs, 0)[0]]                      # the hook: u at the top
        stations = system.stations
        rows += [station.rows[k] for station in stations for k in (0, 1, 2)]
        rows += [station.rows[k] for station in stations for k in (3, 4, 5)]
        rows += [system.driven_rows['mass'], system.driven_rows['damping']]
        physical = np.asarray(rows)                           # (k, n_dofs)
        bit = system.bit_node
        axial, torsion = system.blocks['axial'], system.blocks['torsional']
        reduced = system.physical(np.eye(system.size)) @ physical.T      # (n, k)
        bit_rows = np.zeros((system.size, 2))
        bit_rows[axial.columns, 0] = axial.shapes[bit]
        bit_rows[torsion.columns, 1] = torsion.shapes[bit]
        self.operator = np.ascontiguousarray(np.hstack([reduced, bit_rows]))
        count = 3 * len(stations)
        self.hook = 0
        self.fields = slice(1, 1 + count)
        self.spins = slice(1 + count, 1 + 2 * count)
        self.mass, self.damping = 1 + 2 * count, 2 + 2 * count
        self.bit_u, self.bit_angle = 3 + 2 * count, 4 + 2 * count
        self.driven = np.zeros(self.operator.shape[1])
        self.driven[:physical.shape[0]] = physical[:, system.field(1)].sum(axis=1)
        self.torsion = system.field(1)
        self.columns = np.array([self.mass, self.damping, self.bit_u, self.bit_angle],
                                dtype=np.int64)
        self.no_hole = np.empty(0)

    def string_torque_nm(self, state, forces, member: int = 0) -> float:
        """
        Return T_s, the torque the string takes at its top, of one member (N m, > 0 driving).

        The torque balance of the whole string (:func:`observed_bit.string_torque_nm`, as
        ``Observation.top_torque_nm``) on the state (BatchState) and its forces
        (ForceEvaluation).
        """
        mass, damping = self.mass, self.damping
        acceleration = (state.q_acceleration[member] @ self.operator[:, mass]
                        + state.top_acceleration_rad_per_s2 * self.driven[mass])
        rate = (state.q_rate[member] @ self.operator[:, damping]
                + state.top_speed_rad_per_s * self.driven[damping])
        return float(observed_bit.string_torque_nm(acceleration, rate,
                                                   np.sum(forces.full[member, self.torsion])))
