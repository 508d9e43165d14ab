"""The rig controller's interface over real rclpy and FastDDS (docs/DRIVES.md).

The drive commands by topic (top-drive mode, controller, torque limit; axial mode, block
velocity, WOB set-point), their validation, the echo of every applied command on
/drill_twin/cmd_applied/<name>, the surface readings and the driller's view, all in the log;
and the external impedance controller of examples/impedance_controller.py in the loop,
against the built-in one. The twin runs fast on the torsional-axial model (no lateral motion:
about ten times faster) with the probe of test_ros_twin_node on one executor.
"""
from __future__ import annotations

from collections import defaultdict
import math
from pathlib import Path
import sys
import time

import numpy as np
import pytest
from test_ros_twin_node import ros, stamp_ns, Twin, WAIT_S  # noqa: F401  (ros: a fixture)

from drill_twin import interface as itf

TORSIONAL_AXIAL = ['physics.contact=false', 'physics.kinetic_coupling=false',
                   'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
                   'initial_conditions.lateral_deflection_m=0']
"""The drives benchmark's torsional-axial model (benchmarks/drive_controllers.py)."""
DT_S = 0.01                                     # the node's step and tick
EXAMPLES = Path(__file__).resolve().parents[2] / 'examples'


class DriveTwin(Twin):
    """The probe of test_ros_twin_node with a publisher of every command."""

    def __init__(self, log_dir: Path, **parameters):
        super().__init__(log_dir, **parameters)
        from std_msgs.msg import Float64, String

        from drill_twin.recording.qos import rclpy_qos_profile

        qos = rclpy_qos_profile(itf.STATE_QOS)
        for topic in itf.COMMANDS:
            if topic not in self.commands:
                kind = String if topic in itf.MODE_COMMANDS else Float64
                self.commands[topic] = self.probe.create_publisher(kind, topic, qos)
        deadline = time.monotonic() + WAIT_S
        while not all(p.get_subscription_count() > 0 for p in self.commands.values()):
            assert time.monotonic() < deadline, 'DDS discovery did not complete'
            time.sleep(0.01)

    def command(self, topic: str, value) -> None:
        from drill_twin.ros.messages import command_message

        message = command_message(topic, 0.0 if topic not in itf.MODE_COMMANDS else '')
        message.data = value
        self.commands[topic].publish(message)

    def echoes(self, topic: str):
        return self.received[itf.cmd_applied_topic(topic)]

    def values(self, topic: str) -> np.ndarray:
        return np.array([m.data for m in self.received[topic]])


@pytest.fixture
def drive_twin(ros, tmp_path):                              # noqa: F811
    sessions = []

    def make(**parameters):
        parameters.setdefault('log_dir', tmp_path / 'logs')
        session = DriveTwin(**parameters)
        sessions.append(session)
        return session

    yield make
    for session in sessions:
        session.close()


BAD = [(itf.CMD_TOP_DRIVE_MODE, 'fast', 'top-drive mode', 'not one of kinematic, dynamic'),
       (itf.CMD_TOP_DRIVE_CONTROLLER, 'pid', 'top-drive controller', 'not one of stiff'),
       (itf.CMD_TOP_DRIVE_TORQUE_LIMIT, math.nan, 'top-drive torque limit', 'not a finite'),
       (itf.CMD_TOP_DRIVE_TORQUE_LIMIT, 0.0, 'top-drive torque limit', 'must be > 0'),
       (itf.CMD_AXIAL_MODE, 'winch', 'axial mode', 'not one of hook_load'),
       (itf.CMD_BLOCK_VELOCITY, 5.0, 'block velocity', 'outside [-1, 1] m/s'),
       (itf.CMD_WOB_SETPOINT, math.inf, 'WOB set-point', 'not a finite')]


def test_drive_commands_echoes_surface_readings_and_log(drive_twin):
    """
    Switch the drive and the drawworks by topic.

    Every switch is echoed, stamped with the step it acts in; bad ones are refused with a
    WARN; the surface readings and the driller's view are consistent; all are in the log.
    """
    from mcap_ros2.reader import read_ros2_messages
    from rcl_interfaces.msg import Log

    from drill_twin.recording import reader

    twin = drive_twin(model_overrides=TORSIONAL_AXIAL, ensemble_members=2, kpi_rate_hz=10.0)
    sim = twin.node.engine.simulator
    twin.spin_to(0.3)
    for topic, value in ((itf.CMD_TOP_DRIVE_MODE, 'dynamic'),
                         (itf.CMD_TOP_DRIVE_CONTROLLER, 'soft_torque'),
                         (itf.CMD_TOP_DRIVE_TORQUE_LIMIT, 60e3)):
        twin.command(topic, value)
    for topic, value, *_ in BAD:
        twin.command(topic, value)
    twin.spin_until(lambda: all(twin.echoes(t) for t in (
        itf.CMD_TOP_DRIVE_MODE, itf.CMD_TOP_DRIVE_CONTROLLER, itf.CMD_TOP_DRIVE_TORQUE_LIMIT))
        and len(twin.rosout(Log.WARN, '/drill_twin/cmd/')) >= len(BAD), 'echoes, rejections')
    (mode,), (controller,), (limit,) = (twin.echoes(t) for t in (
        itf.CMD_TOP_DRIVE_MODE, itf.CMD_TOP_DRIVE_CONTROLLER, itf.CMD_TOP_DRIVE_TORQUE_LIMIT))
    assert list(mode.name) == ['top_drive_mode=dynamic'] and list(mode.position) == [1.0]
    assert list(controller.name) == ['top_drive_controller=soft_torque']
    assert list(controller.position) == [1.0]
    assert list(limit.name) == ['top_drive_torque_limit'] and list(limit.position) == [60e3]
    drive = twin.node.engine.rig.top_drive
    assert twin.node.engine.top_drive_mode == 'dynamic'
    assert drive.controller.name == 'soft_torque' and drive.state.torque_limit_nm == 60e3
    lines = twin.rosout(Log.WARN, '/drill_twin/cmd/')
    for topic, value, what, reason in BAD:
        assert any(line.msg.startswith(f'{topic}: {what} command') and reason in line.msg
                   for line in lines), (topic, value)

    # The stamp is the time the switch took effect: the kinematic drive held the initial speed
    # exactly up to that time, the dynamic one moves it in the step that starts there.
    twin.spin_to(stamp_ns(mode) * 1e-9 + 0.5)
    t, top = twin.series(itf.TOP_STATE, 'velocity', 0)
    switched = stamp_ns(mode) * 1e-9
    assert np.all(top[t <= switched + 1e-9] == top[0])
    assert top[np.argmin(np.abs(t - switched - DT_S))] != top[0]

    # The drawworks: WOB set-point and block velocity before the switch are kept (sent while
    # the twin stands, they act from the same step).
    twin.send_while_still([(itf.CMD_WOB_SETPOINT, 110e3), (itf.CMD_BLOCK_VELOCITY, 2e-3),
                           (itf.CMD_AXIAL_MODE, 'block_velocity')])
    twin.spin_until(lambda: twin.echoes(itf.CMD_AXIAL_MODE), 'the axial switch')
    axial = stamp_ns(twin.echoes(itf.CMD_AXIAL_MODE)[-1]) * 1e-9
    assert twin.node.engine.axial_mode == 'block_velocity'
    assert twin.node.engine.rig.commands.weight_on_bit_setpoint_n == 110e3
    twin.command(itf.CMD_HOOK_LOAD, 1.0e6)              # the line pulls what it pulls
    twin.spin_until(lambda: twin.rosout(Log.WARN, 'drill line'), 'the hook-load refusal')
    twin.spin_to(axial + 1.0)

    # Surface readings: one per tick, each topic in step with the bit state.
    n = min(len(twin.received[topic])
            for topic in itf.SURFACE_TOPICS + (itf.BIT_STATE, itf.TOP_STATE))
    assert n > 100
    t = np.array([stamp_ns(m) * 1e-9 for m in twin.received[itf.BIT_STATE]])[:n]
    surface = {topic: twin.values(topic)[:n] for topic in itf.SURFACE_TOPICS}
    _, top_speed = twin.series(itf.TOP_STATE, 'velocity', 0)
    _, top_torque = twin.series(itf.TOP_STATE, 'effort', 0)
    _, bit_depth = twin.series(itf.BIT_STATE, 'position', 0)
    np.testing.assert_array_equal(surface[itf.SURFACE_SPEED], top_speed[:n])
    np.testing.assert_array_equal(surface[itf.SURFACE_TORQUE], top_torque[:n])
    np.testing.assert_array_equal(surface[itf.SURFACE_BIT_DEPTH], bit_depth[:n])
    # The block moves at the commanded velocity: 2 mm/s x 10 ms a step.
    block = surface[itf.SURFACE_BLOCK_POSITION][t > axial + 1.5 * DT_S]
    np.testing.assert_allclose(np.diff(block), 2e-3 * DT_S, rtol=1e-9)
    # At the start (at rest on the static WOB), the surface WOB is the bit's static WOB.
    static_wob = -sim.system.model.prestress.static_weight_on_bit_n
    assert surface[itf.SURFACE_WOB][0] == pytest.approx(static_wob, rel=1e-3)
    assert np.all(np.diff(surface[itf.SURFACE_HOLE_DEPTH]) >= 0)
    # The driller's view: the same readings in drilling units, at the KPI rate.
    hole = twin.values(itf.HOLE_DEPTH)
    driller = {name: twin.values(itf.driller_topic(name)) for name in itf.DRILLER_TOPICS}
    k = min(hole.size, *(v.size for v in driller.values()))
    np.testing.assert_array_equal(driller['DMEA'][:k], hole[:k])
    ticks = np.flatnonzero(np.isin(surface[itf.SURFACE_HOLE_DEPTH], hole[:k]))
    assert ticks.size >= k - 1
    at = {name: values[:k] for name, values in driller.items()}
    index = np.searchsorted(surface[itf.SURFACE_HOLE_DEPTH], hole[:k], side='right') - 1
    np.testing.assert_allclose(at['RPMA'], surface[itf.SURFACE_SPEED][index] * 30 / math.pi,
                               rtol=1e-12)
    np.testing.assert_allclose(at['HKLA'] * 1e3, surface[itf.SURFACE_HOOK_LOAD][index],
                               rtol=1e-12)
    np.testing.assert_allclose(at['HKLA_klbf'] * 4448.2216152605, at['HKLA'] * 1e3,
                               rtol=1e-12)
    np.testing.assert_allclose(at['ROPA'], surface[itf.SURFACE_ROP][index] * 3600, rtol=1e-12)

    # The log holds the commands (String ones too) and their echoes as heard.
    twin.node.close()
    logged = defaultdict(list)
    for split in reader.log_files(twin.node.log.path):
        for item in read_ros2_messages(str(split)):
            logged[item.channel.topic].append(item.ros_msg)
    assert [m.data for m in logged[itf.CMD_TOP_DRIVE_MODE]] == ['dynamic']
    assert [m.data for m in logged[itf.CMD_AXIAL_MODE]] == ['block_velocity']
    for topic in (itf.CMD_TOP_DRIVE_MODE, itf.CMD_AXIAL_MODE, itf.CMD_BLOCK_VELOCITY):
        heard = [(stamp_ns(m), list(m.name), list(m.position)) for m in twin.echoes(topic)]
        assert [(stamp_ns(m), list(m.name), list(m.position))
                for m in logged[itf.cmd_applied_topic(topic)]] == heard
    assert len(logged[itf.driller_topic('WOBA')]) == len(twin.received[
        itf.driller_topic('WOBA')])


# -- an external controller in the loop ------------------------------------------------------

LOOP_S = 30.0
ON_AT_S = 10.0
WINDOW_S = 10.0
WOB_N = 100e3


def _ssi(bit_speed: np.ndarray) -> float:
    from drill_twin.analysis import kpi
    return float(kpi.stick_slip_severity(bit_speed))


def _builtin_bit_speed(overrides) -> np.ndarray:
    """
    Return the bit speed of every step of the scenario under the built-in impedance law.

    Switched on at ON_AT_S by the engine's command, as the node would.
    """
    from drill_twin.config import load_config
    from drill_twin.twin.engine import EnsembleSettings, TwinEngine

    config = load_config(None, overrides + ['integration.time_step_s=0.01'])
    engine = TwinEngine(config, EnsembleSettings(members=0))
    speed = []
    try:
        for step in range(int(round(LOOP_S / DT_S))):
            if step == int(round(ON_AT_S / DT_S)):
                engine.set_top_drive_controller('impedance')
            speed.append(engine.advance(1).bit.speed_rad_per_s)
    finally:
        engine.close()
    return np.array(speed)


def test_an_external_impedance_controller_matches_the_built_in_one(ros):  # noqa: F811
    """
    Close the loop through topics with examples/impedance_controller.py.

    Switched on at 10 s during stick-slip from the untwisted start, around the dynamic drive
    under the plain PI; its stick-slip severity is the built-in law's (switched on at the same
    time), and it measures its command-to-effect latency from the echoes.

    A probe hears the bit state only (the twin, the probe and the controller on one executor).
    """
    from rclpy.executors import SingleThreadedExecutor
    from rclpy.qos import QoSProfile, ReliabilityPolicy
    from sensor_msgs.msg import JointState

    from drill_twin.rig.top_drive import characteristic_impedance
    from drill_twin.ros.parameters import TwinParameters
    from drill_twin.ros.twin_node import create_twin_node

    sys.path.insert(0, str(EXAMPLES))
    try:
        from impedance_controller import ImpedanceController, pipe_impedance_nm_s_per_rad
    finally:
        sys.path.remove(str(EXAMPLES))

    overrides = TORSIONAL_AXIAL + [f'bit_rock.static_weight_on_bit_n={-WOB_N}',
                                   'top_drive.mode=dynamic', 'top_drive.controller=stiff']
    twin = create_twin_node(TwinParameters.from_values(
        {'fast': True, 'duration_s': LOOP_S, 'log_enabled': False, 'ensemble_members': 0,
         'model_overrides': overrides}))
    zeta = characteristic_impedance(twin.engine.config)
    assert pipe_impedance_nm_s_per_rad() == pytest.approx(zeta, rel=1e-12)
    controller = ImpedanceController(twin.engine.top_drive_speed_command, zeta,
                                     switch_drive=False, start_at_s=ON_AT_S)
    probe = ros.create_node('loop_probe')
    heard = []
    probe.create_subscription(JointState, itf.BIT_STATE, heard.append,
                              QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE))
    executor = SingleThreadedExecutor()
    for node in (twin, controller, probe):
        executor.add_node(node)
    try:
        ends = [controller.publishers_matched,
                lambda: twin.outputs.publishers[itf.BIT_STATE].get_subscription_count() > 0,
                lambda: twin.outputs.publishers[itf.SURFACE_TORQUE].get_subscription_count() > 0,
                lambda: twin.outputs.publishers[itf.TOP_STATE].get_subscription_count() > 0,
                lambda: twin.outputs.publishers[itf.cmd_applied_topic(itf.CMD_TOP_DRIVE_SPEED)]
                .get_subscription_count() > 0]
        deadline = time.monotonic() + WAIT_S
        while not all(end() for end in ends):
            assert time.monotonic() < deadline, 'DDS discovery did not complete'
            time.sleep(0.01)
        deadline = time.monotonic() + 20 * WAIT_S
        while not (twin.done.done() and heard and stamp_ns(heard[-1]) >= LOOP_S * 1e9 - 1e3):
            assert time.monotonic() < deadline, 'timed out waiting for the run'
            executor.spin_once(timeout_sec=0.1)
    finally:
        twin.close()
        executor.shutdown()
        for node in (twin, controller, probe):
            node.destroy_node()
    t = np.array([stamp_ns(m) * 1e-9 for m in heard])
    bit = np.array([m.velocity[1] for m in heard])
    external = _ssi(bit[t > LOOP_S - WINDOW_S + 1e-9])
    built_in = _ssi(_builtin_bit_speed(overrides)[-int(round(WINDOW_S / DT_S)):])
    stiff = _ssi(bit[(t > ON_AT_S - WINDOW_S + 1e-9) & (t <= ON_AT_S + 1e-9)])
    wall = np.array([w for w, _, _ in controller.latencies])
    twin_latency = np.array([s for _, s, _ in controller.latencies])
    print(f'\nSSI over the last {WINDOW_S:g} s of {LOOP_S:g} s at {WOB_N / 1e3:g} kN: external '
          f'{external:.4f}, built-in {built_in:.4f} (stiff before: {stiff:.4f}); '
          f'{controller.latency_summary()}; '
          f'twin-time latency min {twin_latency.min():.3f} s max {twin_latency.max():.3f} s; '
          f'wall round trip max {1e3 * wall.max():.2f} ms')
    assert controller.commands > 0.9 * (LOOP_S - ON_AT_S) / DT_S      # one command a tick
    assert len(controller.latencies) > 0.5 * controller.commands
    assert twin_latency.min() >= DT_S - 1e-9                   # never before the reading
    assert stiff > 0.5                                          # stick-slip to remove
    assert external == pytest.approx(built_in, abs=0.05)
