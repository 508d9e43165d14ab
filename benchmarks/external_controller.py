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


def logged_bit_speed(log_dir: Path) -> tuple[np.ndarray, np.ndarray]:
    """(twin time from the first state s, bit speed rad/s) of the logged bit states."""
    from mcap_ros2.reader import read_ros2_messages

    (path,) = glob.glob(str(log_dir / '*' / '*.mcap'))
    stamps, speed = [], []
    for m in read_ros2_messages(path, topics=['/drill_twin/bit/state']):
        stamp = m.ros_msg.header.stamp
        stamps.append(stamp.sec + 1e-9 * stamp.nanosec)
        speed.append(m.ros_msg.velocity[1])
    return np.array(stamps), np.array(speed)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=40.0, help='twin seconds')
    parser.add_argument('--on-at', type=float, default=10.0,
                        help='the controller switches on this long after its first reading, s')
    parser.add_argument('--window', type=float, default=10.0, help='SSI window at the end, s')
    parser.add_argument('--wob-kn', type=float, default=100.0)
    parser.add_argument('--out', type=Path, default=None, help='log directory (default: temp)')
    args = parser.parse_args()
    from drill_twin.dynamics import kpi

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
                          '--duration', str(args.duration + 30.0)]
    print(f'load average before: {os.getloadavg()}')
    wall = time.perf_counter()
    twin = subprocess.Popen(twin_command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                            text=True)
    controller = subprocess.Popen(controller_command, stdout=subprocess.PIPE,
                                  stderr=subprocess.STDOUT, text=True)
    twin_output, _ = twin.communicate()
    controller.send_signal(2)
    controller_output, _ = controller.communicate(timeout=30)
    wall = time.perf_counter() - wall
    print(f'load average after: {os.getloadavg()}; wall {wall:.1f} s; twin exit {twin.returncode}')
    if twin.returncode != 0:
        print(twin_output)
        raise SystemExit(1)
    print('controller:', controller_output.strip().splitlines()[-1])

    stamps, external = logged_bit_speed(out)
    # Logged states are the first tick of each logged period: the first is one step in.
    t = stamps - stamps[0] + DT_S
    built_in = built_in_bit_speed(settings, args.duration, args.on_at)
    t_built_in = DT_S * np.arange(1, built_in.size + 1)
    end = args.duration - args.window

    def ssi(time_s, speed, start, stop):
        chosen = speed[(time_s > start + 1e-9) & (time_s <= stop + 1e-9)]
        return float(kpi.stick_slip_severity(chosen)), float(np.mean(chosen))

    before = ssi(t, external, max(0.0, args.on_at - args.window), args.on_at)
    ext = ssi(t, external, end, args.duration)
    ref = ssi(t_built_in, built_in, end, args.duration)
    print(f'WOB {args.wob_kn:g} kN, {args.duration:g} s, switched on at {args.on_at:g} s; '
          f'SSI over the last {args.window:g} s (mean bit speed):')
    print(f'  stiff drive before the switch   {before[0]:.4f} ({before[1]:.2f} rad/s)')
    print(f'  built-in impedance              {ref[0]:.4f} ({ref[1]:.2f} rad/s)')
    print(f'  external impedance through DDS  {ext[0]:.4f} ({ext[1]:.2f} rad/s), '
          f'{100 * (ext[0] - ref[0]) / ref[0]:+.1f} % of the built-in SSI')
    print(f'log: {out}')


if __name__ == '__main__':
    main()
