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
ROP = max(rho, R(-P, omega)). At fixed omega the axial equation g(P) = ROP(P) - b1 - c1 F1(P)
goes from -inf to +inf; for the mean law it is increasing (one root, in closed form, which
is exact also at omega = 0 where Eq. 25 is singular); for a random germ its root is
bracketed and found by the Illinois method. The torsional equation r(omega) = omega - b2 -
c2 F2(omega) is then solved the same way: F2(0) = 0 (Z(0) = 0) and the mean torque opposes
omega, so [0, b2] brackets a root (wider brackets are searched for random germs).

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
FORCE_TOLERANCE = 1e-9
"""Width of the bracket on the force parameter P (N, plus 1e-15 relative)."""
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

    def torsion_residual(omega):
        point = _axial(law, omega, b1, c1, rho, germ)
        return omega - b2 - c2 * point[3]

    zero = np.zeros_like(b2)
    r_zero = -b2                                    # F2(0) = 0 for every law
    r_b2 = torsion_residual(b2)
    lo, hi, r_lo, r_hi = _ordered(zero, b2, r_zero, r_b2)
    missing = ~_brackets(r_lo, r_hi)
    if missing.any():                               # a random torque that drives the bit
        reach = np.abs(c2 * _axial(law, b2, b1, c1, rho, germ)[3]) + 1e-3
        for _ in range(EXPANSIONS):
            trial = b2 + np.sign(np.where(b2 == 0, 1.0, b2)) * reach
            r_trial = torsion_residual(trial)
            lo, hi, r_lo, r_hi = _extend(missing, lo, hi, r_lo, r_hi, trial, r_trial)
            missing &= ~_brackets(r_lo, r_hi)
            if not missing.any():
                break
            reach = 2.0 * reach
    if omega_guess is not None:                     # narrow the bracket around the iterate
        guess = np.clip(np.asarray(omega_guess, dtype=float), lo, hi)
        lo, hi, r_lo, r_hi = _narrow(lo, hi, r_lo, r_hi, guess, torsion_residual(guess))
    omega = _illinois(torsion_residual, lo, hi, r_lo, r_hi,
                      lambda x: OMEGA_TOLERANCE * (1.0 + np.abs(x)))
    force_parameter, rop, force, torque, cut = _axial(law, omega, b1, c1, rho, germ)
    lifted = force >= 0.0
    on_bottom = force_parameter > 0
    return rop, omega, force, torque, lifted, on_bottom, cut


def _axial(law, omega, b1, c1, rho, germ):
    """Root P of g(P) at a given omega and the point there: (P, ROP, F1, F2, cutting)."""
    z = law._cutting_z(omega)
    r0 = law.cutting_rate(0.0, omega)
    top = np.maximum(rho, r0)
    free = ~(b1 > top)                              # NaN inputs count as free (and stay NaN)
    denominator = c1 + law.a2 * z * z
    cut_force = (r0 - b1) / denominator
    cut_rop = b1 + c1 * cut_force
    resting = cut_rop <= rho
    force = np.where(free, 0.0, np.where(resting, (rho - b1) / c1, cut_force))
    parameter = np.where(free, b1 - top, -force)
    if germ is not None and not free.all():
        on = ~free

        def g(p):
            _, rop, f1, _, _ = _point(law, p, omega, rho, germ)
            return rop - b1 - c1 * f1

        lo = np.where(on, 0.0, parameter)
        r_lo = np.where(on, top - b1, 0.0)
        hi = np.where(on, np.maximum(parameter, 1.0), parameter)
        r_hi = np.where(on, g(hi), 0.0)
        for _ in range(EXPANSIONS):                 # F1 ~ G11 f for large |f|: g -> +inf
            low = on & (r_hi < 0)
            if not low.any():
                break
            lo, r_lo = np.where(low, hi, lo), np.where(low, r_hi, r_lo)
            hi = np.where(low, 2.0 * hi, hi)
            r_hi = np.where(low, g(hi), r_hi)
        root = _illinois(g, lo, hi, r_lo, r_hi,
                         lambda x: FORCE_TOLERANCE + 1e-15 * np.abs(x), active=on)
        parameter = np.where(on, root, parameter)
    p, rop, f1, f2, cut = _point(law, parameter, omega, rho, germ)
    rop = np.where(free, b1, rop)
    return p, rop, f1, f2, cut


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


def _illinois(func, lo, hi, r_lo, r_hi, tolerance, active=None):
    """A root of ``func`` in each bracket [lo, hi] (residuals r_lo, r_hi of opposite signs):
    regula falsi with the Illinois modification, and a bisection whenever the secant point
    falls outside or too close to the ends. Members outside ``active`` return lo."""
    lo, hi = lo.copy(), hi.copy()
    r_lo, r_hi = r_lo.copy(), r_hi.copy()
    x = np.where(np.abs(r_lo) <= np.abs(r_hi), lo, hi)
    done = (r_lo == 0) | (r_hi == 0) | ~np.isfinite(r_lo) | ~np.isfinite(r_hi)
    if active is not None:
        done |= ~active
    done |= (hi - lo) <= tolerance(x)
    last_side = np.zeros(lo.shape, dtype=int)
    for _ in range(ROOT_ITERATIONS):
        if done.all():
            break
        width = hi - lo
        with np.errstate(invalid='ignore', divide='ignore'):
            secant = hi - r_hi * width / (r_hi - r_lo)
        guard = 0.01 * width
        bisect = ~np.isfinite(secant) | (secant <= lo + guard) | (secant >= hi - guard)
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
        x = np.where(done, x, trial)
        done |= (r_trial == 0) | ((hi - lo) <= tolerance(x)) | ~np.isfinite(r_trial)
    return x
