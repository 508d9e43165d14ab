"""
The bit's 2x2 equation of a Newmark iteration, solved by brackets so that it cannot fail.

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
- with a compliant rock (``bit_rock.contact_stiffness_n_per_m`` = k) the resting branch is a
  spring instead: ROP = rho - s F1 with s = gamma / (beta dt k), the end-of-step velocity at
  which the bit presses the rock by -F1 / k; rho is then measured to the undeformed bottom and
  is negative where the bit presses it already. The graph is ROP = max(rho - s F1, R(-P,
  omega)) for P > 0: continuous in P, increasing for the mean law (F1 = -P), and the same at
  s = 0; the hole's bottom ends where the bit ends less -F1 / k.

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

The solve is compiled (:func:`solve_one`, one member, called by the Newmark step kernel);
:func:`solve_bit_equation` runs it over a batch.
"""
from __future__ import annotations

import numpy as np

from drill_twin.model.bit_rock import (BitRockLaw, cutting_rate, maximum, minimum,
                                       randomised_point, torque_of_force, z_factor)
from drill_twin.numerics.compiled import inline, kernel

ROOT_ITERATIONS = 200
"""Cap of the bracketed iterations (Illinois with bisection guard: ~10 are used)."""
OMEGA_TOLERANCE = 1e-13
"""Width of the bracket on omega (rad/s, plus the same relative) at which it is solved."""
FORCE_TOLERANCE = 1e-8
"""Width of the bracket on the force parameter P (N, plus 1e-14 relative): through c1 ~ 4e-8
(m/s)/N it moves ROP by less than 1e-13 m/s."""
FORCE_RELATIVE_TOLERANCE = 1e-14
ROP_TOLERANCE = 1e-16
"""Residual of the axial equation (m/s) at which it is solved."""
BISECT_AFTER = 4
"""Steps after which a bracket that has not halved is bisected (worst case: linear)."""
EXPANSIONS = 80
"""Doublings allowed when a bracket is searched for (random germs only)."""


def solve_bit_equation(law: BitRockLaw, b, c, rho, germ=None, omega_guess=None, slope=None):
    """
    Solve the module's equation for m members.

    :param law: the bit-rock law.
    :param b: (m, 2) bit velocities (ROP m/s, omega rad/s) with no rock force.
    :param c: (m, 2) positive flexibilities over the step ((m/s)/N, (rad/s)/(N m)).
    :param rho: (m,) ROP at which the bit reaches the hole bottom at the end of the step (>= 0
        on a rigid rock; negative where the bit presses a compliant rock already).
    :param germ: (m, 2, 2) random germs or None (mean law).
    :param omega_guess: (m,) a start for omega (the iterate's), or None.
    :param slope: (m,) the resting branch's slope (m/s)/N of a compliant rock, or None (rigid).

    :return: (rop, omega, force, torque, lifted, on_bottom, cutting), arrays of shape (m,): lifted
        when the rock's axial force is zero.
    """
    b = np.ascontiguousarray(b, dtype=float)
    c = np.ascontiguousarray(c, dtype=float)
    rho = np.ascontiguousarray(rho, dtype=float)
    m = b.shape[0]
    slope = np.zeros(m) if slope is None else np.ascontiguousarray(
        np.broadcast_to(slope, (m,)), dtype=float)
    guess = b[:, 1].copy() if omega_guess is None else np.array(omega_guess, dtype=float)
    random = germ is not None
    germs = np.ascontiguousarray(germ, dtype=float) if random else np.eye(2)[None]
    out = np.empty((7, m))
    solve_batch(b, c, rho, slope, germs, random, guess, law.constants, out)
    return (out[0], out[1], out[2], out[3], out[4] > 0, out[5] > 0, out[6])


@kernel
def solve_batch(b, c, rho, slope, germ, random, guess, k, out):
    """
    solve_one for every row of b, c (m, 2), rho, slope, guess (m,).

    Out (7, m): rop, omega, force, torque, lifted, on bottom, cutting rate (flags as 0/1).
    """
    last = germ.shape[0] - 1
    for i in range(b.shape[0]):
        g = min(i, last)
        rop, omega, f1, f2, parameter, cut = solve_one(
            b[i, 0], b[i, 1], c[i, 0], c[i, 1], rho[i], slope[i], germ[g, 0, 0], germ[g, 0, 1],
            germ[g, 1, 1], random, guess[i], k, 0.0)
        out[0, i], out[1, i], out[2, i], out[3, i] = rop, omega, f1, f2
        out[4, i] = 1.0 if f1 >= 0.0 else 0.0
        out[5, i] = 1.0 if parameter > 0 else 0.0
        out[6, i] = cut


@kernel
def solve_one(b1, b2, c1, c2, rho, slope, g11, g12, g22, random, guess, k, kappa=0.0):
    """
    One member's solve (module docstring): (rop, omega, F1, F2, P, cutting rate).

    ``kappa``: on a lobed bottom (bottom_hole_pattern) the surface under the bit moves at
    kappa omega; the graph holds for the ROP relative to it, ROP - kappa omega, and rho, b1
    are then the absolute ones (the rop returned is the relative one).
    """
    germ = (g11, g12, g22, random, kappa)
    b1 = b1 - kappa * b2                      # relative to the surface at omega = b2 ...
    rho = rho - kappa * b2
    if not b1 > maximum(rho, cutting_rate(0.0, b2, k)):
        # The free bit (P <= 0) turns at omega = b2 with no torque: it does not reach the
        # bottom, or outruns the law's cut at zero force, at that speed.
        return b1, b2, 0.0, 0.0, 0.0, cutting_rate(0.0, b2, k)
    b1, rho = b1 + kappa * b2, rho + kappa * b2   # ... and absolute again below
    warm = np.empty(1)                               # the last omega found
    warm[0] = guess
    # The mean law's root at the guessed speed, as the centre of a bracket widened by
    # doublings: G(0) = max(rho, R(0, b2)) - b1 < 0 on the left, and F1 ~ G11 f for large
    # |f| makes G -> +inf on the right.
    low_b2, high_b2 = minimum(0.0, b2), maximum(0.0, b2)
    start = maximum(minimum(guess, high_b2), low_b2)
    centre = _mean_axial_root(start, b1 - kappa * start, c1, rho - kappa * start, slope, k)
    half = 0.02 * centre + 1.0
    lo, hi = maximum(centre - half, 0.0), centre + half
    r_lo = _axial_residual(lo, b1, b2, c1, c2, rho, slope, germ, warm, k)
    r_hi = _axial_residual(hi, b1, b2, c1, c2, rho, slope, germ, warm, k)
    for _ in range(EXPANSIONS):
        left = r_lo > 0
        right = not left and r_hi < 0
        if not (left or right):
            break
        half = 2.0 * half
        if left:
            hi, r_hi = lo, r_lo
            lo = maximum(centre - half, 0.0)
            r_lo = _axial_residual(lo, b1, b2, c1, c2, rho, slope, germ, warm, k)
        else:
            lo, r_lo = hi, r_hi
            hi = centre + half
            r_hi = _axial_residual(hi, b1, b2, c1, c2, rho, slope, germ, warm, k)
    # Illinois on the axial equation (see _illinois_step for the rules).
    x, done = _illinois_start(lo, hi, r_lo, r_hi, FORCE_TOLERANCE, FORCE_RELATIVE_TOLERANCE,
                              ROP_TOLERANCE)
    last_side, reference, count = 0, hi - lo, 0
    for _ in range(ROOT_ITERATIONS):
        if done:
            break
        trial, bisect, count, reference = _illinois_trial(lo, hi, r_lo, r_hi, count,
                                                          reference)
        r_trial = _axial_residual(trial, b1, b2, c1, c2, rho, slope, germ, warm, k)
        x, lo, hi, r_lo, r_hi, last_side, done = _illinois_step(
            x, trial, r_trial, bisect, lo, hi, r_lo, r_hi, last_side, FORCE_TOLERANCE,
            FORCE_RELATIVE_TOLERANCE, ROP_TOLERANCE)
    omega = _torsion(x, b2, c2, rho, slope, germ, warm[0], k)
    rop, f1, f2, cut = _point(x, omega, rho - kappa * omega, slope, germ, k)
    return rop, omega, f1, f2, x, cut


@kernel
def _axial_residual(parameter, b1, b2, c1, c2, rho, slope, germ, warm, k):
    """
    G(P) = ROP(P, omega(P)) - b1 - c1 F1; warm[0]: the last omega found (updated).

    On a lobed bottom (kappa = germ[4]) ROP, b1 and rho relative to the surface at omega(P).
    """
    omega = _torsion(parameter, b2, c2, rho, slope, germ, warm[0], k)
    if np.isfinite(omega):
        warm[0] = omega
    moving = germ[4] * omega
    rop, f1, _, _ = _point(parameter, omega, rho - moving, slope, germ, k)
    return rop - (b1 - moving) - c1 * f1


@kernel
def _torsion_residual(omega, parameter, b2, c2, rho, slope, germ, k):
    return omega - b2 - c2 * _point(parameter, omega, rho, slope, germ, k)[2]


@kernel
def _torsion(parameter, b2, c2, rho, slope, germ, guess, k):
    """Solve omega = b2 + c2 F2(P, omega) for omega at given P (bracketed, module docstring)."""
    r_b2 = _torsion_residual(b2, parameter, b2, c2, rho, slope, germ, k)
    if b2 < 0.0:                                        # F2(P, 0) = 0: r(0) = -b2
        lo, hi, r_lo, r_hi = b2, 0.0, r_b2, -b2
    else:
        lo, hi, r_lo, r_hi = 0.0, b2, -b2, r_b2
    if not _brackets(r_lo, r_hi):                       # a random torque that drives the bit
        reach = abs(r_b2) + 1e-3                        # c2 |F2(P, b2)|
        direction = -1.0 if b2 < 0 else 1.0
        for _ in range(EXPANSIONS):
            trial = b2 + direction * reach
            r_trial = _torsion_residual(trial, parameter, b2, c2, rho, slope, germ, k)
            if trial < lo:
                lo, r_lo = trial, r_trial
            if trial > hi:
                hi, r_hi = trial, r_trial
            if _brackets(r_lo, r_hi):
                break
            reach = 2.0 * reach
    start = maximum(minimum(guess, hi), lo)
    r_start = _torsion_residual(start, parameter, b2, c2, rho, slope, germ, k)
    if np.isfinite(r_start) and _brackets(r_lo, r_hi):  # narrow to [lo, start] or [start, hi]
        if np.sign(r_start) == np.sign(r_lo):
            lo, r_lo = start, r_start
        else:
            hi, r_hi = start, r_start
    x, done = _illinois_start(lo, hi, r_lo, r_hi, OMEGA_TOLERANCE, OMEGA_TOLERANCE,
                              OMEGA_TOLERANCE)
    last_side, reference, count = 0, hi - lo, 0
    for _ in range(ROOT_ITERATIONS):
        if done:
            break
        trial, bisect, count, reference = _illinois_trial(lo, hi, r_lo, r_hi, count,
                                                          reference)
        r_trial = _torsion_residual(trial, parameter, b2, c2, rho, slope, germ, k)
        x, lo, hi, r_lo, r_hi, last_side, done = _illinois_step(
            x, trial, r_trial, bisect, lo, hi, r_lo, r_hi, last_side, OMEGA_TOLERANCE,
            OMEGA_TOLERANCE, OMEGA_TOLERANCE)
    return x


@inline
def _mean_axial_root(omega, b1, c1, rho, slope, k):
    """P of the mean law's axial equation at a given omega, in closed form."""
    z = z_factor(omega, k)
    r0 = cutting_rate(0.0, omega, k)
    top = maximum(rho, r0)
    # G(P) = max(rho + slope P, R(-P)) - b1 + c1 P: the root of a maximum of two increasing
    # lines is the smaller of their roots.
    cutting = (b1 - r0) / (c1 + k[1] * z * z)
    resting = (b1 - rho) / (c1 + slope)
    return minimum(cutting, resting) if b1 > top else 0.0


@kernel
def _point(parameter, omega, rho, slope, germ, k):
    """Return the graph's point at P (module docstring): (ROP, F1, F2, cutting rate)."""
    if parameter > 0:
        force = -parameter
        cut = cutting_rate(force, omega, k)
        torque = torque_of_force(force, omega, cut, k)
        # The random law at the law's own point (R, omega) of that force; a compliant rock
        # is pressed by the force it bears, F1.
        f1, f2 = randomised_point(force, torque, cut, cut, omega, germ[0], germ[1], germ[2],
                                  germ[3], k)
        rop = maximum(rho - slope * f1, cut)
        return rop, f1, f2, cut
    cut = cutting_rate(0.0, omega, k)
    return maximum(rho, cut) + parameter, 0.0, 0.0, cut


@inline
def _brackets(r_lo, r_hi):
    return np.sign(r_lo) * np.sign(r_hi) <= 0 and np.isfinite(r_lo) and np.isfinite(r_hi)


@inline
def _illinois_start(lo, hi, r_lo, r_hi, tolerance, relative, residual_tolerance):
    """Start the Illinois method on [lo, hi]: return (x, done)."""
    x = lo if abs(r_lo) <= abs(r_hi) else hi
    done = (minimum(abs(r_lo), abs(r_hi)) <= residual_tolerance or not np.isfinite(r_lo)
            or not np.isfinite(r_hi) or hi - lo <= tolerance + relative * abs(x))
    return x, done


@inline
def _illinois_trial(lo, hi, r_lo, r_hi, count, reference):
    """
    Next point of the Illinois iteration as (trial, bisect, count, reference).

    Regula falsi, or a bisection when the secant point is not inside the bracket or the bracket
    has not halved in BISECT_AFTER steps.
    """
    width = hi - lo
    count += 1
    stalled = False
    if count == BISECT_AFTER:
        stalled = width > 0.5 * reference
        reference, count = width, 0
    secant = hi - r_hi * width / (r_hi - r_lo)
    bisect = stalled or not np.isfinite(secant) or secant <= lo or secant >= hi
    trial = lo + 0.5 * width if bisect else secant
    return trial, bisect, count, reference


@inline
def _illinois_step(x, trial, r_trial, bisect, lo, hi, r_lo, r_hi, last_side, tolerance,
                   relative, residual_tolerance):
    """
    Move the end of the bracket whose residual has the sign of r(trial).

    Illinois: the end kept twice in a row has its residual halved. Converged when the bracket,
    or a secant step, is below the tolerance, or the residual below ``residual_tolerance``.
    """
    if np.sign(r_trial) == np.sign(r_lo):
        if last_side == -1:
            r_hi = 0.5 * r_hi
        lo, r_lo, last_side = trial, r_trial, -1
    else:
        if last_side == 1:
            r_lo = 0.5 * r_lo
        hi, r_hi, last_side = trial, r_trial, 1
    moved = abs(trial - x)
    small = tolerance + relative * abs(trial)
    done = (abs(r_trial) <= residual_tolerance or hi - lo <= small
            or not np.isfinite(r_trial) or (not bisect and moved <= small))
    return trial, lo, hi, r_lo, r_hi, last_side, done
