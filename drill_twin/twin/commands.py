"""
The operator's commands to the twin: checked, then handed to the mean model's rig.

A command is accepted only when it is a finite number (or one of the named choices) inside
the operator's limits (:class:`CommandLimits`) and the range the model can represent
(:class:`~drill_twin.integrator.envelope.StringEnvelope`); otherwise it raises
:class:`CommandRejected`, the previous command stays, and a 'command_rejected' event says
why. The mean model's :class:`~drill_twin.rig.rig.Rig` keeps every command, also those of a
mode not active yet (the controller and torque limit of a kinematic drive, the block velocity
and WOB set-point under the hook-load input), for when it becomes active. The ensemble turns
at the mean model's top speed and, axially, takes the hook load the mean model applies or,
with the drawworks, hangs every member's line from the mean model's block.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

from drill_twin.integrator.envelope import PLAUSIBLE_BLOCK_SPEED_M_PER_S
from drill_twin.integrator.stepping import TwinEvent
from drill_twin.rig.controllers import CONTROLLERS
from drill_twin.rig.drawworks import AxialMode
from drill_twin.rig.top_drive import TopDriveMode

TOP_DRIVE_MODES = (TopDriveMode.KINEMATIC.value, TopDriveMode.DYNAMIC.value)
"""The top-drive modes an operator can command."""
AXIAL_MODES = (AxialMode.HOOK_LOAD.value, AxialMode.BLOCK_VELOCITY.value,
               AxialMode.AUTODRILLER.value)
"""The axial modes an operator can command."""


class CommandRejected(ValueError):
    """A command that is not finite or outside its range; the previous one stays."""


@dataclass(frozen=True)
class CommandLimits:
    """
    The operator's command ranges (rad/s and N).

    A clamp on top of what the model can represent (the hook load's range derived from the
    string, :mod:`drill_twin.integrator.envelope`).
    """

    top_drive_speed_max_rad_per_s: float = 30.0
    hook_load_min_n: float = 0.0
    hook_load_max_n: float = 5.0e6
    top_drive_torque_limit_max_nm: float = 500.0e3


class CommandInput:
    """
    The command methods of :class:`~drill_twin.twin.engine.TwinEngine` (module docstring).

    The engine provides ``rig`` (the mean model's), ``limits`` (CommandLimits), ``envelope``
    (StringEnvelope), ``time_s``, the list ``_events`` and the counters ``commands_received``
    and ``rejected_commands``.
    """

    @property
    def top_drive_speed_command(self) -> float:
        """The top-drive speed command (rad/s)."""
        return self.rig.commands.top_speed_rad_per_s

    @property
    def hook_load_command(self):
        """The hook load command (N; in a drawworks mode what the line pulled last)."""
        return self.rig.commands.hook_load_n

    @property
    def top_drive_mode(self) -> str:
        """Return 'dynamic' or 'kinematic': the mean model's top drive now."""
        return self.rig.top_drive_mode.value

    @property
    def top_drive_controller(self) -> str:
        """Return the dynamic drive's controller (kept while the drive is kinematic)."""
        return self.rig.commands.controller

    @property
    def axial_mode(self) -> str:
        """Return the mean model's axial input now (hook_load, block_velocity, autodriller)."""
        return self.rig.axial_mode.value

    def set_top_drive_speed(self, rad_per_s: float) -> None:
        """Top-drive speed command (rad/s), applied from the next step; raises CommandRejected."""
        self._check('top-drive speed', rad_per_s, 0.0, self.limits.top_drive_speed_max_rad_per_s,
                    'rad/s')
        self.rig.set_top_drive_speed(float(rad_per_s))

    def set_hook_load(self, newton: float) -> None:
        """
        Set the hook load command (N), applied from the next step; raises CommandRejected.

        Accepted inside the operator's limits and the range the model can represent (the
        string's weight minus the largest WOB up to the weight plus the drag of a string
        rising at block speed, :class:`~drill_twin.integrator.envelope.StringEnvelope`).
        """
        self._check('hook load', newton, self.limits.hook_load_min_n,
                    self.limits.hook_load_max_n, 'N', self._hook_load_reason)
        self.rig.set_hook_load(float(newton))

    def _hook_load_reason(self, newton: float) -> str | None:
        if self.rig.axial_mode is not AxialMode.HOOK_LOAD:
            return (f'the hook load is what the drill line pulls in axial mode '
                    f'{self.axial_mode} (switch the axial mode to hook_load first)')
        return self.envelope.hook_load_reason(newton)

    def set_top_drive_mode(self, mode: str) -> None:
        """Switch the top drive, 'kinematic' or 'dynamic' (bumpless); raises CommandRejected."""
        self._check_choice('top-drive mode', mode, TOP_DRIVE_MODES)
        self.rig.set_top_drive_mode(mode)

    def set_top_drive_controller(self, controller: str) -> None:
        """
        Set the dynamic drive's controller: 'stiff', 'soft_torque' or 'impedance'.

        Kept for when the drive becomes dynamic; raises CommandRejected.
        """
        self._check_choice('top-drive controller', controller, CONTROLLERS)
        self.rig.set_top_drive_controller(controller)

    def set_top_drive_torque_limit(self, newton_metre: float) -> None:
        """
        Set the dynamic drive's motor torque limit (N m, > 0).

        Kept for when the drive becomes dynamic; raises CommandRejected.
        """
        self._check('top-drive torque limit', newton_metre, 0.0,
                    self.limits.top_drive_torque_limit_max_nm, 'N m',
                    lambda v: None if v > 0 else (f'top-drive torque limit command {v:g} N m '
                                                  f'must be > 0 N m'))
        self.rig.set_torque_limit(float(newton_metre))

    def set_axial_mode(self, mode: str) -> None:
        """Switch the axial input (hook_load, block_velocity, autodriller; bumpless)."""
        self._check_choice('axial mode', mode, AXIAL_MODES)
        self.rig.set_axial_mode(mode)

    def set_block_velocity(self, m_per_s: float) -> None:
        """Set the block velocity (m/s, down > 0) block_velocity mode follows."""
        fastest = PLAUSIBLE_BLOCK_SPEED_M_PER_S
        self._check('block velocity', m_per_s, -fastest, fastest, 'm/s')
        self.rig.set_block_velocity(float(m_per_s))

    def set_weight_on_bit_setpoint(self, newton: float) -> None:
        """Set the autodriller's WOB set-point (N, compression > 0, up to the envelope's)."""
        self._check('WOB set-point', newton, 0.0, self.envelope.weight_on_bit_max_n, 'N')
        self.rig.set_weight_on_bit_setpoint(float(newton))

    def _check_choice(self, what: str, value, choices) -> None:
        self.commands_received += 1
        if value not in choices:
            self._reject(what, value, f'{what} command {value!r} is not one of '
                                      f'{", ".join(choices)}')

    def _check(self, what, value, low, high, unit, physics=None) -> None:
        self.commands_received += 1
        try:
            value = float(value)
        except (TypeError, ValueError):
            value = float('nan')
        reason = None
        if not math.isfinite(value):
            reason = f'{what} command {value} is not a finite number'
        elif not low <= value <= high:
            reason = f'{what} command {value:g} {unit} is outside [{low:g}, {high:g}] {unit}'
        elif physics is not None:
            reason = physics(value)
        if reason:
            self._reject(what, value, reason)

    def _reject(self, what: str, value, reason: str) -> None:
        """Count and report a refused command, and raise CommandRejected."""
        self.rejected_commands += 1
        self._events.append(TwinEvent('command_rejected', 'warn', self.time_s,
                                      reason + '; the previous command stays',
                                      {'command': what, 'value': str(value)}))
        raise CommandRejected(reason)
