"""
The blueprint of the twin's rerun views: the tabs and the plots in each.

Tabs (:data:`~drill_twin.viz.rerun_entities.TABS`): the bit, the driller's (surface) view, the
lateral motion (orbits in the borehole, contact force and deflection along the depth), the
ensemble (or an offline estimate) and diagnostics. Each plot names the entities it shows.
"""
from __future__ import annotations

from typing import Sequence

import rerun.blueprint as rrb

from drill_twin import interface as itf
from drill_twin.viz.rerun_entities import (
    CHANNEL_UNITS, ENSEMBLE_QUANTITIES, GERM_ENTRIES, LAW_ENTRIES, station_entity,
    StringGeometry, tab_index, TAB_TITLES, TIMELINE, TRAIL_S)


def _legend(visible: bool = True):
    return rrb.PlotLegend(corner='LeftTop', visible=visible)


def _series(name: str, contents: Sequence[str], *, legend: bool = False, **kwargs):
    return rrb.TimeSeriesView(name=name, origin='/', contents=list(contents),
                              plot_legend=_legend(legend), **kwargs)


def _bit_tab():
    return rrb.Grid(
        _series('Bit depth (m)', ['bit/depth']),
        _series('ROP (m/h): instant (blue), window mean (white)', ['bit/rop', 'kpi/rop']),
        _series('Speed (rpm): bit (blue), surface (orange)', ['bit/speed', 'top/speed']),
        _series('Weight on bit (kN)', ['bit/wob']),
        _series('Torque on bit (kN·m)', ['bit/tob']),
        _series('Stick-slip severity SSI (-)', ['kpi/ssi']),
        grid_columns=2, name=TAB_TITLES['bit'])


def _driller_tab():
    return rrb.Grid(
        _series('Surface speed (rpm), commands as dots', ['top/speed', 'cmd/top_drive_speed']),
        _series('Surface torque (kN·m)', ['top/torque']),
        _series('Hook load (kN), commands as dots', ['top/hook_load', 'cmd/hook_load']),
        _series('Weight on bit (kN)', ['bit/wob']),
        _series('ROP (m/h): instant (blue), window mean (white)', ['bit/rop', 'kpi/rop']),
        _series('Stick-slip severity SSI (-)', ['kpi/ssi']),
        grid_columns=2, name=TAB_TITLES['driller'])


def _orbit_view(geometry: StringGeometry, index: int):
    x_m = geometry.stations_m[index]
    entity = station_entity(x_m)
    reach = 1e3 * geometry.borehole_radius_m * 1.1
    trail = rrb.VisibleTimeRanges(timeline=TIMELINE,
                                  start=rrb.TimeRangeBoundary.cursor_relative(seconds=-TRAIL_S),
                                  end=rrb.TimeRangeBoundary.cursor_relative())
    return rrb.Spatial2DView(
        name=f'Orbit at {itf.station_label(x_m)}',
        origin=entity, contents=[f'{entity}/{part}' for part in (
            'wall', 'contact_circle', 'axes', 'labels', 'orbit', 'pipe')],
        visual_bounds=rrb.VisualBounds2D(x_range=[-reach, reach],
                                         y_range=[-reach - 10.0, reach]),
        background=rrb.Background(color=(255, 255, 255)),
        overrides={f'{entity}/orbit': [trail]})


def _lateral_tab(geometry: StringGeometry):
    views = []
    for index in range(len(geometry.stations_m)):
        views.append(_orbit_view(geometry, index))
    views.append(rrb.BarChartView(name='Wall contact force (kN) vs depth (m)',
                                  origin='along/contact_force', plot_legend=_legend(False)))
    for x_m in geometry.stations_m:
        entity = station_entity(x_m)
        views.append(_series(f'Radial deflection at {itf.station_label(x_m)} (mm)',
                             [f'{entity}/radial', f'{entity}/clearance']))
    views.append(rrb.BarChartView(name='Deflection, % of clearance, vs depth (m)',
                                  origin='along/deflection', plot_legend=_legend(False)))
    if not geometry.stations_m:
        views.append(rrb.TextDocumentView(name='No measurement stations in this log',
                                          origin='lateral'))
    grid = rrb.Grid(*views, grid_columns=len(geometry.stations_m) + 1,
                    row_shares=[3, 2] if geometry.stations_m else None)
    return rrb.Vertical(
        grid, rrb.Horizontal(
            _series('Largest wall contact force along the string (kN)', ['contact/max_force']),
            rrb.TextDocumentView(name='How to read', origin='lateral/help'),
            column_shares=[1, 1]),
        row_shares=[3, 1], name=TAB_TITLES['lateral'])


def _ensemble_tab(assimilation: bool = False, law: bool = False, bias_channels=(),
                  estimate: bool = False):
    views = []
    if estimate:                    # an offline estimate: its bit speed, the truth, open loop
        views.append(_series(
            'Bit speed (rpm): estimate (blue), its 95 % band (shaded), truth (green), '
            'open loop (grey: mean, 95 %)',
            ['ensemble/speed/band', 'ensemble/speed/open_loop/lower',
             'ensemble/speed/open_loop/upper', 'ensemble/speed/open_loop/mean',
             'ensemble/speed/truth', 'ensemble/speed/mean']))
    for key, (title, unit) in ({} if estimate else ENSEMBLE_QUANTITIES).items():
        views.append(_series(
            f'{title} ({unit}): ensemble mean (blue), 95 % band (shaded), mean model (orange)',
            [f'ensemble/{key}/band', f'ensemble/{key}/model', f'ensemble/{key}/mean']))
    if assimilation:
        views.append(_series(
            'Estimated bit-rock germ: G11 (blue), G12 (orange), G22 (green); mean, 95 % (thin)',
            [f'ensemble/germ/{key}/{b}' for key in GERM_ENTRIES
             for b in ('lower', 'upper', 'mean')]))
    if assimilation and law:
        views.append(_series(
            'Law factors a1..a5 (blue, orange, green, red, purple; 1 = configured), '
            'mean, 95 % (thin)',
            [f'ensemble/law/{key}/{b}' for key in LAW_ENTRIES
             for b in ('lower', 'upper', 'mean')]))
    for channel in bias_channels if assimilation else ():
        views.append(_series(
            f'Estimated {channel} sensor bias ({CHANNEL_UNITS.get(channel, "SI")}): mean, '
            '95 % (thin)', [f'ensemble/bias/{channel}/{b}' for b in ('lower', 'upper', 'mean')]))
    return rrb.Vertical(*views, name=TAB_TITLES['ensemble'])


def _diagnostics_tab():
    return rrb.Horizontal(
        rrb.Vertical(
            _series('Real-time factor (twin s per wall s)', ['diagnostics/real_time_factor']),
            _series('Tick wall time (ms): last (blue), slowest (red)',
                    ['diagnostics/tick_time', 'diagnostics/tick_time_max']),
            _series('Newton iterations per step: mean model (blue), ensemble (orange)',
                    ['diagnostics/iterations', 'diagnostics/ensemble_iterations']),
            _series('Member resets so far', ['diagnostics/resets'])),
        rrb.Vertical(
            rrb.TextLogView(name='Events (impacts, lift-offs, resets, rejected commands)',
                            origin='diagnostics/events'),
            rrb.TextLogView(name='/rosout', origin='rosout')),
        name=TAB_TITLES['diagnostics'])


def twin_blueprint(geometry: StringGeometry, *, active_tab: int | str = 0,
                   follow: bool = True, assimilation: bool = False, law: bool = False,
                   bias_channels=(), estimate: bool = False):
    """
    Build the rerun blueprint of the twin's views (tabs :data:`TABS`).

    :param active_tab: the tab shown first (index or name).
    :param follow: start with the time cursor following the newest data (at the end of a
        recorded run, moving with a live one).
    :param assimilation: the ensemble tab shows the estimated germ too.
    :param law: and the estimated factors of the law's coefficients (parameters 'law').
    :param bias_channels: and the estimated biases of these channels' sensors.
    :param estimate: the log is an offline estimate (EST.mcap): the ensemble tab shows its bit
        speed with the truth and the open loop instead of the twin's ensemble.
    """
    tabs = rrb.Tabs(_bit_tab(), _driller_tab(), _lateral_tab(geometry),
                    _ensemble_tab(assimilation, law, tuple(bias_channels), estimate),
                    _diagnostics_tab(), active_tab=tab_index(active_tab))
    return rrb.Blueprint(tabs,
                         rrb.TimePanel(timeline=TIMELINE, state='collapsed',
                                       play_state='following' if follow else 'paused'),
                         rrb.BlueprintPanel(state='collapsed'),
                         rrb.SelectionPanel(state='collapsed'), auto_views=False)
