"""Stick-slip severity versus WOB (and versus surface speed) for each top-drive controller.

    PYTHONPATH=$PWD python benchmarks/drive_controllers.py OUT_DIR [--duration 60]
        [--window 20] [--wob-kn 50 75 100 125 150 175] [--speed-hz 0.5 0.83 1.2]

For the paper's string (sections, bit-rock law, fluid, prestress), with the lateral motion
left out (no lateral modes, no wall contact, no kinetic coupling or finite strain: the
torsional-axial model, about ten times faster; docs/DRIVES.md says why), started twisted by
the steady torque (shorter start-up), it runs the
paper's kinematic drive and the dynamic top drive under each controller (``stiff``,
``soft_torque``, ``impedance``) at each WOB (the static WOB of the prestress, the hook load
of that state) at the paper's speed, and at each speed at 150 kN; SSI of the bit speed over
the last ``--window`` seconds. Writes OUT_DIR/drive_controllers.csv and
OUT_DIR/drive_controllers.png. One run at a time (the machine is shared).
"""
from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np

DRIVES = ('kinematic', 'stiff', 'soft_torque', 'impedance')
TORSIONAL_AXIAL = ['physics.contact=false', 'physics.kinetic_coupling=false',
                   'physics.finite_strain=false', 'reduced_basis.lateral_modes=0',
                   'initial_conditions.lateral_deflection_m=0',
                   'initial_conditions.steady_twist=true']
COLUMNS = ('drive', 'weight_on_bit_kn', 'speed_hz', 'stick_slip_severity',
           'bit_speed_min_rad_per_s', 'bit_speed_max_rad_per_s', 'bit_speed_mean_rad_per_s',
           'top_speed_mean_rad_per_s', 'top_speed_min_rad_per_s', 'top_speed_max_rad_per_s',
           'motor_torque_max_nm', 'rop_mean_m_per_h', 'failed', 'wall_time_s')


def run_point(drive: str, wob_kn: float, speed_hz: float, duration_s: float,
              window_s: float, extra: tuple[str, ...] = (), label: str | None = None) -> dict:
    from drill_twin.config import load_config
    from drill_twin.analysis import kpi
    from drill_twin.integrator.simulator import Simulator, SimulationDiverged
    from drill_twin.rig.rig import Rig
    from drill_twin.rig.top_drive import TopDriveMode

    overrides = TORSIONAL_AXIAL + [f'bit_rock.static_weight_on_bit_n={-1e3 * wob_kn}',
                                   f'operation.top_drive_speed_hz={speed_hz}']
    if drive != 'kinematic':
        overrides += ['top_drive.mode=dynamic', f'top_drive.controller={drive}']
    overrides += list(extra)
    row = {'drive': label or drive, 'weight_on_bit_kn': wob_kn, 'speed_hz': speed_hz,
           'failed': 0}
    start = time.perf_counter()
    simulator = Simulator(load_config(overrides=overrides))
    rig = Rig(simulator)
    steps = int(round(duration_s / simulator.dt))
    first = steps - int(round(window_s / simulator.dt))
    bit, top, motor, rop = [], [], [], []
    try:
        for k in range(1, steps + 1):
            rig.step()
            if k >= first:
                bit.append(simulator.last.bit_speed_rad_per_s[0])
                top.append(rig.top_drive.speed_rad_per_s)
                motor.append(rig.top_drive.state.motor_torque_nm
                             if rig.top_drive_mode is TopDriveMode.DYNAMIC else np.nan)
                rop.append(simulator.last.rop_m_per_s[0])
    except SimulationDiverged:
        row['failed'] = 1
    bit, top = np.array(bit), np.array(top)
    if bit.size:
        row.update(stick_slip_severity=float(kpi.stick_slip_severity(bit)),
                   bit_speed_min_rad_per_s=float(bit.min()),
                   bit_speed_max_rad_per_s=float(bit.max()),
                   bit_speed_mean_rad_per_s=float(bit.mean()),
                   top_speed_mean_rad_per_s=float(top.mean()),
                   top_speed_min_rad_per_s=float(top.min()),
                   top_speed_max_rad_per_s=float(top.max()),
                   motor_torque_max_nm=float(np.nanmax(np.abs(motor))) if drive != 'kinematic'
                   else float('nan'),
                   rop_mean_m_per_h=3600.0 * float(np.mean(rop)))
    row['wall_time_s'] = time.perf_counter() - start
    return row


def figure(rows: list[dict], path: Path) -> None:
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt

    fig, (by_wob, by_speed) = plt.subplots(1, 2, figsize=(10, 4))
    paper_speed = 0.83
    for drive in dict.fromkeys(r['drive'] for r in rows):
        mine = [r for r in rows if r['drive'] == drive and 'stick_slip_severity' in r]
        wob = sorted((float(r['weight_on_bit_kn']), float(r['stick_slip_severity']))
                     for r in mine if float(r['speed_hz']) == paper_speed)
        speed = sorted((float(r['speed_hz']), float(r['stick_slip_severity'])) for r in mine
                       if float(r['weight_on_bit_kn']) == 150.0)
        if wob:
            by_wob.plot(*zip(*wob), 'o-', label=drive)
        if speed:
            by_speed.plot(*zip(*speed), 'o-', label=drive)
    by_wob.set_xlabel('WOB (kN)')
    by_wob.set_title(f'surface speed {paper_speed} Hz')
    by_speed.set_xlabel('surface speed (Hz)')
    by_speed.set_title('WOB 150 kN')
    for axes in (by_wob, by_speed):
        axes.set_ylabel('stick-slip severity')
        axes.grid(True)
        axes.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    plt.close(fig)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('out_dir')
    parser.add_argument('--duration', type=float, default=60.0)
    parser.add_argument('--window', type=float, default=20.0)
    parser.add_argument('--wob-kn', type=float, nargs='+',
                        default=[50.0, 75.0, 100.0, 125.0, 150.0, 175.0])
    parser.add_argument('--speed-hz', type=float, nargs='+', default=[0.5, 1.2])
    parser.add_argument('--drives', nargs='+', default=list(DRIVES), choices=DRIVES)
    parser.add_argument('--set', action='append', default=[], metavar='KEY=VALUE',
                        help='extra config override for these runs (repeatable)')
    parser.add_argument('--label', help='name of the series in the table (default: the drive)')
    parser.add_argument('--append', action='store_true',
                        help='add to the rows already in OUT_DIR/drive_controllers.csv')
    args = parser.parse_args()
    from threadpoolctl import threadpool_limits

    out = Path(args.out_dir)
    out.mkdir(parents=True, exist_ok=True)
    points = [(w, 0.83) for w in args.wob_kn] + [(150.0, s) for s in args.speed_hz
                                                 if s != 0.83]
    table = out / 'drive_controllers.csv'
    rows = []
    if args.append and table.exists():
        with open(table, newline='') as handle:
            rows = [{k: v for k, v in row.items() if v != ''} for row in csv.DictReader(handle)]
    with threadpool_limits(limits=1, user_api='blas'):
        for drive in args.drives:
            for wob, speed in points:
                row = run_point(drive, wob, speed, args.duration, args.window,
                                tuple(args.set), args.label)
                rows.append(row)
                print({k: (round(v, 4) if isinstance(v, float) else v) for k, v in row.items()},
                      flush=True)
                with open(table, 'w', newline='') as handle:
                    writer = csv.DictWriter(handle, COLUMNS, restval='')
                    writer.writeheader()
                    writer.writerows(rows)
    figure(rows, out / 'drive_controllers.png')
    print(f'{table} and drive_controllers.png written')


if __name__ == '__main__':
    main()
