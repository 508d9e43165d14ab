"""Soak: the shipped twin run for a long time in real time; memory and log growth per hour.

    python benchmarks/soak.py [--duration 3600] [--warm-up 300] [--interval 5] [--no-log]
                              [--ensemble N] [--ensemble-in-process] [--log-dir DIR]

Starts ``drill-twin twin`` (the shipped parameters, config/twin.yaml: 100 Hz, 64 members in a
worker process, an MCAP log) as a child process in its own ROS domain (localhost only), samples
every ``--interval`` seconds the resident memory (RSS, /proc/PID/statm) of the node's process
and of its ensemble worker and the size of the log directory, stops the twin with SIGINT after
``--duration`` wall seconds and prints, from a least-squares line through the samples after
``--warm-up`` seconds:

- the node's RSS slope (MB per hour) and the worker's;
- the log's growth (MB per hour; the file is chunked and flushed every second);
- the twin's exit status.

Not a test: it takes as long as it is told (default one hour). A flat memory is a slope
below 1 MB per hour (docs/SPEED.md, "The twin node", gives the figures of a run at the
shipped parameters). The samples are written to ``--csv`` if given.
"""
from __future__ import annotations

import argparse
import os
import random
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
PAGE = os.sysconf('SC_PAGE_SIZE')


def rss_mb(pid: int) -> float | None:
    """Resident memory of a process (MB), or None if it is gone."""
    try:
        with open(f'/proc/{pid}/statm') as statm:
            return int(statm.read().split()[1]) * PAGE / 1e6
    except (FileNotFoundError, ProcessLookupError, IndexError):
        return None


def children(pid: int) -> list[int]:
    """Direct children of a process (the ensemble worker)."""
    try:
        with open(f'/proc/{pid}/task/{pid}/children') as listing:
            return [int(p) for p in listing.read().split()]
    except FileNotFoundError:
        return []


def folder_mb(folder: Path) -> float:
    return sum(f.stat().st_size for f in folder.rglob('*') if f.is_file()) / 1e6


def slope_per_hour(t_s: np.ndarray, values: np.ndarray) -> float:
    """Least-squares slope of values against time, per hour (nan with fewer than 2 points)."""
    keep = np.isfinite(values)
    if keep.sum() < 2:
        return float('nan')
    return float(np.polyfit(t_s[keep], values[keep], 1)[0] * 3600.0)


def environment(folder: Path) -> dict:
    env = dict(os.environ)
    env.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 101)))
    env.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    env.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    env['ROS_LOG_DIR'] = str(folder / 'ros_log')
    env['PYTHONPATH'] = os.pathsep.join(filter(None, [str(ROOT), env.get('PYTHONPATH')]))
    return env


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--duration', type=float, default=3600.0, help='wall seconds')
    parser.add_argument('--warm-up', type=float, default=300.0,
                        help='seconds left out of the fits')
    parser.add_argument('--interval', type=float, default=5.0, help='sampling period (s)')
    parser.add_argument('--no-log', action='store_true', help='run the twin without a log')
    parser.add_argument('--ensemble', type=int, help='ensemble members (default: shipped)')
    parser.add_argument('--ensemble-in-process', action='store_true')
    parser.add_argument('--log-dir', type=Path, help='where the log goes (default: temporary)')
    parser.add_argument('--csv', type=Path, help='write the samples here')
    args = parser.parse_args(argv)

    with tempfile.TemporaryDirectory(prefix='drill_twin_soak_') as temporary:
        folder = Path(temporary)
        log_dir = args.log_dir or folder / 'logs'
        command = [sys.executable, '-m', 'drill_twin.cli.main', 'twin', '--log-dir', str(log_dir)]
        if args.no_log:
            command.append('--no-log')
        if args.ensemble is not None:
            command += ['--ensemble', str(args.ensemble)]
        if args.ensemble_in_process:
            command.append('--ensemble-in-process')
        twin = subprocess.Popen(command, env=environment(folder), stdout=subprocess.DEVNULL,
                                stderr=open(folder / 'twin.err', 'w'))
        start = time.monotonic()
        samples = []
        try:
            while time.monotonic() - start < args.duration and twin.poll() is None:
                time.sleep(args.interval)
                workers = children(twin.pid)
                worker = rss_mb(workers[0]) if workers else None
                logged = folder_mb(log_dir) if log_dir.exists() else 0.0
                samples.append((time.monotonic() - start, rss_mb(twin.pid),
                                np.nan if worker is None else worker, logged))
        finally:
            if twin.poll() is None:
                twin.send_signal(signal.SIGINT)
            try:
                status = twin.wait(timeout=30)
            except subprocess.TimeoutExpired:
                twin.kill()
                status = twin.wait()
        errors = (folder / 'twin.err').read_text().strip().splitlines()

    data = np.array([[np.nan if v is None else v for v in row] for row in samples], dtype=float)
    if args.csv:
        np.savetxt(args.csv, data, delimiter=',', header='t_s,node_rss_mb,worker_rss_mb,log_mb',
                   comments='')
    if data.shape[0] < 2:
        print(f'the twin ran {len(samples)} samples only (exit {status}); stderr:')
        print('\n'.join(errors[-10:]))
        return 1
    late = data[:, 0] >= min(args.warm_up, 0.5 * data[-1, 0])
    t = data[late, 0]
    print(f'wall time {data[-1, 0]:.0f} s, {late.sum()} samples after '
          f'{t[0]:.0f} s (warm-up), exit status {status}')
    print(f'node RSS   {data[late, 1][0]:.1f} -> {data[-1, 1]:.1f} MB, slope '
          f'{slope_per_hour(t, data[late, 1]):+.2f} MB/hour')
    if np.isfinite(data[late, 2]).any():
        print(f'worker RSS {np.nanmin(data[late, 2]):.1f} ... {np.nanmax(data[late, 2]):.1f} MB, '
              f'slope {slope_per_hour(t, data[late, 2]):+.2f} MB/hour')
    print(f'log        {data[-1, 3]:.1f} MB, growth {slope_per_hour(t, data[late, 3]):.1f} '
          f'MB/hour')
    return 0


if __name__ == '__main__':
    sys.exit(main())
