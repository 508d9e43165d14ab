"""The external impedance controller against the built-in one, across processes, in real time.

    python benchmarks/external_controller.py [--duration 40] [--on-at 10] [--window 10]
        [--wob-kn 100] [--out DIR]

Starts ``drill-twin twin`` (real time, 100 Hz, one 10 ms step a tick, the torsional-axial
model of the paper's string started untwisted, the dynamic top drive under its plain PI
``stiff``, no ensemble, logged to DIR) and, beside it in its own process,
``examples/impedance_controller.py`` switching on ``--on-at`` seconds after the first reading
it hears (FastDDS on this machine). The twin's log gives the bit speed; the same scenario
under the built-in ``impedance`` controller, switched on at the same time by the engine's
command, is run in this process. Prints the stick-slip severity of both over the last
``--window`` seconds, the stiff drive's before the switch, the controller's own latency
summary (the twin time from the reading to the effect; the wall round trip) and this
machine's load average: the loop through topics holds only as long as its delay does
(docs/DRIVES.md).
"""
from __future__ import annotations

import argparse
import glob
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
TORSIONAL_AXIAL = ['physics.contact=false', 'physics.kinetic_coupling=false',
                   'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
                   'initial_conditions.lateral_deflection_m=0']
DT_S = 0.01
CONTROLLER_HEAD_START_S = 5.0
"""The controller's start before the twin's (its imports and DDS set-up), s."""


def overrides(wob_kn: float) -> list[str]:
    return TORSIONAL_AXIAL + [f'bit_rock.static_weight_on_bit_n={-1e3 * wob_kn}',
                              'top_drive.mode=dynamic', 'top_drive.controller=stiff']


def built_in_bit_speed(settings: list[str], duration_s: float, on_at_s: float) -> np.ndarray:
    """Bit speed of every step under the built-in impedance law switched on at on_at_s."""
    from drill_twin.config import load_config
    from drill_twin.twin.engine import EnsembleSettings, TwinEngine

    engine = TwinEngine(load_config(None, settings + [f'integration.time_step_s={DT_S}']),
                        EnsembleSettings(members=0))
    speed = []
    try:
        for step in range(int(round(duration_s / DT_S))):
            if step == int(round(on_at_s / DT_S)):
                engine.set_top_drive_controller('impedance')
            speed.append(engine.advance(1).bit.speed_rad_per_s)
    finally:
        engine.close()
    return np.array(speed)


def logged_run(log_dir: Path) -> tuple[np.ndarray, np.ndarray, float]:
    """
    (stamps s, bit speed rad/s) of the logged bit states and the first applied speed command.

    Stamps are the twin's clock (the system clock at its start plus the twin time).
    """
    from mcap_ros2.reader import read_ros2_messages

    (path,) = glob.glob(str(log_dir / '*' / '*.mcap'))
    stamps, speed, first_command = [], [], None
    for m in read_ros2_messages(path, topics=['/drill_twin/bit/state',
                                              '/drill_twin/cmd_applied/top_drive_speed']):
        stamp = m.ros_msg.header.stamp
        seconds = stamp.sec + 1e-9 * stamp.nanosec
        if m.channel.topic == '/drill_twin/bit/state':
            stamps.append(seconds)
            speed.append(m.ros_msg.velocity[1])
        elif first_command is None or seconds < first_command:
            first_command = seconds
    return np.array(stamps), np.array(speed), first_command


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=40.0, help='twin seconds')
    parser.add_argument('--on-at', type=float, default=10.0,
                        help='the controller switches on this long after its first reading, s')
    parser.add_argument('--window', type=float, default=10.0, help='SSI window at the end, s')
    parser.add_argument('--wob-kn', type=float, default=100.0)
    parser.add_argument('--out', type=Path, default=None, help='log directory (default: temp)')
    args = parser.parse_args()
    from drill_twin.analysis import kpi

    settings = overrides(args.wob_kn)
    out = args.out or Path(tempfile.mkdtemp(prefix='external_controller_'))
    bin_dir = Path(sys.executable).parent
    twin_command = [str(bin_dir / 'drill-twin'), 'twin', '--duration', str(args.duration),
                    '--ensemble', '0', '--log-dir', str(out)]
    for setting in settings:
        twin_command += ['--set', setting]
    twin_command += ['--ros-args', '-p', f'time_step_s:={DT_S}']
    controller_command = [sys.executable, str(ROOT / 'examples' / 'impedance_controller.py'),
                          '--start-at', str(args.on_at),
                          '--duration', str(args.duration + 30.0 + CONTROLLER_HEAD_START_S)]
    print(f'load average before: {os.getloadavg()}')
    wall = time.perf_counter()
    # The controller first: it counts --start-at from the first reading it hears, which must
    # be the twin's first tick for both laws to switch on at the same twin time.
    controller = subprocess.Popen(controller_command, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True)
    time.sleep(CONTROLLER_HEAD_START_S)
    twin = subprocess.Popen(twin_command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    twin_output, _ = twin.communicate()
    controller.send_signal(2)
    controller_output, _ = controller.communicate(timeout=30)
    wall = time.perf_counter() - wall
    print(f'load average after: {os.getloadavg()}; wall {wall:.1f} s; twin exit {twin.returncode}')
    if twin.returncode != 0:
        print(twin_output)
        raise SystemExit(1)
    print('controller:', controller_output.strip().splitlines()[-1])

    stamps, external, first_command = logged_run(out)
    # Logged states are the first tick of each logged period: the first is one step in.
    t = stamps - stamps[0] + DT_S
    # The external law took effect with its first command: the built-in one is switched on at
    # that very step (DDS discovery and the first reading decide when, and the SSI of a window
    # in the transient depends on the phase of the switch in the stick-slip cycle).
    switched_s = round((first_command - stamps[0] + DT_S) / DT_S) * DT_S
    built_in = built_in_bit_speed(settings, args.duration, switched_s)
    t_built_in = DT_S * np.arange(1, built_in.size + 1)
    end = args.duration - args.window

    def ssi(time_s, speed, start, stop):
        chosen = speed[(time_s > start + 1e-9) & (time_s <= stop + 1e-9)]
        return float(kpi.stick_slip_severity(chosen)), float(np.mean(chosen))

    before = ssi(t, external, max(0.0, switched_s - args.window), switched_s)
    ext = ssi(t, external, end, args.duration)
    ref = ssi(t_built_in, built_in, end, args.duration)
    print(f'WOB {args.wob_kn:g} kN, {args.duration:g} s, the external law took effect at '
          f'{switched_s:.2f} s (asked: {args.on_at:g} s after its first reading), the built-in '
          f'one switched on then; SSI over the last {args.window:g} s (mean bit speed):')
    print(f'  stiff drive before the switch   {before[0]:.4f} ({before[1]:.2f} rad/s)')
    print(f'  built-in impedance              {ref[0]:.4f} ({ref[1]:.2f} rad/s)')
    print(f'  external impedance through DDS  {ext[0]:.4f} ({ext[1]:.2f} rad/s), '
          f'{100 * (ext[0] - ref[0]) / ref[0]:+.1f} % of the built-in SSI')
    print(f'log: {out}')


if __name__ == '__main__':
    main()
