"""Looking at the twin's MCAP logs in rerun (0.41): a blueprint, ``.rrd`` conversion, viewer.

How rerun's MCAP importer lays out a ROS 2 log (``ros2msg`` schemas, CDR messages):

- every topic becomes the entity of the same path ('/drill_twin/bit/state');
- timelines ``message_log_time``, ``message_publish_time`` and, for messages with a
  header, ``ros2_timestamp`` (the header stamp);
- ``sensor_msgs/JointState`` becomes three child entities ``<topic>/position``,
  ``<topic>/velocity`` and ``<topic>/effort``, each a ``Scalars`` batch with one instance per
  joint in message order (series named after the joints); the blueprint picks joints by
  position, so the twin must publish them in the order of
  :data:`~drill_twin.recording.topics.BIT_JOINTS` and ``TOP_JOINTS``;
- ``sensor_msgs/Imu`` becomes one ``Scalars`` batch [gyroscope x, y, z, accelerometer x, y, z];
- ``std_msgs/Float64MultiArray`` becomes one ``Scalars`` batch ([0], [1], ...);
- ``rcl_interfaces/Log`` on /rosout becomes a ``TextLog``;
- other types (Float64, WrenchStamped, Vector3Stamped, DiagnosticArray, Clock) are stored as
  one struct component '<pkg>.msg.<Type>:message'; a ``SeriesLines`` visualizer with a
  component mapping (source component plus a jq-like selector such as '.wrench.force.x' onto
  ``Scalars:scalars``) plots a field of it.

Every view uses the ``message_log_time`` timeline, the only one all topics have (Float64
messages have no header).  rerun itself is imported only by the functions that need it.
"""
from __future__ import annotations

import os
from pathlib import Path
import re
import shutil
import subprocess
import sys
import tempfile
from typing import Iterable, Sequence

from drill_twin import interface as itf

APPLICATION_ID = 'drill_twin'
TIMELINE = 'message_log_time'
"""Timeline of every view: the MCAP log time, which every message has."""

_STATION = re.compile(r'^/drill_twin/vibration/x(\d+)(?:p(\d+))?m/imu$')

# Which joint of a JointState field to show; the order is topics.BIT_JOINTS / TOP_JOINTS.
_FIRST, _SECOND = (True, False), (False, True)

# Colours (RGB)
BLUE, ORANGE, GREEN, RED, GREY = (66, 135, 245), (245, 147, 66), (80, 190, 100), \
    (230, 70, 70), (150, 150, 150)
BAND = (120, 170, 250)


def joint_entity(topic: str, field: str) -> str:
    """Entity of one JointState field ('position', 'velocity', 'effort') of a topic."""
    return f'{topic}/{field}'


def message_component(type_name: str) -> str:
    """Component holding a whole reflected message, e.g. 'std_msgs.msg.Float64:message'."""
    return type_name.replace('/', '.') + ':message'


def stations_from_topics(topic_names: Iterable[str]) -> list[float]:
    """Measurement-station depths (m) named by the vibration IMU topics of a log, sorted."""
    stations = []
    for topic in topic_names:
        match = _STATION.match(topic)
        if match:
            whole, fraction = match.groups()
            stations.append(float(f'{whole}.{fraction}' if fraction else whole))
    return sorted(stations)


# -- blueprint ---------------------------------------------------------------------------------

def _field_mapping(type_name: str, selector: str):
    """Map one field (jq-like ``selector``) of a reflected message onto the plotted scalars."""
    from rerun.blueprint.encodings import ComponentSourceKind, VisualizerComponentMapping

    return VisualizerComponentMapping(target='Scalars:scalars',
                                      source_kind=ComponentSourceKind.SourceComponent,
                                      source_component=message_component(type_name),
                                      selector=selector)


def _field_line(name: str, type_name: str, selector: str, color=None):
    """Make a SeriesLines visualizer plotting one field of a reflected message."""
    import rerun as rr

    return rr.SeriesLines(names=name, colors=color).visualizer(
        mappings=[_field_mapping(type_name, selector)])


def _field_points(name: str, type_name: str, selector: str, color=None):
    """Make a SeriesPoints visualizer marking one field of each message (commands)."""
    import rerun as rr

    return rr.SeriesPoints(names=name, colors=color, marker_sizes=4.0).visualizer(
        mappings=[_field_mapping(type_name, selector)])


def _joint_line(names: Sequence[str], visible: Sequence[bool], color=None, width=None):
    """Make a SeriesLines override showing only chosen joints of a JointState field."""
    import rerun as rr

    colors = None if color is None else [color] * len(names)
    widths = None if width is None else [width] * len(names)
    return rr.SeriesLines(names=list(names), visible_series=list(visible), colors=colors,
                          widths=widths)


def _plot(name: str, overrides: dict, **kwargs):
    import rerun.blueprint as rrb

    return rrb.TimeSeriesView(name=name, origin='/', contents=list(overrides),
                              overrides=overrides, **kwargs)


def _float64_plot(name: str, topic: str, label: str, color=BLUE):
    return _plot(name, {topic: _field_line(label, 'std_msgs/msg/Float64', '.data', color)})


def _bit_tab():
    import rerun.blueprint as rrb

    state = itf.BIT_STATE
    wrench = 'geometry_msgs/msg/WrenchStamped'
    return rrb.Grid(
        _plot('Depth (m)', {joint_entity(state, 'position'):
                            _joint_line(['depth', 'bit angle'], _FIRST, BLUE)}),
        _plot('ROP (m/s)', {joint_entity(state, 'velocity'):
                            _joint_line(['ROP', 'bit speed'], _FIRST, BLUE)}),
        _plot('Bit and top-drive speed (rad/s)', {
            joint_entity(state, 'velocity'): _joint_line(['ROP', 'bit speed'], _SECOND, BLUE),
            joint_entity(itf.TOP_STATE, 'velocity'):
                _joint_line(['top-drive speed', 'block speed'], _FIRST, ORANGE)}),
        _plot('WOB (N)', {
            joint_entity(state, 'effort'): _joint_line(['WOB (state)', 'TOB'], _FIRST, BLUE, 4.0),
            itf.BIT_WRENCH: _field_line('WOB (wrench force.x)', wrench, '.wrench.force.x',
                                        ORANGE)}),
        _plot('TOB (N m)', {
            joint_entity(state, 'effort'): _joint_line(['WOB', 'TOB (state)'], _SECOND, BLUE, 4.0),
            itf.BIT_WRENCH: _field_line('TOB (wrench torque.x)', wrench, '.wrench.torque.x',
                                        ORANGE)}),
        _float64_plot('Stick-slip severity (-)', itf.KPI_STICK_SLIP, 'stick-slip severity'),
        grid_columns=2, name='Bit')


def _band_plot(name: str, field: str, visible, labels: Sequence[str]):
    """Mean and 2.5/97.5 % bounds of one JointState quantity, overlaid."""
    overrides = {}
    for topic, suffix, color, width in ((itf.ENSEMBLE_LOWER, '2.5 %', BAND, 1.0),
                                        (itf.ENSEMBLE_UPPER, '97.5 %', BAND, 1.0),
                                        (itf.ENSEMBLE_MEAN, 'mean', BLUE, 2.5)):
        names = [f'{label} {suffix}' for label in labels]
        overrides[joint_entity(topic, field)] = _joint_line(names, visible, color, width)
    return _plot(name, overrides)


def _ensemble_tab():
    import rerun.blueprint as rrb

    return rrb.Vertical(
        _band_plot('Ensemble bit speed (rad/s): mean, 2.5-97.5 %', 'velocity', _SECOND,
                   ('ROP', 'bit speed')),
        _band_plot('Ensemble ROP (m/s): mean, 2.5-97.5 %', 'velocity', _FIRST,
                   ('ROP', 'bit speed')),
        _band_plot('Ensemble WOB (N): mean, 2.5-97.5 %', 'effort', _FIRST, ('WOB', 'TOB')),
        name='Ensemble')


def _vibration_tab(stations_m: Sequence[float]):
    import rerun.blueprint as rrb

    imu_names = ['gyro x', 'gyro y', 'gyro z', 'acc x', 'acc y', 'acc z']
    vector = 'geometry_msgs/msg/Vector3Stamped'
    views = []
    for x_m in stations_m:
        label = f'{x_m:g} m'
        imu, displacement = itf.vibration_imu_topic(x_m), itf.vibration_displacement_topic(x_m)
        views.append(_plot(f'Acceleration at {label} (m/s²)', {imu: _joint_line(
            imu_names, (False, False, False, True, True, True))}))
        views.append(_plot(f'Angular speed at {label} (rad/s)', {imu: _joint_line(
            imu_names, (True, True, True, False, False, False))}))
        views.append(rrb.TimeSeriesView(
            name=f'Lateral displacement at {label} (m)', origin='/', contents=[displacement],
            overrides={displacement: [_field_line('v (y)', vector, '.vector.y', BLUE),
                                      _field_line('w (z)', vector, '.vector.z', ORANGE)]}))
    if not views:
        views.append(rrb.TextDocumentView(name='No measurement stations in this log',
                                          origin='/drill_twin/vibration'))
    return rrb.Grid(*views, grid_columns=3, name='Vibration')


def _contact_kpi_tab():
    import rerun.blueprint as rrb

    return rrb.Grid(
        rrb.TimeSeriesView(name='Contact forces (N)', origin=itf.CONTACT_FORCES),
        _float64_plot('Stick-slip severity (-)', itf.KPI_STICK_SLIP, 'stick-slip severity'),
        _float64_plot('Mechanical specific energy (Pa)', itf.KPI_MSE, 'MSE'),
        _float64_plot('ROP (m/h)', itf.KPI_ROP, 'ROP'),
        grid_columns=2, name='Contact & KPIs')


def _top_tab():
    import rerun.blueprint as rrb

    top = itf.TOP_STATE
    float64 = 'std_msgs/msg/Float64'
    names_top, names_hook = ['top-drive', 'hook'], ['top-drive', 'hook']
    return rrb.Grid(
        _plot('Top-drive speed (rad/s)', {
            joint_entity(top, 'velocity'): _joint_line(names_top, _FIRST, BLUE),
            itf.CMD_TOP_DRIVE_SPEED: _field_points('command', float64, '.data', ORANGE)}),
        _plot('Top-drive torque (N m)', {
            joint_entity(top, 'effort'): _joint_line(names_top, _FIRST, BLUE)}),
        _plot('Hook load (N)', {
            joint_entity(top, 'effort'): _joint_line(names_hook, _SECOND, BLUE),
            itf.CMD_HOOK_LOAD: _field_points('command', float64, '.data', ORANGE)}),
        _plot('Block travel (m)', {
            joint_entity(top, 'position'): _joint_line(names_hook, _SECOND, BLUE)}),
        grid_columns=2, name='Top drive')


def _diagnostics_tab():
    import rerun.blueprint as rrb
    from rerun.blueprint.archetypes import DataframeQuery
    from rerun.blueprint.components import ComponentColumnSelector

    message = ComponentColumnSelector(
        entity_path=itf.DIAGNOSTICS,
        component=message_component('diagnostic_msgs/msg/DiagnosticArray'))
    query = DataframeQuery(timeline=TIMELINE, select=[TIMELINE, message],
                           auto_scroll=True)
    return rrb.DataframeView(name='/diagnostics', origin=itf.DIAGNOSTICS, query=query)


TABS = ('Bit', 'Ensemble', 'Vibration', 'Contact & KPIs', 'Top drive', '/diagnostics')


def twin_blueprint(stations_m: Sequence[float] = (), *, active_tab: int | str = 0):
    """Build the rerun blueprint for a twin log with stations at ``stations_m`` (m).

    Tabs (see :data:`TABS`): bit state and wrench; ensemble mean with 2.5/97.5 % bounds;
    vibration per station; contact forces and KPIs; top drive with its commands;
    /diagnostics.  Below the tabs, /rosout stays in view.
    """
    import rerun.blueprint as rrb

    if isinstance(active_tab, str):
        active_tab = TABS.index(active_tab)          # rerun matches names of views only
    tabs = rrb.Tabs(_bit_tab(), _ensemble_tab(), _vibration_tab(list(stations_m)),
                    _contact_kpi_tab(), _top_tab(), _diagnostics_tab(), active_tab=active_tab)
    rosout = rrb.TextLogView(name='/rosout', origin=itf.ROSOUT)
    return rrb.Blueprint(rrb.Vertical(tabs, rosout, row_shares=[5, 1]),
                         rrb.TimePanel(timeline=TIMELINE, state='collapsed'),
                         rrb.SelectionPanel(state='collapsed'), auto_views=False)


# -- files and viewer --------------------------------------------------------------------------

def _stations(mcap_path, stations_m):
    if stations_m is not None:
        return [float(x) for x in stations_m]
    from drill_twin.recording.reader import topics

    return stations_from_topics(topics(mcap_path))


def save_rrd(mcap_path: str | os.PathLike, rrd_path: str | os.PathLike,
             stations_m: Sequence[float] | None = None, *, active_tab: int | str = 0,
             application_id: str = APPLICATION_ID) -> Path:
    """Convert a twin log (an MCAP file or a bag directory of splits) into a self-contained
    ``.rrd`` holding the twin's blueprint.

    A file without footer (the recorder was killed) is first recovered into a temporary
    complete copy (:func:`~drill_twin.recording.recovery.recover_log`), since rerun's
    importer needs the summary.

    :param stations_m: measurement-station depths (m); default: read from the log's topics.
    :param active_tab: index or name (see :data:`TABS`) of the tab shown first.
    :returns: the ``.rrd`` path.
    """
    from drill_twin.recording.reader import is_complete, log_files
    from drill_twin.recording.recovery import recover_log

    mcap_path, rrd_path = Path(mcap_path), Path(rrd_path)
    if not mcap_path.exists():
        raise FileNotFoundError(mcap_path)
    files = log_files(mcap_path)
    stations = _stations(mcap_path, stations_m)
    with tempfile.TemporaryDirectory(prefix='drill_twin_recover_') as directory:
        complete = []
        for file in files:
            if is_complete(file):
                complete.append(file)
            else:
                complete.append(Path(directory) / file.name)
                recover_log(file, complete[-1])
        _write_rrd(complete, rrd_path, stations, active_tab, application_id, mcap_path.stem)
    return rrd_path


def _write_rrd(mcap_paths: Sequence[Path], rrd_path: Path, stations: Sequence[float],
               active_tab, application_id: str, recording_id: str) -> None:
    import rerun as rr

    blueprint = twin_blueprint(stations, active_tab=active_tab)
    recording = rr.RecordingStream(application_id, recording_id=recording_id)
    try:
        recording.save(rrd_path, default_blueprint=blueprint)
        for mcap_path in mcap_paths:
            recording.log_file_from_path(mcap_path)
        recording.flush()            # waits for the importer threads, then the file sink
    finally:
        recording.disconnect()


def rerun_executable() -> str:
    """Find the rerun viewer: next to this Python (a venv's ``bin/rerun``), else on PATH."""
    beside = Path(sys.executable).with_name('rerun')
    if beside.is_file() and os.access(beside, os.X_OK):
        return str(beside)
    found = shutil.which('rerun')
    if found is None:
        raise FileNotFoundError('no rerun executable (pip install rerun-sdk)')
    return found


def open_viewer(mcap_path: str | os.PathLike, stations_m: Sequence[float] | None = None, *,
                rrd_dir: str | os.PathLike | None = None,
                extra_args: Sequence[str] = ()) -> subprocess.Popen:
    """Open the rerun viewer on an MCAP log with the twin's blueprint applied.

    Writes ``<log stem>.rrd`` (the log plus blueprint, see :func:`save_rrd`) into
    ``rrd_dir`` (default: a new temporary directory, left for the viewer to read) and starts
    ``rerun`` on it.  Returns the viewer process; the caller may ``wait()`` for it.
    """
    directory = Path(rrd_dir) if rrd_dir is not None else Path(
        tempfile.mkdtemp(prefix='drill_twin_rerun_'))
    rrd_path = save_rrd(mcap_path, directory / (Path(mcap_path).stem + '.rrd'), stations_m)
    return subprocess.Popen([rerun_executable(), str(rrd_path), *extra_args])
