"""
The Newmark scheme's constants and its predictor and corrector: the one definition.

Average acceleration (beta = 1/4, gamma = 1/2): unconditionally stable, no numerical damping.
For a step of dt (s) from (d, v, a) to the new acceleration a':

    d* = d + dt v + (1/2 - beta) dt^2 a        v* = v + (1 - gamma) dt a       (predictor)
    d' = d* + beta dt^2 a'                     v' = v* + gamma dt a'           (corrector)

and the effective matrix of the implicit step is M + gamma dt C + beta dt^2 K. The functions
work on floats and on numpy arrays of any shape alike (element-wise); the compiled step
(:mod:`~drill_twin.integrator.newmark_kernel`) compiles the same functions into its loops
(:func:`~drill_twin.numerics.compiled.inline`), and the rig's drives
(:mod:`drill_twin.rig`) call them on their rows of the reduced state.
"""
from __future__ import annotations

BETA = 0.25
"""Newmark's beta (average acceleration)."""
GAMMA = 0.5
"""Newmark's gamma (average acceleration)."""


def predicted_displacement(d, v, a, dt):
    """Return the predicted displacement d* = d + dt v + (1/2 - beta) dt^2 a (dt in s)."""
    return d + dt * v + (0.5 - BETA) * dt * dt * a


def predicted_velocity(v, a, dt):
    """Return the predicted velocity v* = v + (1 - gamma) dt a."""
    return v + (1.0 - GAMMA) * dt * a


def corrected_displacement(d_predicted, a_new, dt):
    """Return the corrected displacement d' = d* + beta dt^2 a'."""
    return d_predicted + BETA * dt * dt * a_new


def corrected_velocity(v_predicted, a_new, dt):
    """Return the corrected velocity v' = v* + gamma dt a'."""
    return v_predicted + GAMMA * dt * a_new


def effective_matrix(mass, damping, stiffness, dt):
    """Return M + gamma dt C + beta dt^2 K, the matrix of the implicit step's linear part."""
    return mass + GAMMA * dt * damping + BETA * dt * dt * stiffness
