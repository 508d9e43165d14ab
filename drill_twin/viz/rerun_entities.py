"""
What the twin's rerun views show, by name: entities, timeline, tabs, units, colours, geometry.

The vocabulary shared by the static styles (:mod:`~drill_twin.viz.rerun_styles`), the data
(:mod:`~drill_twin.viz.rerun_series`) and the blueprint (:mod:`~drill_twin.viz.rerun_blueprint`);
it does not import rerun, so that the command line can offer the tab names cheaply.

Entities (under ``/``): ``bit/*``, ``top/*``, ``cmd/*``, ``kpi/*``, ``ensemble/germ/<g>/{mean,
lower,upper}`` and ``ensemble/law/<a>/{mean,lower,upper}`` (assimilation), ``ensemble/<q>/{band,
mean,model}``, ``lateral/<station>/*`` (orbit, pipe, wall, radial deflection),
``along/*`` (contact force and deflection along the depth), ``diagnostics/*``, ``rosout``.
Everything is on one duration timeline, ``run time``, in seconds of the run, in the units a
drilling engineer reads: rpm, kN, kN·m, m/h, mm.
"""
from __future__ import annotations

from dataclasses import dataclass
import math
from typing import Sequence

import numpy as np

from drill_twin import interface as itf
from drill_twin.fem.mesh import build_mesh

APPLICATION_ID = 'drill_twin'
TIMELINE = 'run time'
"""The duration timeline of every view: seconds since the start of the run."""

TABS = ('bit', 'driller', 'lateral', 'ensemble', 'diagnostics')
"""Tab names for ``--tab`` (and ``active_tab``), in display order."""
TAB_TITLES = {'bit': 'Bit', 'driller': 'Driller', 'lateral': 'Lateral motion',
              'ensemble': 'Ensemble', 'diagnostics': 'Diagnostics'}

RPM_PER_RAD_PER_S = 60.0 / (2.0 * math.pi)
BAND_LINES = 48
"""Lines filling the 95 % band (rerun has no filled area between two series)."""
BAND_LINE_WIDTH = 6.0
TRAIL_S = 10.0
"""Seconds of orbit drawn behind the cursor."""

# Colours (RGB)
BLUE, ORANGE, GREEN, RED, GREY, DARK = ((40, 110, 230), (245, 140, 40), (60, 170, 90),
                                        (225, 60, 60), (140, 140, 140), (70, 70, 70))
PURPLE = (150, 90, 200)
LIGHT = (225, 225, 225)        # on rerun's dark plot background
BAND = (175, 200, 245)


# -- geometry --------------------------------------------------------------------------------

@dataclass(frozen=True)
class StringGeometry:
    """What the lateral views draw: borehole, node depths and the stations' pipe size (m)."""

    borehole_radius_m: float
    node_x_m: np.ndarray
    stations_m: tuple[float, ...]
    station_outer_radius_m: tuple[float, ...]

    @property
    def station_clearance_m(self) -> tuple[float, ...]:
        """Radial gap between pipe and wall at each station (m): the centre's wall contact."""
        return tuple(self.borehole_radius_m - r for r in self.station_outer_radius_m)

    @classmethod
    def from_config(cls, config, stations_m: Sequence[float] | None = None) -> 'StringGeometry':
        """
        From a :class:`~drill_twin.config.schema.DrillStringConfig`.

        Stations default to ``config.output.stations_m``.
        """
        mesh = build_mesh(config)
        stations = tuple(float(x) for x in (config.output.stations_m if stations_m is None
                                            else stations_m))
        outer = []
        for x_m in stations:
            element, _ = mesh.locate(min(max(x_m, 0.0), mesh.total_length_m))
            outer.append(float(mesh.outer_radius_m[element]))
        return cls(config.borehole.diameter_m / 2.0, np.asarray(mesh.node_x_m, dtype=float),
                   stations, tuple(outer))


def station_entity(x_m: float) -> str:
    """Entity of a station's lateral views, e.g. 'lateral/x700m' (topic-safe name)."""
    return f'lateral/{itf.station_name(x_m)}'


def tab_index(tab: int | str) -> int:
    """Index of a tab given by index or (case-insensitive) name; ValueError if unknown."""
    if isinstance(tab, int):
        if not 0 <= tab < len(TABS):
            raise ValueError(f'tab index {tab} is not in 0..{len(TABS) - 1}')
        return tab
    name = str(tab).strip().lower()
    for i, key in enumerate(TABS):
        if name in (key, TAB_TITLES[key].lower()):
            return i
    raise ValueError(f'unknown tab {tab!r}; one of: {", ".join(TABS)}')


ENSEMBLE_QUANTITIES = {
    # key: (title, unit)
    'speed': ('Bit speed', 'rpm'),
    'rop': ('ROP', 'm/h'),
    'wob': ('WOB', 'kN'),
}
GERM_ENTRIES = {'g11': ('G11', BLUE), 'g12': ('G12', ORANGE), 'g22': ('G22', GREEN)}
"""The estimated bit-rock germ's entries (assimilation), in message order, and their colours."""
LAW_ENTRIES = {'a1': ('a1', BLUE), 'a2': ('a2', ORANGE), 'a3': ('a3', GREEN),
               'a4': ('a4', RED), 'a5': ('a5', PURPLE)}
"""The estimated factors of the law's a1 ... a5 (assimilation, parameters 'law'), in message
order, and their colours."""
HEALTH_ENTITIES = {'real_time_factor': 'diagnostics/real_time_factor',
                   'tick_time_ms': 'diagnostics/tick_time',
                   'tick_time_max_ms': 'diagnostics/tick_time_max',
                   'iterations_per_step': 'diagnostics/iterations',
                   'ensemble_iterations_per_step': 'diagnostics/ensemble_iterations',
                   'resets': 'diagnostics/resets'}
"""The twin's health figures (keys of its /diagnostics status), in this order, and their
entities."""
CHANNEL_UNITS = {'top_speed': 'rad/s', 'top_torque': 'N m', 'hook_load': 'N',
                 'block_position': 'm', 'bit_speed': 'rad/s', 'torque_on_bit': 'N m',
                 'weight_on_bit': 'N'}
"""The SI unit of each measured channel (assimilation.measurements), for the sensor biases."""
