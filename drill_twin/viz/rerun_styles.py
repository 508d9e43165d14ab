"""
The static parts of the twin's rerun views: series names, colours and widths, the borehole.

Logged once per recording (``static=True``) by :func:`log_styles`, before the data of
:mod:`~drill_twin.viz.rerun_series`. The lateral views look down the hole: v to the right, w down
the screen (x, the string axis, points into the screen, so (x, v, w) is right-handed).
"""
from __future__ import annotations

import warnings

import numpy as np
import rerun as rr

from drill_twin.viz.rerun_entities import (
    BAND, BAND_LINE_WIDTH, BAND_LINES, BLUE, DARK, ENSEMBLE_QUANTITIES, GERM_ENTRIES, GREEN,
    GREY, LAW_ENTRIES, LIGHT, ORANGE, PURPLE, RED, station_entity, StringGeometry, TRAIL_S)

_LINES = {
    # entity: (legend name, colour, width)
    'bit/depth': ('bit depth', BLUE, 2.0),
    'bit/rop': ('ROP (instant)', BLUE, 1.5),
    'kpi/rop': ('ROP (window mean)', LIGHT, 2.5),
    'bit/speed': ('bit', BLUE, 1.5),
    'top/speed': ('surface (top drive)', ORANGE, 2.5),
    'bit/wob': ('WOB', BLUE, 1.5),
    'bit/tob': ('TOB', BLUE, 1.5),
    'top/torque': ('surface torque', ORANGE, 1.5),
    'top/hook_load': ('hook load', ORANGE, 2.0),
    'kpi/ssi': ('SSI', PURPLE, 2.0),
    'kpi/mse': ('MSE', GREEN, 2.0),
    'contact/max_force': ('largest wall force', RED, 1.5),
    'diagnostics/real_time_factor': ('real-time factor', BLUE, 2.0),
    'diagnostics/tick_time': ('tick', BLUE, 1.5),
    'diagnostics/tick_time_max': ('slowest tick (last 100)', RED, 1.5),
    'diagnostics/iterations': ('mean model', BLUE, 1.5),
    'diagnostics/ensemble_iterations': ('ensemble', ORANGE, 1.5),
    'diagnostics/resets': ('member resets', RED, 2.0),
}
_POINTS = {
    'cmd/top_drive_speed': ('command', LIGHT, 5.0),
    'cmd/hook_load': ('command', LIGHT, 5.0),
}
LATERAL_HELP = (
    'Orbits look down the hole at the cursor time: black the borehole wall, orange the pipe '
    '(or collar), blue the path of its centre over the last {trail:g} s, red where the '
    'centre is when the pipe touches the wall. Bar charts: along the string, at the cursor.')


def log_styles(recording, geometry: StringGeometry) -> None:
    """Log the static parts: series names, colours and widths, the borehole drawings."""
    for entity, (name, colour, width) in _LINES.items():
        recording.log(entity, rr.SeriesLines(names=name, colors=colour, widths=width),
                      static=True)
    for entity, (name, colour, size) in _POINTS.items():
        recording.log(entity, rr.SeriesPoints(names=name, colors=colour, marker_sizes=size,
                                              markers='circle'), static=True)
    for key in ENSEMBLE_QUANTITIES:
        recording.log(f'ensemble/{key}/band', rr.SeriesLines(
            names=['95 % band'] * BAND_LINES, colors=[BAND] * BAND_LINES,
            widths=[BAND_LINE_WIDTH] * BAND_LINES), static=True)
        recording.log(f'ensemble/{key}/mean', rr.SeriesLines(
            names='ensemble mean', colors=BLUE, widths=2.5), static=True)
        recording.log(f'ensemble/{key}/model', rr.SeriesLines(
            names='mean model', colors=ORANGE, widths=1.2), static=True)
    for group, entries in (('germ', GERM_ENTRIES), ('law', LAW_ENTRIES)):
        for key, (name, colour) in entries.items():
            log_bound_styles(recording, f'ensemble/{group}/{key}', name, colour)
    for x_m, outer_m, gap_m in zip(geometry.stations_m, geometry.station_outer_radius_m,
                                   geometry.station_clearance_m):
        _log_cross_section(recording, station_entity(x_m), geometry.borehole_radius_m,
                           outer_m, gap_m)
        recording.log(f'{station_entity(x_m)}/radial', rr.SeriesLines(
            names='deflection', colors=BLUE, widths=1.5), static=True)
        recording.log(f'{station_entity(x_m)}/clearance', rr.SeriesLines(
            names='wall contact', colors=RED, widths=2.0), static=True)
    _log_data_styles(recording, geometry)
    recording.log('lateral/help', rr.TextDocument(LATERAL_HELP.format(trail=TRAIL_S),
                                                  media_type='text/plain'), static=True)


def log_bound_styles(recording, entity: str, name: str, colour, mean_width: float = 2.0,
                     bound_width: float = 0.8) -> None:
    """Log the styles of an estimate ``<entity>/mean`` and its 95 % ``<entity>/{lower,upper}``."""
    recording.log(f'{entity}/mean', rr.SeriesLines(
        names=f'{name} (mean)', colors=colour, widths=mean_width), static=True)
    for bound in ('lower', 'upper'):
        recording.log(f'{entity}/{bound}', rr.SeriesLines(
            names=f'{name} (95 %)', colors=colour, widths=bound_width), static=True)


def _log_cross_section(recording, entity: str, borehole_m: float, outer_m: float,
                       gap_m: float) -> None:
    """Borehole wall, the circle where the pipe's centre touches it, axes, a scale bar."""
    wall_mm, gap_mm = 1e3 * borehole_m, 1e3 * gap_m
    recording.log(f'{entity}/wall', rr.Ellipses2D(
        centers=[(0.0, 0.0)], half_sizes=[(wall_mm, wall_mm)], colors=DARK, line_radii=1.5,
        draw_order=1.0), static=True)
    recording.log(f'{entity}/contact_circle', rr.Ellipses2D(
        centers=[(0.0, 0.0)], half_sizes=[(gap_mm, gap_mm)], colors=RED, line_radii=0.6,
        draw_order=2.0), static=True)
    tick = _scale_mm(wall_mm)
    top = -wall_mm - 4.0                     # scale bar and axis names in the top corners,
    recording.log(f'{entity}/axes', rr.LineStrips2D(   # outside the wall circle
        [[(-wall_mm, 0.0), (wall_mm, 0.0)], [(0.0, -wall_mm), (0.0, wall_mm)],
         [(-wall_mm - 10.0, top), (-wall_mm - 10.0 + tick, top)]],
        colors=[GREY, GREY, DARK], radii=[0.3, 0.3, 1.2], draw_order=0.5), static=True)
    # (a pointer resting in the middle of a view shows a tooltip: no labels there)
    recording.log(f'{entity}/labels', rr.Points2D(
        [(wall_mm - 10.0, top + 2.0), (-wall_mm - 10.0 + tick / 2, top + 14.0)],
        radii=0.01, colors=DARK, labels=['v →  w ↓', f'{tick:g} mm'], show_labels=True),
        static=True)
    del outer_m                                          # the pipe is drawn with the data


def _scale_mm(length_mm: float) -> float:
    """Return a round scale-bar length about a third of ``length_mm``."""
    for step in (500, 200, 100, 50, 20, 10, 5, 2, 1):
        if step <= length_mm / 2.5:
            return float(step)
    return 1.0


def _log_data_styles(recording, geometry: StringGeometry) -> None:
    """Log the static colours of the orbits, pipes and bar charts."""
    _log_bar_axes(recording, geometry)
    for x_m in geometry.stations_m:
        entity = station_entity(x_m)
        recording.log(f'{entity}/orbit', rr.LineStrips2D.from_fields(
            colors=BLUE, radii=0.8, draw_order=3.0), static=True)
        recording.log(f'{entity}/pipe', rr.Ellipses2D.from_fields(
            colors=ORANGE, line_radii=1.5, draw_order=4.0), static=True)


def _log_bar_axes(recording, geometry: StringGeometry) -> None:
    """Log the abscissa (depth, m), bar widths and colours of the along-the-depth charts."""
    nodes = geometry.node_x_m
    width = 0.8 * float(np.min(np.diff(nodes))) if nodes.size > 1 else 1.0
    charts = [('along/contact_force', nodes, width, RED)]
    if geometry.stations_m:
        charts.append(('along/deflection', np.asarray(geometry.stations_m), 40.0, BLUE))
    for entity, abscissa, bar_width, colour in charts:
        with warnings.catch_warnings():       # from_fields warns about the absent values
            warnings.simplefilter('ignore')
            chart = rr.BarChart.from_fields(
                abscissa=abscissa, widths=np.full(abscissa.size, bar_width, dtype=np.float32),
                color=colour)
        recording.log(entity, chart, static=True)
