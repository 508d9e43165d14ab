"""The bit's 2x2 equation of a Newmark iteration, solved by brackets so that it cannot fail.

Inside an iteration the bit velocities x = (ROP, omega) at the end of the step obey

    ROP = b1 + c1 F1,    omega = b2 + c2 F2,

b = the velocities the bit would have with no rock force, c = gamma dt diag(B^T S^-1 B) > 0
(B^T S^-1 B is diagonal: the linear axial, torsional and lateral blocks do not couple, and the
wall contact acts on lateral DOFs only), F = (F1, F2) the force and torque of the rock.

The rock's law, with the hole's bottom, is a monotone graph in ROP at a given omega:

- the bit ends the step above the hole bottom (ROP < rho): F = 0. rho >= 0 is the end-of-step
  ROP that puts the bit exactly on the hole bottom (0 when it is on bottom already);
- on bottom and cutting (ROP = R(f, omega) > rho, R the cutting rate of
  :meth:`BitRockLaw.cutting_rate`): the mean force f of Eq. 25, and the torque
  :meth:`BitRockLaw.torque_of_force`;
- on bottom and resting (ROP = rho): any f between the law's force at rho and 0 (a unilateral
  contact; at omega <= 0, where the bit does not cut, every f <= 0).

It is parametrised by one increasing number P: P <= 0 is the free bit (ROP = rho* + P, F = 0,
rho* = max(rho, R(0, omega))); P > 0 is on bottom with the mean force f = -P and
ROP = max(rho, R(-P, omega)); every function of (P, omega) below is continuous, also at
omega = 0 where Eq. 25 is singular (R is smooth in f and omega).

At a given P the torsional equation r(omega) = omega - b2 - c2 F2(P, omega) has F2(P, 0) = 0
(Z(0) = 0) and, for the mean law, a torque that opposes omega: [0, b2] brackets its root
(wider brackets are searched for random germs). Its slope is 1 - c2 dF2/domega, close to 1
(c2 ~ 6e-6 (rad/s)/(N m) at 5 ms), so that root omega(P) is unique and continuous. The axial
equation G(P) = ROP(P, omega(P)) - b1 - c1 F1(P, omega(P)) is then continuous, negative at
P = 0 (unless the bit is free) and -> +inf, so it has a root, bracketed and found by the
Illinois method. For the mean law G increases (one root). A random germ with a large G12 can
make F1 rise steeply with P near the cutting threshold (the coupling G12 sqrt(f t omega /
ROP)); G may then have several roots, each of them a solution of the 2x2 equation. (With the
nesting the other way round, the inner axial root would jump between them as omega moves,
and the outer equation would have no root at the jump.)

Nothing here can fail for finite inputs: continuous functions on brackets with a sign
change, and at most a fixed number of halvings.
"""
from __future__ import annotations

import numpy as np

from drill_twin.dynamics.bit_rock import BitRockLaw

ROOT_ITERATIONS = 200
"""Cap of the bracketed iterations (Illinois with bisection guard: ~10 are used)."""
OMEGA_TOLERANCE = 1e-13
"""Width of the bracket on omega (rad/s, plus the same relative) at which it is solved."""
FORCE_TOLERANCE = 1e-8
"""Width of the bracket on the force parameter P (N, plus 1e-14 relative): through c1 ~ 4e-8
(m/s)/N it moves ROP by less than 1e-13 m/s."""
ROP_TOLERANCE = 1e-16
"""Residual of the axial equation (m/s) at which it is solved."""
BISECT_AFTER = 4
"""Steps after which a bracket that has not halved is bisected (worst case: linear)."""
EXPANSIONS = 80
"""Doublings allowed when a bracket is searched for (random germs only)."""


def solve_bit_equation(law: BitRockLaw, b, c, rho, germ=None, omega_guess=None):
    """Solve the module's equation for m members.

    Args:
        law: the bit-rock law.
        b: (m, 2) bit velocities (ROP m/s, omega rad/s) with no rock force.
        c: (m, 2) positive flexibilities over the step ((m/s)/N, (rad/s)/(N m)).
        rho: (m,) ROP at which the bit reaches the hole bottom at the end of the step (>= 0).
        germ: (m, 2, 2) random germs or None (mean law).
        omega_guess: (m,) a start for omega (the iterate's), or None.

    Returns:
        (rop, omega, force, torque, lifted, on_bottom, cutting), arrays of shape (m,): lifted
        when the rock's axial force is zero.
    """
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    rho = np.asarray(rho, dtype=float)
    b1, b2 = b[:, 0], b[:, 1]
    c1, c2 = c[:, 0], c[:, 1]
    guess = b2.copy() if omega_guess is None else np.asarray(omega_guess, dtype=float).copy()
    # The free bit (P <= 0) turns at omega = b2 with no torque: free if it does not reach
    # the bottom, or outruns the law's cut at zero force, at that speed.
    free = ~(b1 > np.maximum(rho, law.cutting_rate(0.0, b2)))
    on = ~free
    warm = guess.copy()                             # the last omega found, per member

    def axial_residual(parameter):
        omega = _torsion(law, parameter, b2, c2, rho, germ, warm)
        warm[:] = np.where(np.isfinite(omega), omega, warm)
        _, rop, f1, _, _ = _point(law, parameter, omega, rho, germ)
        return rop - b1 - c1 * f1

    # The mean law's root at the guessed speed, as the centre of a bracket widened by
    # doublings: G(0) = max(rho, R(0, b2)) - b1 < 0 on the left, and F1 ~ G11 f for large
    # |f| makes G -> +inf on the right.
    centre = np.where(on, _mean_axial_root(law, np.clip(guess, np.minimum(0.0, b2),
                                                         np.maximum(0.0, b2)),
                                           b1, c1, rho), 0.0)
    half = 0.02 * centre + 1.0
    lo, hi = np.maximum(centre - half, 0.0), centre + half
    r_lo, r_hi = axial_residual(lo), axial_residual(hi)
    for _ in range(EXPANSIONS):
        left = on & (r_lo > 0)
        right = on & ~left & (r_hi < 0)
        if not (left.any() or right.any()):
            break
        half = np.where(left | right, 2.0 * half, half)
        hi, r_hi = np.where(left, lo, hi), np.where(left, r_lo, r_hi)
        lo, r_lo = np.where(right, hi, lo), np.where(right, r_hi, r_lo)
        lo = np.where(left, np.maximum(centre - half, 0.0), lo)
        hi = np.where(right, centre + half, hi)
        r_lo = np.where(left, axial_residual(lo), r_lo)
        r_hi = np.where(right, axial_residual(hi), r_hi)
    parameter = _illinois(axial_residual, lo, hi, r_lo, r_hi,
                          lambda x: FORCE_TOLERANCE + 1e-14 * np.abs(x), ROP_TOLERANCE,
                          active=on)
    parameter = np.where(on, parameter, 0.0)
    omega = np.where(on, _torsion(law, parameter, b2, c2, rho, germ, warm), b2)
    _, rop, force, torque, cut = _point(law, parameter, omega, rho, germ)
    rop = np.where(on, rop, b1)
    lifted = force >= 0.0
    return rop, omega, force, torque, lifted, parameter > 0, cut


def _torsion(law, parameter, b2, c2, rho, germ, guess):
    """omega solving omega = b2 + c2 F2(P, omega) at given P (bracketed, module docstring)."""
    def residual(omega):
        return omega - b2 - c2 * _point(law, parameter, omega, rho, germ)[3]

    zero = np.zeros_like(b2)
    r_b2 = residual(b2)
    lo, hi, r_lo, r_hi = _ordered(zero, b2, -b2, r_b2)              # F2(P, 0) = 0
    missing = ~_brackets(r_lo, r_hi)
    if missing.any():                               # a random torque that drives the bit
        reach = np.abs(r_b2) + 1e-3                 # c2 |F2(P, b2)|
        for _ in range(EXPANSIONS):
            trial = b2 + np.sign(np.where(b2 == 0, 1.0, b2)) * reach
            lo, hi, r_lo, r_hi = _extend(missing, lo, hi, r_lo, r_hi, trial, residual(trial))
            missing &= ~_brackets(r_lo, r_hi)
            if not missing.any():
                break
            reach = 2.0 * reach
    start = np.clip(guess, lo, hi)
    lo, hi, r_lo, r_hi = _narrow(lo, hi, r_lo, r_hi, start, residual(start))
    return _illinois(residual, lo, hi, r_lo, r_hi,
                     lambda x: OMEGA_TOLERANCE * (1.0 + np.abs(x)), OMEGA_TOLERANCE)


def _mean_axial_root(law, omega, b1, c1, rho):
    """P of the mean law's axial equation at a given omega, in closed form."""
    z = law._cutting_z(omega)
    r0 = law.cutting_rate(0.0, omega)
    top = np.maximum(rho, r0)
    cut_force = (r0 - b1) / (c1 + law.a2 * z * z)
    resting = b1 + c1 * cut_force <= rho
    force = np.where(resting, (rho - b1) / c1, cut_force)
    return np.where(b1 > top, -force, 0.0)


def _point(law, parameter, omega, rho, germ):
    """The graph's point at P (module docstring): (P, ROP, F1, F2, cutting rate)."""
    on = parameter > 0
    force = np.where(on, -parameter, 0.0)
    cut = law.cutting_rate(force, omega)
    rop = np.where(on, np.maximum(rho, cut), np.maximum(rho, law.cutting_rate(0.0, omega))
                   + parameter)
    torque = np.where(on, law.torque_of_force(force, omega, cut), 0.0)
    f1, f2 = law.randomised(force, torque, rop, cut, omega, germ)
    return parameter, rop, np.where(on, f1, 0.0), np.where(on, f2, 0.0), cut


def _brackets(r_lo, r_hi):
    return (np.sign(r_lo) * np.sign(r_hi) <= 0) & np.isfinite(r_lo) & np.isfinite(r_hi)


def _ordered(a, b, r_a, r_b):
    swap = b < a
    return (np.where(swap, b, a), np.where(swap, a, b), np.where(swap, r_b, r_a),
            np.where(swap, r_a, r_b))


def _extend(mask, lo, hi, r_lo, r_hi, trial, r_trial):
    """Grow [lo, hi] to include ``trial`` for the members in ``mask``."""
    below = mask & (trial < lo)
    above = mask & (trial > hi)
    return (np.where(below, trial, lo), np.where(above, trial, hi),
            np.where(below, r_trial, r_lo), np.where(above, r_trial, r_hi))


def _narrow(lo, hi, r_lo, r_hi, x, r_x):
    """Replace the end of [lo, hi] whose residual has the sign of r(x)."""
    usable = np.isfinite(r_x) & _brackets(r_lo, r_hi)
    left = usable & (np.sign(r_x) == np.sign(r_lo))
    right = usable & ~left
    return (np.where(left, x, lo), np.where(right, x, hi), np.where(left, r_x, r_lo),
            np.where(right, r_x, r_hi))


def _illinois(func, lo, hi, r_lo, r_hi, tolerance, residual_tolerance, active=None):
    """A root of ``func`` in each bracket [lo, hi] (residuals r_lo, r_hi of opposite signs):
    regula falsi with the Illinois modification, and a bisection whenever the secant point is
    not inside the bracket or the bracket has not halved in BISECT_AFTER steps. Converged when
    the bracket, or a secant step, is below ``tolerance(x)``, or the residual below
    ``residual_tolerance``. Members outside ``active`` return their start."""
    lo, hi = lo.copy(), hi.copy()
    r_lo, r_hi = r_lo.copy(), r_hi.copy()
    x = np.where(np.abs(r_lo) <= np.abs(r_hi), lo, hi)
    done = ((np.minimum(np.abs(r_lo), np.abs(r_hi)) <= residual_tolerance)
            | ~np.isfinite(r_lo) | ~np.isfinite(r_hi))
    if active is not None:
        done |= ~active
    done |= (hi - lo) <= tolerance(x)
    last_side = np.zeros(lo.shape, dtype=int)
    reference = hi - lo                               # the width BISECT_AFTER steps ago
    count = 0
    for _ in range(ROOT_ITERATIONS):
        if done.all():
            break
        width = hi - lo
        count += 1
        stalled = np.zeros(lo.shape, dtype=bool)
        if count == BISECT_AFTER:
            stalled = width > 0.5 * reference
            reference, count = width, 0
        with np.errstate(invalid='ignore', divide='ignore', over='ignore'):
            secant = hi - r_hi * width / (r_hi - r_lo)
        bisect = stalled | ~np.isfinite(secant) | (secant <= lo) | (secant >= hi)
        trial = np.where(bisect, lo + 0.5 * width, secant)
        trial = np.where(done, x, trial)
        r_trial = func(trial)
        same_as_lo = np.sign(r_trial) == np.sign(r_lo)
        move_lo = ~done & same_as_lo
        move_hi = ~done & ~same_as_lo
        # Illinois: the end kept twice in a row has its residual halved.
        r_hi = np.where(move_lo & (last_side == -1), 0.5 * r_hi, r_hi)
        r_lo = np.where(move_hi & (last_side == 1), 0.5 * r_lo, r_lo)
        lo, r_lo = np.where(move_lo, trial, lo), np.where(move_lo, r_trial, r_lo)
        hi, r_hi = np.where(move_hi, trial, hi), np.where(move_hi, r_trial, r_hi)
        last_side = np.where(move_lo, -1, np.where(move_hi, 1, last_side))
        moved = np.abs(trial - x)
        x = np.where(done, x, trial)
        small = tolerance(x)
        done |= ((np.abs(r_trial) <= residual_tolerance) | ((hi - lo) <= small)
                 | ~np.isfinite(r_trial) | (~bisect & (moved <= small)))
    return x
