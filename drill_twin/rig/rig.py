"""
The rig: the driller's commands turned into the simulator's surface inputs, step by step.

A :class:`Rig` drives one :class:`~drill_twin.integrator.simulator.Simulator`. It holds the
commands (:class:`RigCommands`: top-drive speed, controller and torque limit; hook load, block
velocity, WOB set-point) and the machines that act on them:

- the top drive (:class:`~drill_twin.rig.top_drive.TopDriveMode`): kinematic (the paper's
  imposed speed), dynamic (a rotor under a PI speed loop and a stick-slip controller) or
  followed (another model's speed, the twin's ensemble);
- the axial input (:class:`~drill_twin.rig.drawworks.AxialMode`): the hook load as a force
  (held by the drum's brake where it would move the top faster than the block can), the block
  moved at a velocity or by the autodriller (the hook load is the drill line's pull), or
  every member's line hung from another model's block (the ensemble).

Each step, :meth:`Rig.inputs` moves the machines over the coming step and returns (top speed,
hook load); :meth:`Rig.step` hands them to ``simulator.step``. The machines read the
simulator's state and operators where they need the string's response within the step (the
dynamic drive's T_s = T_0 + Z omega, the drawworks' predicted top motion); nothing of the rig
writes into the simulator. The rig's variables (commands, each machine's ``state``) are its
own: :meth:`Rig.checkpoint` copies them and :meth:`Rig.restore` puts them back, which
:meth:`Rig.step` does when the simulator refuses the step (SimulationDiverged). With the
configured defaults (kinematic drive, hook-load input) the rig is the paper's.
"""
from __future__ import annotations

import dataclasses
from typing import NamedTuple

import numpy as np

from drill_twin.integrator.newmark import StepResult
from drill_twin.integrator.simulator import SimulationDiverged
from drill_twin.rig.controllers import CONTROLLERS, make_controller
from drill_twin.rig.drawworks import (DRAWWORKS_MODES, AxialMode, Drawworks, DrawworksState,
                                      FollowedBlock, FollowedBlockState, HookBrake,
                                      line_hook_load_n)
from drill_twin.rig.top_drive import (DynamicTopDrive, FollowedTopSpeed, KinematicTopDrive,
                                      TopDriveMode)

__all__ = ['AxialMode', 'Rig', 'RigCheckpoint', 'RigCommands', 'TopDriveMode']


@dataclasses.dataclass(slots=True)
class RigCommands:
    """
    What the driller asked for (SI).

    top_speed_rad_per_s: the top-drive speed command; hook_load_n: the hook load command (N,
    one for the batch or (m,) per member; in a drawworks mode what the line pulled over the
    last step; an array is replaced, never written in place); block_velocity_m_per_s: the
    block velocity command (down > 0); weight_on_bit_setpoint_n: the autodriller's (> 0 in
    compression); controller: the dynamic drive's ('stiff', 'soft_torque', 'impedance');
    torque_limit_nm: the dynamic drive's motor torque limit (None: the configured).
    """

    top_speed_rad_per_s: float
    hook_load_n: float | np.ndarray
    block_velocity_m_per_s: float
    weight_on_bit_setpoint_n: float
    controller: str
    torque_limit_nm: float | None = None

    def copy(self) -> RigCommands:
        return RigCommands(self.top_speed_rad_per_s, self.hook_load_n,
                           self.block_velocity_m_per_s, self.weight_on_bit_setpoint_n,
                           self.controller, self.torque_limit_nm)


class RigCheckpoint(NamedTuple):
    """A rig's variables at one instant (:meth:`Rig.checkpoint`): copies, and the machines."""

    commands: RigCommands
    top_drive: object
    top_drive_state: object
    axial_mode: AxialMode
    drawworks: Drawworks | None
    drawworks_state: DrawworksState | None
    followed_block: FollowedBlock | None
    followed_block_state: FollowedBlockState | None


class Rig:
    """
    The commands and machines that drive ``simulator`` (module docstring).

    Built as ``simulator.config`` says (``top_drive.mode``, ``drawworks.mode``), taking over
    where the simulator is: the commands are its current top speed and hook load. One rig per
    simulator: it listens to the simulator's member restarts to reseat the drill lines.
    """

    def __init__(self, simulator):
        config = simulator.config
        self.simulator = simulator
        self.config = config
        state = simulator.state
        drawworks = config.drawworks
        self.commands = RigCommands(
            top_speed_rad_per_s=state.top_speed_rad_per_s, hook_load_n=state.hook_load_n,
            block_velocity_m_per_s=drawworks.block_velocity_m_per_s,
            weight_on_bit_setpoint_n=drawworks.weight_on_bit_setpoint_n,
            controller=config.top_drive.controller)
        if config.top_drive.mode == TopDriveMode.DYNAMIC.value:
            self.top_drive = self._dynamic_drive()
        else:
            self.top_drive = KinematicTopDrive(
                state.top_speed_rad_per_s, config.operation.top_drive_acceleration_rad_per_s2)
        self.axial_mode = AxialMode(drawworks.mode)
        self.drawworks = (Drawworks(simulator, drawworks, self.commands.hook_load_n)
                          if self.axial_mode in DRAWWORKS_MODES else None)
        """The drawworks in a block_velocity or autodriller mode, else None."""
        self.followed_block: FollowedBlock | None = None
        """The ensemble's lines (built when a block is first followed)."""
        self._brake: HookBrake | None = None
        simulator.reset_listeners.append(self._reseat_lines)

    # -- commands ------------------------------------------------------------------------
    @property
    def top_speed_command_rad_per_s(self) -> float:
        """The top-drive speed command (rad/s)."""
        return self.commands.top_speed_rad_per_s

    @property
    def hook_load_command_n(self):
        """The hook load command (N, scalar or (m,)); in a drawworks mode the line's last pull."""
        return self.commands.hook_load_n

    @property
    def top_drive_mode(self) -> TopDriveMode:
        """What sets the top speed now."""
        return self.top_drive.mode

    def set_top_drive_speed(self, rad_per_s: float) -> None:
        """Set the top-drive speed command (rad/s), followed from the next step on."""
        self.commands.top_speed_rad_per_s = float(rad_per_s)

    def set_hook_load(self, newton) -> None:
        """
        Set the hook load command (N), applied from the next step on.

        One value for the whole batch, or one per member, shape (m,) (each member's own drill
        line). In a drawworks mode the line's pull replaces it at the next step.
        """
        if np.ndim(newton) == 0:
            self.commands.hook_load_n = float(newton)
            return
        loads = np.array(newton, dtype=float)
        members = self.simulator.members
        if loads.shape != (members,):
            raise ValueError(f'hook loads must have shape ({members},), got {loads.shape}')
        self.commands.hook_load_n = loads

    def set_top_drive_mode(self, mode, controller: str | None = None) -> None:
        """
        Switch the top drive at run time, bumpless.

        ``mode`` (a :class:`TopDriveMode` or its value): 'kinematic' (the speed now held, then
        following commands at ``operation.top_drive_acceleration_rad_per_s2``), 'dynamic' (the
        PI integral starts at the string's current torque; with ``controller``, else the
        controller command) or 'followed' (the speed now held until :meth:`follow_top_speed`).
        """
        try:
            mode = TopDriveMode(mode)
        except ValueError:
            raise ValueError(f'top drive mode must be kinematic, dynamic or followed, '
                             f'not {mode!r}') from None
        if controller is not None:
            self._check_controller(controller)
            self.commands.controller = controller
        speed = self.top_drive.speed_rad_per_s
        if mode is TopDriveMode.KINEMATIC:
            self.top_drive = KinematicTopDrive(
                speed, self.config.operation.top_drive_acceleration_rad_per_s2)
        elif mode is TopDriveMode.DYNAMIC:
            self.top_drive = self._dynamic_drive()
        else:
            self.top_drive = FollowedTopSpeed(speed)

    def set_top_drive_controller(self, controller: str) -> None:
        """Set the dynamic drive's controller (kept while the drive is not dynamic)."""
        self._check_controller(controller)
        self.commands.controller = controller
        if self.top_drive.mode is TopDriveMode.DYNAMIC:
            self.top_drive = self._dynamic_drive()

    def set_torque_limit(self, newton_metre: float) -> None:
        """Set the dynamic drive's motor torque limit (N m, > 0), from the next step on."""
        if not newton_metre > 0:
            raise ValueError(f'the torque limit must be > 0 N m, got {newton_metre!r}')
        self.commands.torque_limit_nm = float(newton_metre)
        if self.top_drive.mode is TopDriveMode.DYNAMIC:
            self.top_drive.state.torque_limit_nm = float(newton_metre)

    def set_axial_mode(self, mode) -> None:
        """
        Switch the axial input at run time, bumpless.

        ``mode`` (an :class:`AxialMode` or its value): 'hook_load' (the hook load command stays
        what the line last pulled), 'block_velocity' or 'autodriller' (the block starts where
        the line pulls the current hook load; the autodriller's integral at the block's
        velocity) or 'followed_block' (the lines seated at the first :meth:`follow_block`).
        """
        try:
            mode = AxialMode(mode)
        except ValueError:
            raise ValueError(f'axial mode must be one of '
                             f'{", ".join(m.value for m in AxialMode)}, not {mode!r}') from None
        if mode is not AxialMode.FOLLOWED_BLOCK and self.followed_block is not None:
            self.followed_block.release()
        if mode in DRAWWORKS_MODES:
            if self.drawworks is None:
                self.drawworks = Drawworks(self.simulator, self.config.drawworks,
                                           self.commands.hook_load_n)
            if mode is AxialMode.AUTODRILLER and self.axial_mode is not AxialMode.AUTODRILLER:
                self.drawworks.engage_autodriller()
        else:
            self.drawworks = None
        self.axial_mode = mode

    def set_block_velocity(self, m_per_s: float) -> None:
        """Set the block velocity command (m/s, down > 0), followed in block_velocity mode."""
        self.commands.block_velocity_m_per_s = float(m_per_s)

    def set_weight_on_bit_setpoint(self, newton: float) -> None:
        """Set the autodriller's WOB set-point (N, > 0 in compression)."""
        self.commands.weight_on_bit_setpoint_n = float(newton)

    def follow_top_speed(self, rad_per_s: float) -> None:
        """Impose ``rad_per_s`` as the top speed at the end of the coming step (followed mode)."""
        if self.top_drive.mode is not TopDriveMode.FOLLOWED:
            self.set_top_drive_mode(TopDriveMode.FOLLOWED)
        self.top_drive.follow(rad_per_s)

    def follow_block(self, block_position_m: float, block_velocity_m_per_s: float) -> np.ndarray:
        """
        Hang every member's line from a block at x_b, v_b at the end of the coming step.

        Sets and returns the members' hook loads of the step (N, (m,);
        :class:`~drill_twin.rig.drawworks.FollowedBlock`).
        """
        if self.axial_mode is not AxialMode.FOLLOWED_BLOCK:
            self.set_axial_mode(AxialMode.FOLLOWED_BLOCK)
        if self.followed_block is None:
            self.followed_block = FollowedBlock(self.simulator, self.config.drawworks)
        loads = self.followed_block.follow(block_position_m, block_velocity_m_per_s,
                                           self.commands.hook_load_n)
        self.set_hook_load(loads)
        return loads

    @staticmethod
    def _check_controller(controller: str) -> None:
        if controller not in CONTROLLERS:
            raise ValueError(f'top drive controller must be one of {", ".join(CONTROLLERS)}, '
                             f'not {controller!r}')

    def _dynamic_drive(self) -> DynamicTopDrive:
        """Return a dynamic drive under the controller and torque limit commands, bumpless."""
        settings = dataclasses.replace(self.config.top_drive, mode=TopDriveMode.DYNAMIC.value,
                                       controller=self.commands.controller)
        config = dataclasses.replace(self.config, top_drive=settings)
        return DynamicTopDrive(self.simulator, settings,
                               make_controller(config, self.simulator.system),
                               self.commands.torque_limit_nm)

    # -- stepping ------------------------------------------------------------------------
    def inputs(self) -> tuple[float, float | np.ndarray]:
        """
        Move the machines over the coming step; return its (top speed rad/s, hook load N).

        The drawworks first (its hook load becomes the command), then the top drive; in
        hook_load mode the drum's brake may hold the command (``drawworks.block_speed_max``).
        """
        commands = self.commands
        if self.drawworks is not None:
            commands.hook_load_n = self.drawworks.before_step(
                self.axial_mode is AxialMode.AUTODRILLER, commands.block_velocity_m_per_s,
                commands.weight_on_bit_setpoint_n)
        speed = self.top_drive.advance(commands.top_speed_rad_per_s, self.simulator.dt)
        hook = commands.hook_load_n
        if self.axial_mode is AxialMode.HOOK_LOAD:
            brake = self._hook_brake()
            if brake is not None:
                hook = brake.hook_load(hook)
        return speed, hook

    def _hook_brake(self) -> HookBrake | None:
        """Return the drum's brake of hook_load mode (None when not configured)."""
        if self._brake is None:
            speed_max = self.config.drawworks.block_speed_max_m_per_s
            if speed_max is None:
                return None
            self._brake = HookBrake(self.simulator, speed_max)
        return self._brake

    def step(self) -> StepResult:
        """
        Step the simulator once under the rig's inputs.

        If the simulator refuses the step (SimulationDiverged, re-raised), the rig is put back
        as it was before it (:meth:`restore`).
        """
        checkpoint = self.checkpoint()
        speed, hook = self.inputs()
        try:
            return self.simulator.step(speed, hook)
        except SimulationDiverged:
            self.restore(checkpoint)
            raise

    def checkpoint(self) -> RigCheckpoint:
        """Return the rig's variables now (copies), for :meth:`restore`."""
        drawworks, followed = self.drawworks, self.followed_block
        return RigCheckpoint(
            self.commands.copy(), self.top_drive, self.top_drive.state.copy(), self.axial_mode,
            drawworks, None if drawworks is None else drawworks.state.copy(),
            followed, None if followed is None else followed.state.copy())

    def restore(self, checkpoint: RigCheckpoint) -> None:
        """Put the rig's variables back as they were at ``checkpoint`` (reusable)."""
        self.commands = checkpoint.commands.copy()
        self.top_drive = checkpoint.top_drive
        self.top_drive.state = checkpoint.top_drive_state.copy()
        self.axial_mode = checkpoint.axial_mode
        self.drawworks = checkpoint.drawworks
        if self.drawworks is not None:
            self.drawworks.state = checkpoint.drawworks_state.copy()
        self.followed_block = checkpoint.followed_block
        if self.followed_block is not None:
            self.followed_block.state = checkpoint.followed_block_state.copy()

    def reset_members(self, members) -> None:
        """
        Restart ``members`` of the simulator from a safe state under the hook load command.

        A drawworks then pays out or takes in line so that it pulls that hook load (the block
        does not jump); an ensemble's lines are reseated likewise.
        """
        if np.size(members) == 0:
            return
        self.simulator.reset_members(members, self.commands.hook_load_n)
        if self.drawworks is not None:
            self.drawworks.reseat(self.commands.hook_load_n)

    def _reseat_lines(self, members) -> None:
        """Reseat the followed lines of ``members`` (the simulator restarted or replaced them)."""
        followed = self.followed_block
        if followed is not None and followed.following:
            followed.reseat(members, self.commands.hook_load_n)

    # -- surface -------------------------------------------------------------------------
    def measured_hook_load_n(self, observation) -> float:
        """Return the hook load a rig measures (N): the line's pull, or the hook force."""
        if self.drawworks is None:
            return float(observation.hook_load_n)
        return line_hook_load_n(self.drawworks)

    def block_position_m(self, observation) -> float:
        """Return the block's position (m, down > 0): the drawworks', or the top's (member 0)."""
        if self.drawworks is None:
            return float(observation.hook_position_m[0])
        return float(self.drawworks.state.block_position_m)
