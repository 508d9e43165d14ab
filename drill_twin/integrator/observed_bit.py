"""
An observation of the state, in one compiled pass, written into arrays with a record axis.

:meth:`Simulator.observe` and the offline recorder (:class:`~drill_twin.simulation.history.
History`) both call :func:`observe_into`: the observer's rows of q, q' and q'' (one product
each), the derived bit quantities (:func:`derive`), the bit's forces, the wall contact's
reductions, the events so far and the stations, written at record k of the arrays
:class:`ObservedArrays` holds. ``observe`` hands out views of a one-record set; the recorder
has it write straight into its buffers. One compiled call costs about 19 us for the mean
model (thirty small numpy operations cost three times that once a step has evicted numpy's
working set from the cache).

The torque the string takes at its top is :func:`string_torque_nm`, the torque balance of
the whole string; :func:`derive` compiles it in, and the rig's dynamic top drive measures with
it too (:meth:`~drill_twin.integrator.observation.ObserverRows.string_torque_nm`).
"""
from __future__ import annotations

import numpy as np

from drill_twin.model.bit_rock import maximum
from drill_twin.numerics.compiled import inline, kernel
from drill_twin.integrator.newmark_kernel import on_rock

DERIVED = ('depth_m', 'rop_m_per_s', 'angle_rad', 'depth_of_cut_m_per_rad', 'hole_depth_m',
           'top_torque_nm')
"""Rows of :func:`derive`'s ``derived`` array, in order."""

FLOAT_RECORDS = ('bit_depth_m', 'hole_depth_m', 'rop_m_per_s', 'angle_rad',
                 'depth_of_cut_m_per_rad', 'top_torque_nm', 'bit_axial_velocity_m_per_s',
                 'speed_rad_per_s', 'weight_on_bit_n', 'torque_on_bit_nm', 'hook_position_m',
                 'hook_velocity_m_per_s', 'impacts_so_far', 'lift_offs_so_far',
                 'landings_so_far', 'max_contact_force_n')
"""Rows of :class:`ObservedArrays`'s ``floats``: Observation attributes by name, but the last
(the largest radial wall force over the nodes, N), per member."""
(BIT_DEPTH, HOLE_DEPTH, ROP, ANGLE, DEPTH_OF_CUT, TOP_TORQUE, AXIAL_VELOCITY, SPEED, WOB, TOB,
 HOOK_POSITION, HOOK_VELOCITY, IMPACTS, LIFT_OFFS, LANDINGS, MAX_CONTACT_FORCE) = range(16)
FLAG_RECORDS = ('on_bottom', 'lifted')
"""Rows of :class:`ObservedArrays`'s ``flags`` (Observation attributes)."""
ON_BOTTOM, LIFTED = range(2)
STATION_RECORDS = ('station_displacement_m', 'station_velocity_m_per_s',
                   'station_acceleration_m_per_s2', 'station_spin_rate_rad_per_s')
"""Rows of :class:`ObservedArrays`'s ``stations`` (Observation attributes)."""


def string_torque_nm(acceleration_mass, rate_damping, torsional_force):
    """
    Return T_s, the torque the string takes at its top (N m, > 0 when the drive drives it).

    The torque balance of the whole string about x (the rigid rotation costs no strain):
    T_s = (M psi) . (a + psi alpha) + (C psi) . (v + psi omega) - sum of the non-linear
    torsional forces. ``acceleration_mass`` = (M psi) . (a + psi alpha) (N m),
    ``rate_damping`` = (C psi) . (v + psi omega) (N m), ``torsional_force`` the sum of f_NL
    over the torsional DOFs (N m). Scalars; plain Python here, compiled into :func:`derive`.
    """
    return (acceleration_mass + rate_damping) - torsional_force


_string_torque = inline(string_torque_nm)


class ObservedArrays:
    """
    What :func:`observe_into` writes, for ``records`` records of m members.

    floats (F, records, m): FLOAT_RECORDS; flags (2, records, m): FLAG_RECORDS;
    touching_nodes (records, m): the nodes on the wall; stations (4, records, m, n_stations,
    3): STATION_RECORDS. The detailed quantities (top torque, hook, stations) are written for
    the first ``detailed`` members only.
    """

    def __init__(self, records: int, members: int, n_stations: int, fill=np.empty):
        self.floats = fill((len(FLOAT_RECORDS), records, members))
        self.flags = fill((len(FLAG_RECORDS), records, members), dtype=bool)
        self.touching_nodes = fill((records, members), dtype=np.int64)
        self.stations = fill((len(STATION_RECORDS), records, members, n_stations, 3))

    @property
    def arrays(self) -> tuple:
        """Return the arrays in :func:`observe_into`'s order."""
        return self.floats, self.flags, self.touching_nodes, self.stations


@kernel
def derive(q_rows, rate_rows, acceleration_rows, driven, top_speed, top_acceleration,
           full, torsion_start, torsion_stop, columns, velocity, omega, height, height_rate,
           hole, length_m, e, top_angle, derived, on_bottom):
    """
    Fill ``derived`` (6, m) (rows: DERIVED) and ``on_bottom`` (m,) of an observation.

    q_rows (m, k), rate_rows and acceleration_rows (d, k) for the d <= m detailed members:
    the observer's rows of q, q' and q'' (the driven rotation's rate and acceleration times
    ``driven`` (k,) are added to the latter two, in place); full (m, n_dofs): f_NL, whose
    torsional DOFs are torsion_start:torsion_stop; columns: (mass, damping, bit_u, bit_angle)
    the observer's columns of the torque balance and the bit; velocity, omega: the bit's
    axial velocity and spin (m/s, rad/s), height and height_rate: the rock's surface under the
    bit below the hole's mean bottom (m, m/s), hole: the hole as the bit's axial displacement
    (m), each (m,); length_m: the string's length; e: the law's regularisation (rad/s);
    top_angle (rad). The top torque (row 5) only for the detailed members.
    """
    detailed, k = rate_rows.shape
    mass, damping, bit_u_column, bit_angle_column = columns[0], columns[1], columns[2], columns[3]
    for i in range(detailed):
        for j in range(k):
            rate_rows[i, j] += top_speed * driven[j]
            acceleration_rows[i, j] += top_acceleration * driven[j]
        string = 0.0
        for j in range(torsion_start, torsion_stop):
            string += full[i, j]
        derived[5, i] = _string_torque(acceleration_rows[i, mass], rate_rows[i, damping],
                                       string)
    for i in range(q_rows.shape[0]):
        bit_u = q_rows[i, bit_u_column]
        derived[0, i] = length_m + bit_u
        on = on_rock(bit_u, hole[i], height[i])
        on_bottom[i] = on
        rop = maximum(velocity[i] - height_rate[i], 0.0) if on else 0.0
        derived[1, i] = rop
        derived[2, i] = top_angle + q_rows[i, bit_angle_column]
        derived[3, i] = rop * omega[i] / (omega[i] * omega[i] + e * e)
        derived[4, i] = length_m + hole[i]


@kernel
def observe_into(k, q, rate, acceleration, detailed, operator, hook, fields_start, spins_start,
                 driven, top_speed, top_acceleration, full, torsion_start, torsion_stop,
                 columns, velocity, omega, lifted, wob, tob, height, height_rate, hole,
                 has_hole, length_m, e, top_angle, radial_force, in_contact, impacts,
                 lift_offs, landings, floats, flags, touching_nodes, stations):
    """
    Write an observation at record ``k`` of (floats, flags, touching_nodes, stations).

    The :class:`ObservedArrays` layout. q, rate, acceleration (m, n) the state, operator (n,
    c) the observer's rows (``ObserverRows``: hook column, stations' fields from
    fields_start and spins from spins_start, station-major), detailed <= m the members whose
    top torque, hook and stations are observed; the rest as :func:`derive`'s arguments, but
    hole (m,) (the hole bottom as the bit's axial displacement, used when has_hole, else the
    bit's own); lifted, wob, tob (m,) the bit's; radial_force (m, n_nodes), in_contact the
    wall's; impacts, lift_offs, landings (m,) the events so far.
    """
    members = q.shape[0]
    q_rows = np.dot(q, operator)
    rate_rows = np.dot(rate[:detailed], operator)
    acceleration_rows = np.dot(acceleration[:detailed], operator)
    bit = hole if has_hole else q_rows[:, columns[2]].copy()
    derived = np.empty((6, members))
    on_bottom = np.empty(members, dtype=np.bool_)
    derive(q_rows, rate_rows, acceleration_rows, driven, top_speed, top_acceleration, full,
           torsion_start, torsion_stop, columns, velocity, omega, height, height_rate, bit,
           length_m, e, top_angle, derived, on_bottom)
    for i in range(members):
        floats[BIT_DEPTH, k, i] = derived[0, i]
        floats[HOLE_DEPTH, k, i] = derived[4, i]
        floats[ROP, k, i] = derived[1, i]
        floats[ANGLE, k, i] = derived[2, i]
        floats[DEPTH_OF_CUT, k, i] = derived[3, i]
        floats[AXIAL_VELOCITY, k, i] = velocity[i]
        floats[SPEED, k, i] = omega[i]
        floats[WOB, k, i] = wob[i]
        floats[TOB, k, i] = tob[i]
        floats[IMPACTS, k, i] = impacts[i]
        floats[LIFT_OFFS, k, i] = lift_offs[i]
        floats[LANDINGS, k, i] = landings[i]
        floats[MAX_CONTACT_FORCE, k, i] = np.max(radial_force[i])
        touching_nodes[k, i] = np.sum(in_contact[i])
        flags[ON_BOTTOM, k, i] = on_bottom[i]
        flags[LIFTED, k, i] = lifted[i]
    n_stations = stations.shape[3]
    for i in range(detailed):
        floats[TOP_TORQUE, k, i] = derived[5, i]
        floats[HOOK_POSITION, k, i] = q_rows[i, hook]
        floats[HOOK_VELOCITY, k, i] = rate_rows[i, hook]
        for station in range(n_stations):
            for c in range(3):
                field = fields_start + 3 * station + c
                stations[0, k, i, station, c] = q_rows[i, field]
                stations[1, k, i, station, c] = rate_rows[i, field]
                stations[2, k, i, station, c] = acceleration_rows[i, field]
                stations[3, k, i, station, c] = rate_rows[i, spins_start + 3 * station + c]
