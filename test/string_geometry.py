"""The drill string's section geometry written out from the configuration (independent of fem)."""
from __future__ import annotations

import math

import numpy as np


def area_m2(section) -> float:
    """Return the cross-section's steel area pi (D_o^2 - D_i^2) / 4 (m^2)."""
    return math.pi / 4 * (section.outer_diameter_m ** 2 - section.inner_diameter_m ** 2)


def node_masses_and_clearances(config) -> tuple[np.ndarray, np.ndarray]:
    """
    Return each node's steel mass (kg) and clearance to the borehole wall (m), (n_nodes,) each.

    The elements are the sections' equal parts, top to bottom; a node takes half of each
    element touching it; its clearance is the hole's radius less the largest outer radius of
    those elements.
    """
    element_mass, element_radius = [], []
    for s in config.sections:
        element_mass += [s.density_kg_per_m3 * area_m2(s) * s.length_m / s.elements] * s.elements
        element_radius += [s.outer_diameter_m / 2] * s.elements
    element_mass, element_radius = np.array(element_mass), np.array(element_radius)
    mass, radius = np.zeros(element_mass.size + 1), np.zeros(element_mass.size + 1)
    mass[:-1] += 0.5 * element_mass
    mass[1:] += 0.5 * element_mass
    radius[:-1] = element_radius
    radius[1:] = np.maximum(radius[1:], element_radius)
    return mass, config.borehole.diameter_m / 2 - radius
