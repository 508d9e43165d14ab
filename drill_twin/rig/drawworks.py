"""
The drawworks.

The travelling block moved at a commanded velocity, or by the autodriller to hold a WOB
set-point, holding the string's top through the drill line (docs/DRIVES.md, "The drawworks").

The paper's axial input is a hook force. A rig sets instead the block's motion; the hook load
is what the line pulls, measured:

    H = H_S + k_l (u_top - x_b - s) + c_l (u_top' - v_b),   H >= 0 (a slack line pulls nothing),

u_top the top's axial displacement from the prestressed state (down > 0), x_b and v_b the
block's displacement and velocity from the same state, s the line paid out since (after a
restart, below), H_S the prestressed hook load. The
simulator takes the hook load of the coming step as a force; u_top after the step is affine
in it (the axial block is linear; the bit force, the only non-linear axial force here, is
taken from the last converged step), so H is solved implicitly with the string's axial
block, as the top drive's torque is (drill_twin/rig/top_drive.py). The drawworks reads the
simulator's state and operators and returns the hook load; the rig hands it to the simulator.

The autodriller regulates v_b = v_I + K_p e, v_I' = K_i e, e = WOB_sp - WOB (WOB > 0 in
compression, measured at the last step), with v_b within [0, v_max]: an autodriller feeds
line and does not hoist (started on a string that rebounds upwards, it brakes the block to a
stop instead of following the string up), and never faster than its ROP limit v_max
(``autodriller_feed_rate_max_m_per_s``). The integral v_I is held within the same [0, v_max]
(anti-windup by clamping): a WOB overshoot is then bounded by about v_max / K_p, the error at
which the proportional action stops the block. Engaged, the integral starts from the block's
velocity (bumpless) clamped to [0, v_max]: unclamped, the integral of this slow loop (period
about 130 s) started at the 0.2 m/s of a block still slowing from a run down would feed a
stopped bit to 900 kN at a 200 kN set-point, and the string's wind-up would then spin the bit
at 150 rad/s when the top drive starts. In both modes v_b moves towards its target by at most
a_max dt a step (``block_acceleration_max_m_per_s2``): a velocity step would ring the string's
axial modes (a 0.25 m/s stop swings the bit by 0.45 m/s), which no drum does.

After a member is restarted from a safe state, :meth:`Drawworks.reseat` pays out or takes in
line (s, zero until then) so that it pulls that state's hook load; the block does not jump.

Member 0 is the reference member (the hook load is shared by the batch).

Beside the drawworks: :class:`HookBrake` (the drum's brake under the paper's hook force) and
:class:`FollowedBlock` (every member of an ensemble hung from the rig's block by a line of its
own). The axial input's modes are :class:`AxialMode`.
"""
from __future__ import annotations

import dataclasses
import enum

import numpy as np
import scipy.linalg as la

from drill_twin.config.schema import Drawworks as DrawworksConfig
from drill_twin.integrator import newmark_scheme as newmark
from drill_twin.integrator.member_measures import largest_top_speed


class AxialMode(enum.Enum):
    """What sets the hook load of the coming step."""

    HOOK_LOAD = 'hook_load'
    """The paper's: the hook load command as a force (held by the drum's brake if configured)."""
    BLOCK_VELOCITY = 'block_velocity'
    """The block moved at the commanded velocity; the hook load is the drill line's pull."""
    AUTODRILLER = 'autodriller'
    """The block moved by the autodriller towards a WOB set-point; the line's pull."""
    FOLLOWED_BLOCK = 'followed_block'
    """Every member's own line hung from another model's block (the twin's ensemble)."""


DRAWWORKS_MODES = (AxialMode.BLOCK_VELOCITY, AxialMode.AUTODRILLER)
"""The modes in which a :class:`Drawworks` moves the block."""


class TopAxialMotion:
    """
    Return the top's axial displacement and velocity after the coming step.

    As affine functions of the hook load of that step (member 0, or every member), from the
    simulator's state and the operators of its axial block (Newmark's predictor and corrector,
    :mod:`~drill_twin.integrator.newmark_scheme`).
    """

    def __init__(self, simulator):
        system = simulator.system
        self.simulator = simulator
        self.dt = simulator.dt
        c = system.blocks['axial'].columns
        self.columns = c
        self.row = system.top_axial_row[c]
        self._row = np.ascontiguousarray(self.row, dtype=float)
        self.static_hook_load_n = system.model.prestress.hook_load_n
        self.mass = system.mass[c, c]
        self.damping = system.damping[c, c]
        self.stiffness = system.stiffness[c, c]
        dt = self.dt
        self._factor = la.lu_factor(newmark.effective_matrix(self.mass, self.damping,
                                                             self.stiffness, dt))
        response = -la.lu_solve(self._factor, self.row)           # da/dH
        self.displacement_slope_m_per_n = float(newmark.BETA * dt * dt * self.row @ response)
        self.velocity_slope_m_per_s_per_n = float(newmark.GAMMA * dt * self.row @ response)

    def now(self) -> tuple[float, float]:
        """(u_top, u_top') at the current state (m, m/s)."""
        state = self.simulator.state
        return (float(self.row @ state.q[0, self.columns]),
                float(self.row @ state.q_rate[0, self.columns]))

    def predicted(self, hook_load_n: float = 0.0) -> tuple[float, float]:
        """(u_top, u_top') of member 0 after the step under ``hook_load_n`` (m, m/s)."""
        u, v = self._predicted(0, hook_load_n)
        return float(u), float(v)

    def speed_below(self, speed_m_per_s: float) -> bool:
        """Return whether every member's top moves slower than ``speed_m_per_s`` now (m/s)."""
        return largest_top_speed(np.ascontiguousarray(self.simulator.state.q_rate),
                                 self.columns.start, self._row) < speed_m_per_s

    def now_members(self) -> tuple[np.ndarray, np.ndarray]:
        """(u_top, u_top') of every member at the current state, (m,) each (m, m/s)."""
        state, c = self.simulator.state, self.columns
        return state.q[:, c] @ self.row, state.q_rate[:, c] @ self.row

    def predicted_members(self) -> tuple[np.ndarray, np.ndarray]:
        """(u_top, u_top') of every member after the step under a zero hook load, (m,) each."""
        return self._predicted(slice(None), 0.0)

    def hook_load_through_line(self, stiffness, damping, u0, v0, block_position_m,
                               block_velocity_m_per_s, slack_m):
        """
        Return the hook load H a drill line pulls over the coming step (N, >= 0).

        H = H_S + k (u_top(H) - x_b - s) + c (u_top'(H) - v_b) solved with u_top(H) and
        u_top'(H) affine in H (u0, v0 at H = 0, the slopes of this class); scalars or (m,).
        """
        rest = (self.static_hook_load_n + stiffness * (u0 - block_position_m - slack_m)
                + damping * (v0 - block_velocity_m_per_s))
        slope = (1.0 - stiffness * self.displacement_slope_m_per_n
                 - damping * self.velocity_slope_m_per_s_per_n)
        return np.maximum(rest / slope, 0.0)

    def _predicted(self, rows, hook_load_n):
        """Newmark's end-of-step top motion of ``rows`` (0 or a slice) under one hook load."""
        sim, dt, c = self.simulator, self.dt, self.columns
        state = sim.state
        q, v, a = state.q[rows, c], state.q_rate[rows, c], state.q_acceleration[rows, c]
        d_pred = newmark.predicted_displacement(q, v, a, dt)
        v_pred = newmark.predicted_velocity(v, a, dt)
        load = (sim.last.modal[rows, c] - v_pred @ self.damping.T - d_pred @ self.stiffness.T
                - self.row * (hook_load_n - self.static_hook_load_n))
        a_new = la.lu_solve(self._factor, load.T).T
        return (newmark.corrected_displacement(d_pred, a_new, dt) @ self.row,
                newmark.corrected_velocity(v_pred, a_new, dt) @ self.row)


@dataclasses.dataclass(slots=True)
class DrawworksState:
    """
    The drawworks' variables (m, m/s, N).

    block_position_m: x_b (down > 0, from the prestressed state); block_velocity_m_per_s:
    v_b; autodriller_integral_m_per_s: v_I; hook_load_n: what the line pulls over the last
    step; line_slack_m: s, the line's length change since the drawworks took over.
    """

    block_position_m: float
    block_velocity_m_per_s: float
    autodriller_integral_m_per_s: float
    hook_load_n: float
    line_slack_m: float = 0.0

    def copy(self) -> DrawworksState:
        return DrawworksState(self.block_position_m, self.block_velocity_m_per_s,
                              self.autodriller_integral_m_per_s, self.hook_load_n,
                              self.line_slack_m)


class Drawworks:
    """
    Block velocity input and autodriller (module docstring).

    :param simulator: the string whose top the line holds (read, never written).
    :param config: the drawworks.
    :param hook_load_command_n: the hook load the string hangs from now (N): the block starts
        where the line pulls it (no jump when the drawworks takes over), at the top's speed.

    :meth:`before_step` moves the block over the coming step and returns the hook load.
    """

    def __init__(self, simulator, config: DrawworksConfig, hook_load_command_n: float):
        self.simulator = simulator
        self.config = config
        self.top = TopAxialMotion(simulator)
        self.line_stiffness = config.line_stiffness_n_per_m
        self.line_damping = config.line_damping_n_s_per_m
        self.kp = config.autodriller_proportional_m_per_s_per_n
        self.ki = config.autodriller_integral_m_per_s2_per_n
        self.feed_rate_max_m_per_s = config.autodriller_feed_rate_max_m_per_s
        self.acceleration_max_m_per_s2 = config.block_acceleration_max_m_per_s2
        position, velocity = self.top.now()
        self.state = DrawworksState(
            block_position_m=position - (hook_load_command_n
                                         - self.top.static_hook_load_n) / self.line_stiffness,
            block_velocity_m_per_s=velocity,               # the block ramps from the top's speed
            autodriller_integral_m_per_s=self._feed(velocity),   # bumpless: the top's speed
            hook_load_n=float(hook_load_command_n))

    def reseat(self, hook_load_command_n: float) -> None:
        """
        Pay out or take in line so that it pulls ``hook_load_command_n`` (N) now.

        The block does not jump (an ensemble follows it): the line's slack s takes the change.
        """
        position, _ = self.top.now()
        self.state.line_slack_m = (position - self.state.block_position_m
                                   - (hook_load_command_n - self.top.static_hook_load_n)
                                   / self.line_stiffness)

    def engage_autodriller(self) -> None:
        """Start the autodriller's integral from the block's velocity (bumpless, clamped)."""
        self.state.autodriller_integral_m_per_s = self._feed(self.state.block_velocity_m_per_s)

    def _feed(self, m_per_s: float) -> float:
        """Return a feed rate within the autodriller's range [0, v_max] (m/s)."""
        return min(max(m_per_s, 0.0), self.feed_rate_max_m_per_s)

    def measured_weight_on_bit_n(self) -> float:
        """WOB of the last step, > 0 in compression (N)."""
        return float(-self.simulator.last.weight_on_bit_n[0])

    def before_step(self, autodriller: bool, block_velocity_command_m_per_s: float,
                    weight_on_bit_setpoint_n: float) -> float:
        """
        Move the block over the coming step; return the hook load it implies (N).

        ``autodriller``: the autodriller sets the block's velocity towards the WOB set-point
        (N, > 0 in compression); else the block follows the velocity command (m/s, down > 0).
        """
        state, dt = self.state, self.top.dt
        if autodriller:
            error = weight_on_bit_setpoint_n - self.measured_weight_on_bit_n()
            state.autodriller_integral_m_per_s = self._feed(
                state.autodriller_integral_m_per_s + self.ki * dt * error)
            # It feeds line (v_b >= 0, never hoists) up to its ROP limit, whatever the string does.
            target = self._feed(state.autodriller_integral_m_per_s + self.kp * error)
        else:
            target = block_velocity_command_m_per_s
        reach = self.acceleration_max_m_per_s2 * dt
        now = state.block_velocity_m_per_s
        state.block_velocity_m_per_s = min(max(target, now - reach), now + reach)
        state.block_position_m += dt * state.block_velocity_m_per_s
        u0, v0 = self.top.predicted(0.0)
        state.hook_load_n = float(self.top.hook_load_through_line(
            self.line_stiffness, self.line_damping, u0, v0, state.block_position_m,
            state.block_velocity_m_per_s, state.line_slack_m))
        return state.hook_load_n


def line_hook_load_n(drawworks: Drawworks) -> float:
    """Return the line's pull at the current state (N): the hook load as measured."""
    u, v = drawworks.top.now()
    state = drawworks.state
    return max(drawworks.top.static_hook_load_n
               + drawworks.line_stiffness * (u - state.block_position_m - state.line_slack_m)
               + drawworks.line_damping * (v - state.block_velocity_m_per_s), 0.0)


class HookBrake:
    """
    The drum's brake under the paper's hook force: the top moves no faster than the block can.

    In ``hook_load`` mode the hook load is a force, and nothing in the paper's model limits how
    fast it moves the string: a hook load 250 kN below the string's weight with the bit 7 m off
    bottom drops the string at 5.4 m/s onto the rock, and at the string's weight a string
    released from its WOB drifts up at 0.5 m/s. A rig's hook hangs from a block that the drum
    moves at most at ``block_speed_max_m_per_s``: where the command would take the top's axial
    speed beyond it in the coming step, the hook load is what holds it there,
    H = H_cmd + (v_cap - v(H_cmd)) / (dv/dH) (u_top' affine in H, as in
    :class:`TopAxialMotion`), never below 0. Below the cap the command is applied unchanged.

    It keeps the last command it saw only to skip the prediction while the command holds and
    the top is far below the cap (a cache: the hook load is the same without it).
    """

    def __init__(self, simulator, speed_max_m_per_s: float):
        self.simulator = simulator
        self.top = TopAxialMotion(simulator)
        self.speed_max_m_per_s = float(speed_max_m_per_s)
        self._last_command = None

    def hook_load(self, command_n):
        """Return the hook load to apply over the coming step: the command, or the brake's."""
        if type(command_n) is float or np.ndim(command_n) == 0:
            last, command = self._last_command, float(command_n)
            changed = not (type(last) is float and last == command)
            self._last_command = command
        else:
            changed = not np.array_equal(command_n, self._last_command)
            self._last_command = np.copy(command_n)
        if not changed and self.top.speed_below(0.5 * self.speed_max_m_per_s):
            return command_n                    # one step cannot reach the cap from here
        state = self.simulator.state
        if not all(np.all(np.isfinite(x)) for x in (state.q, state.q_rate, state.q_acceleration)):
            return command_n                    # a diverged member is the guard's to handle
        slope = self.top.velocity_slope_m_per_s_per_n
        _, free = self.top.predicted_members()                   # u_top' at H = 0, (m,)
        command = np.broadcast_to(np.asarray(command_n, dtype=float), free.shape)
        speed = free + slope * command
        cap = self.speed_max_m_per_s
        if np.all(np.abs(speed) <= cap):
            return command_n
        held = np.maximum(command + (np.clip(speed, -cap, cap) - speed) / slope, 0.0)
        if np.ndim(command_n) == 0 and held.size == 1:
            return float(held[0])               # one member, one hook load: keep it a scalar
        return held


@dataclasses.dataclass(slots=True)
class FollowedBlockState:
    """The followed block's position x_b (m) and every member's line slack s_m, (m,) (m)."""

    block_position_m: float = 0.0
    slack_m: np.ndarray | None = None
    """None until the block is first followed; replaced, never written in place."""

    def copy(self) -> FollowedBlockState:
        return FollowedBlockState(self.block_position_m, self.slack_m)


class FollowedBlock:
    """
    Every member's drill line hung from one block that moves as the rig's (the ensemble's input).

    The ensemble's members are one string on uncertain rock: the rig moves one block and each
    member's line pulls its own hook load,

        H_m = H_S + k_l (u_top,m - x_b - s_m) + c_l (u_top,m' - v_b),   H_m >= 0,

    solved with each member's axial block as :class:`Drawworks` does for member 0. s_m, the
    slack of member m's line, is set when the block is first followed (each line then pulls the
    hook load its member had: no jump) and again for members restarted from a safe state
    (:meth:`reseat`). Without it the members would take the mean model's hook load as a force,
    and a member whose hole is deeper than the mean model's would fall further when the mean
    model sets down.
    """

    def __init__(self, simulator, config: DrawworksConfig):
        self.simulator = simulator
        self.members = simulator.members
        self.top = TopAxialMotion(simulator)
        self.line_stiffness = config.line_stiffness_n_per_m
        self.line_damping = config.line_damping_n_s_per_m
        self.state = FollowedBlockState()

    @property
    def following(self) -> bool:
        """Whether the lines hang from the block (since the first :meth:`follow`)."""
        return self.state.slack_m is not None

    def follow(self, block_position_m: float, block_velocity_m_per_s: float,
               hook_load_command_n) -> np.ndarray:
        """
        Return every member's hook load for the coming step; the block ends it at x_b (N, (m,)).

        ``hook_load_command_n``: the hook loads the members hang from now (N, scalar or (m,)):
        the first call seats every line to pull its member's.
        """
        state = self.state
        if state.slack_m is None:
            state.block_position_m = block_position_m
            self.reseat(np.arange(self.members), hook_load_command_n)
        state.block_position_m = block_position_m
        u0, v0 = self.top.predicted_members()
        return self.top.hook_load_through_line(self.line_stiffness, self.line_damping, u0, v0,
                                               block_position_m, block_velocity_m_per_s,
                                               state.slack_m)

    def reseat(self, members, hook_load_command_n) -> None:
        """Set the slack of ``members`` so that their lines pull ``hook_load_command_n`` now."""
        members = np.asarray(members, dtype=int)
        hook = np.broadcast_to(np.asarray(hook_load_command_n, dtype=float), (self.members,))
        position, _ = self.top.now_members()
        slack = (position - self.state.block_position_m
                 - (hook - self.top.static_hook_load_n) / self.line_stiffness)
        kept = (np.zeros(self.members) if self.state.slack_m is None
                else self.state.slack_m.copy())
        kept[members] = slack[members]
        self.state.slack_m = kept

    def release(self) -> None:
        """Stop following (back to one hook load for the batch): the next follow reseats all."""
        self.state.slack_m = None
