"""
The bit's 2x2 equation of a Newmark iteration, for one member (compiled into the step).

With the string's forces frozen at the iterate, the bit's velocities x = (ROP, omega) obey

    x = x_lin + gamma dt H (F(x) - F_c),   H = B^T S^-1 B

(:mod:`~drill_twin.integrator.newmark`), F the bit-rock law. :func:`solve_bit` takes one Newton
step from the iterate's velocities where it stays on the law's cutting branch, else the
bracketed solve of :mod:`drill_twin.model.bit_equation`, which cannot fail. Its operands are
named: :class:`BitEquation` (the member's equation) and :class:`MemberLaw` (its law), and it
returns a :class:`BitSolution`; numba builds and reads these in registers.
"""
from __future__ import annotations

from typing import NamedTuple

import numpy as np

from drill_twin.model.bit_equation import solve_one
from drill_twin.model.bit_rock import cutting_rate, fade_force, law_point, maximum
from drill_twin.numerics.compiled import inline


class BitEquation(NamedTuple):
    """
    x = linear + gdt H (F(x) - F_c) of one member.

    linear_rop (m/s), linear_omega (rad/s): x_lin; flexibility (2, 2): H; start_rop,
    start_omega: the iterate's velocities (the Newton step's start); touch: the absolute
    end-of-step ROP that puts the bit on the rock's surface (m/s); slope: the compliant rock's
    resting branch, (1/k) gamma / (beta dt) (0 for a rigid rock); gdt: gamma dt (s);
    static_force_n: f_c (N); kappa: the lobed surface moves at kappa omega (m/rad).
    """

    linear_rop: float
    linear_omega: float
    flexibility: np.ndarray
    start_rop: float
    start_omega: float
    touch: float
    slope: float
    gdt: float
    static_force_n: float
    kappa: float


class MemberLaw(NamedTuple):
    """The member's law: germ entries g11, g12, g22, random, constants (8,), fade speed."""

    g11: float
    g12: float
    g22: float
    random: bool
    constants: np.ndarray
    fade_speed: float


class BitSolution(NamedTuple):
    """
    The bit's velocities and forces at the solution.

    rop (absolute, m/s), omega (rad/s), force, torque (N, N m), lifted (the bit off the rock),
    the law's Jacobian j00 ... j11 (zero when lifted), solved (finite), robust (1 if the
    bracketed solve was needed, else 0).
    """

    rop: float
    omega: float
    force: float
    torque: float
    lifted: bool
    j00: float
    j01: float
    j10: float
    j11: float
    solved: bool
    robust: int


@inline
def solve_bit(equation, law):
    """
    Solve x = linear + gamma dt H (F(x) - F_c) for one member; return a :class:`BitSolution`.

    One Newton step from the iterate's velocities kept where it stays on the law's cutting
    branch (ROP > 0: Eq. 25-26 read at a negative ROP, a bit rising while it presses a
    compliant rock, give a torque that drives the bit, +2.2 MN m at a member's rebound in
    the envelope sweep), else the bracketed solve of :mod:`bit_equation`. On a lobed bottom
    whose surface moves at kappa omega the law holds for the ROP relative to it,
    x0 - kappa x1 (its Jacobian taken with it).
    """
    step = _newton_step(equation, law)
    if step.solved:
        return step
    return _bracketed(equation, law, step)


@inline
def _newton_step(equation, law):
    """
    One Newton step from the iterate; ``solved`` False where it may leave the cutting branch.

    Then the law's Jacobian at the iterate is in j00 ... j11 (zero when lifted).
    """
    h, kappa = equation.flexibility, equation.kappa
    start0, start1, touch = equation.start_rop, equation.start_omega, equation.touch
    gdt, static_force, constants = equation.gdt, equation.static_force_n, law.constants
    f, t, j00, j01, j10, j11 = law_point(start0 - kappa * start1, start1, law.g11, law.g12,
                                         law.g22, law.random, constants)
    j01 -= kappa * j00                   # d/d omega of F(x0 - kappa x1, x1)
    j11 -= kappa * j10
    lifted = f >= 0.0
    if lifted:
        f = t = j00 = j01 = j10 = j11 = 0.0
    a0, a1 = f - static_force, t - 0.0
    g0 = start0 - equation.linear_rop - gdt * (h[0, 0] * a0 + h[0, 1] * a1)
    g1 = start1 - equation.linear_omega - gdt * (h[1, 0] * a0 + h[1, 1] * a1)
    # (I - gdt H J) step = g.
    m00 = 1.0 - gdt * (h[0, 0] * j00 + h[0, 1] * j10)
    m01 = 0.0 - gdt * (h[0, 0] * j01 + h[0, 1] * j11)
    m10 = 0.0 - gdt * (h[1, 0] * j00 + h[1, 1] * j10)
    m11 = 1.0 - gdt * (h[1, 0] * j01 + h[1, 1] * j11)
    determinant = m00 * m11 - m01 * m10
    s0 = (m11 * g0 - m01 * g1) / determinant
    s1 = (m00 * g1 - m10 * g0) / determinant
    x0, x1 = start0 - s0, start1 - s1
    c0 = f - (j00 * s0 + j01 * s1)
    c1 = t - (j10 * s0 + j11 * s1)
    relative, start_relative = x0 - kappa * x1, start0 - kappa * start1
    safe = (np.sign(relative) == np.sign(start_relative) and np.sign(x1) == np.sign(start1)
            and abs(start_relative - relative) <= 0.5 * abs(start_relative) and not lifted
            and c0 < 0 and x0 > touch and relative > 0 and x1 > 0)
    if safe and equation.slope > 0.0:     # on the cutting branch, beyond the rock's spring
        safe = x0 > touch - equation.slope * c0
    if safe and x1 >= law.fade_speed:                       # where the torque may fade
        mean_force = law_point(relative, x1, 1.0, 0.0, 1.0, False, constants)[0]
        safe = mean_force < fade_force(x1, constants)
    return BitSolution(rop=x0, omega=x1, force=c0, torque=c1, lifted=False, j00=j00, j01=j01,
                       j10=j10, j11=j11, solved=safe, robust=0)


@inline
def _bracketed(equation, law, step):
    """Solve by bracketing (:func:`~drill_twin.model.bit_equation.solve_one`), or free the bit."""
    h, kappa, touch = equation.flexibility, equation.kappa, equation.touch
    gdt, static_force = equation.gdt, equation.static_force_n
    c_0, c_1 = gdt * h[0, 0], gdt * h[1, 1]
    b0, b1 = equation.linear_rop - c_0 * static_force, equation.linear_omega - c_1 * 0.0
    if not b0 - kappa * b1 > maximum(touch - kappa * b1, cutting_rate(0.0, b1, law.constants)):
        # A bit that cannot reach the rock (or outruns the law's cut at zero force) at the
        # speed it has without a rock torque is free: F = 0, omega = b2, no search.
        rop, omega, f1, f2 = b0, b1, 0.0, 0.0
    else:
        rop, omega, f1, f2, _, _ = solve_one(b0, b1, c_0, c_1, touch, equation.slope, law.g11,
                                             law.g12, law.g22, law.random,
                                             equation.start_omega, law.constants, kappa)
        rop += kappa * omega                                     # absolute again
    free = f1 >= 0.0
    j00, j01, j10, j11 = step.j00, step.j01, step.j10, step.j11
    if free:                      # the Jacobian of a guarded member is the law's at the iterate
        j00 = j01 = j10 = j11 = 0.0
    solved = np.isfinite(rop) and np.isfinite(omega)
    return BitSolution(rop=rop, omega=omega, force=f1, torque=f2, lifted=free, j00=j00,
                       j01=j01, j10=j10, j11=j11, solved=solved, robust=1)
