"""The rig's inputs: the set point (operation), the top drive and the drawworks."""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Literal

from drill_twin.config.bounds import (
    BLOCK_SPEED_MAX_M_PER_S, BLOCK_SPEED_REASON, DRIVE_GAIN_MAX, DRIVE_GAIN_REASON,
    DRIVE_INERTIA_MAX_KG_M2, DRIVE_INERTIA_REASON, DRIVE_TORQUE_MAX_NM, DRIVE_TORQUE_REASON,
    HOOK_LOAD_MAX_N, HOOK_LOAD_REASON, LINE_STIFFNESS_MAX_N_PER_M, LINE_STIFFNESS_REASON,
    TOP_DRIVE_ACCELERATION_MAX_RAD_PER_S2, TOP_DRIVE_ACCELERATION_REASON,
    TOP_DRIVE_SPEED_MAX_HZ, TOP_DRIVE_SPEED_REASON, WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON)
from drill_twin.config.checks import at_most, ConfigValueError, non_negative, positive

TopDriveMode = Literal['kinematic', 'dynamic']
DriveController = Literal['stiff', 'soft_torque', 'impedance']
DrawworksMode = Literal['hook_load', 'block_velocity', 'autodriller']


@dataclass(frozen=True, slots=True, kw_only=True)
class Operation:
    """The rig's set point: top-drive speed and hook load."""

    top_drive_speed_hz: float
    top_drive_acceleration_rad_per_s2: float
    """How fast the top-drive speed follows a new command."""
    hook_load_n: float | None = None
    """None: the hook load of the prestressed state, so that the mean WOB is the static one."""

    def __post_init__(self):
        if not math.isfinite(self.top_drive_speed_hz):
            raise ConfigValueError('top_drive_speed_hz', 'must be finite')
        at_most(self, 'top_drive_speed_hz', TOP_DRIVE_SPEED_MAX_HZ, TOP_DRIVE_SPEED_REASON)
        positive(self, 'top_drive_acceleration_rad_per_s2')
        at_most(self, 'top_drive_acceleration_rad_per_s2', TOP_DRIVE_ACCELERATION_MAX_RAD_PER_S2,
                TOP_DRIVE_ACCELERATION_REASON)
        if self.hook_load_n is not None:
            if not math.isfinite(self.hook_load_n):
                raise ConfigValueError('hook_load_n', 'must be finite or null')
            if self.hook_load_n < 0:
                raise ConfigValueError('hook_load_n', f'must be >= 0 (a hook can only pull), '
                                                      f'got {self.hook_load_n:g}')
            at_most(self, 'hook_load_n', HOOK_LOAD_MAX_N, HOOK_LOAD_REASON)

    @property
    def top_drive_speed_rad_per_s(self) -> float:
        """Omega_x in rad/s."""
        return 2.0 * math.pi * self.top_drive_speed_hz


@dataclass(frozen=True, slots=True, kw_only=True)
class TopDrive:
    """
    The top drive (docs/DRIVES.md).

    ``kinematic``: the paper's imposed speed (the string's top rotation follows the command at
    ``operation.top_drive_acceleration_rad_per_s2``); ``dynamic``: a rotor of ``inertia_kg_m2``
    (referred to the main shaft through the gearbox) under a PI speed controller whose motor
    torque is limited to ``torque_limit_nm``, driving the string's top, with the speed set-point
    shaped by ``controller``.

    ``impedance_nm_s_per_rad`` (N m s/rad) is derived from the string unless given: for
    ``impedance`` the top pipe's characteristic impedance zeta = I_p sqrt(rho k_s G), for
    ``soft_torque`` k_t / omega_1 (torsional stiffness over first torsional frequency).
    """

    mode: TopDriveMode = 'kinematic'
    inertia_kg_m2: float = 2000.0
    proportional_gain_nm_s_per_rad: float = 2.0e5
    integral_gain_nm_per_rad: float = 2.0e5
    torque_limit_nm: float = 80.0e3
    controller: DriveController = 'stiff'
    impedance_nm_s_per_rad: float | None = None
    """None: derived from the string (see the class docstring)."""
    soft_torque_corner_fraction: float = 0.5
    """soft_torque: high-pass corner of the torque feedback as a fraction of the first
    torsional frequency of the string (fixed top)."""
    mean_torque_time_constant_s: float = 10.0
    """impedance: the slowly varying mean torque (a first-order low-pass) that the speed
    set-point does not respond to, so the mean speed stays at the command."""

    def __post_init__(self):
        positive(self, 'inertia_kg_m2', 'torque_limit_nm', 'soft_torque_corner_fraction',
                 'mean_torque_time_constant_s')
        non_negative(self, 'proportional_gain_nm_s_per_rad', 'integral_gain_nm_per_rad')
        at_most(self, 'inertia_kg_m2', DRIVE_INERTIA_MAX_KG_M2, DRIVE_INERTIA_REASON)
        at_most(self, 'proportional_gain_nm_s_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)
        at_most(self, 'integral_gain_nm_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)
        at_most(self, 'torque_limit_nm', DRIVE_TORQUE_MAX_NM, DRIVE_TORQUE_REASON)
        if self.impedance_nm_s_per_rad is not None:
            positive(self, 'impedance_nm_s_per_rad')
            at_most(self, 'impedance_nm_s_per_rad', DRIVE_GAIN_MAX, DRIVE_GAIN_REASON)


@dataclass(frozen=True, slots=True, kw_only=True)
class Drawworks:
    """
    The axial input (docs/DRIVES.md).

    ``hook_load``: the paper's hook force (``operation.hook_load_n``); ``block_velocity``: the
    travelling block moves at ``block_velocity_m_per_s`` (down > 0) and holds the top through a
    drill line of ``line_stiffness_n_per_m`` and ``line_damping_n_s_per_m``, the hook load is
    measured; ``autodriller``: the block velocity regulated (PI) to hold
    ``weight_on_bit_setpoint_n`` (> 0, compression). In either the block's velocity changes at
    most at ``block_acceleration_max_m_per_s2`` (the drum's motor and brake).
    """

    mode: DrawworksMode = 'hook_load'
    block_velocity_m_per_s: float = 0.0
    block_acceleration_max_m_per_s2: float = 0.2
    line_stiffness_n_per_m: float = 2.0e7
    line_damping_n_s_per_m: float = 2.0e5
    block_speed_max_m_per_s: float | None = 1.0
    """The fastest the drum moves the block (m/s): in ``hook_load`` mode the brake holds the
    top's axial speed to it (rig/drawworks.HookBrake). None: the paper's bare hook force."""
    weight_on_bit_setpoint_n: float = 100.0e3
    autodriller_proportional_m_per_s_per_n: float = 1.0e-7
    autodriller_integral_m_per_s2_per_n: float = 5.0e-9
    autodriller_feed_rate_max_m_per_s: float = 0.02
    """The autodriller's ROP limit (m/s; 0.02 = 72 m/h, above the law's steady ROP over the
    envelope, 64 m/h at 30 rad/s and 300 kN): it never feeds line faster, and its integral is
    held within [0, this] (anti-windup)."""

    def __post_init__(self):
        if not math.isfinite(self.block_velocity_m_per_s):
            raise ConfigValueError('block_velocity_m_per_s', 'must be finite')
        at_most(self, 'block_velocity_m_per_s', BLOCK_SPEED_MAX_M_PER_S, BLOCK_SPEED_REASON)
        positive(self, 'line_stiffness_n_per_m', 'block_acceleration_max_m_per_s2',
                 'autodriller_feed_rate_max_m_per_s')
        at_most(self, 'autodriller_feed_rate_max_m_per_s', BLOCK_SPEED_MAX_M_PER_S,
                BLOCK_SPEED_REASON)
        if self.block_speed_max_m_per_s is not None:
            positive(self, 'block_speed_max_m_per_s')
        non_negative(self, 'line_damping_n_s_per_m', 'weight_on_bit_setpoint_n',
                     'autodriller_proportional_m_per_s_per_n',
                     'autodriller_integral_m_per_s2_per_n')
        at_most(self, 'line_stiffness_n_per_m', LINE_STIFFNESS_MAX_N_PER_M,
                LINE_STIFFNESS_REASON)
        at_most(self, 'weight_on_bit_setpoint_n', WEIGHT_ON_BIT_MAX_N, WEIGHT_ON_BIT_REASON)
