"""Timing of the real twin node in-process: real-time pacing margin and the fastest RTF.

    python benchmarks/twin_node.py [--seconds 30] [--fast-seconds S] [--no-log] [--in-process]

Runs ``TwinNode`` with the shipped parameters (config/twin.yaml: 16-member ensemble in a
worker process, 100 Hz timer, MCAP log into a temporary directory; ``--in-process``: the
ensemble in the node's process) on a SingleThreadedExecutor with no subscribers,
for ``--seconds`` wall seconds at real-time pacing, then again in fast mode (as fast as
possible, /clock published). BLAS is single-threaded, as ``drill-twin twin`` runs it.

Measured per tick: the timer callback's duration (the model's ``advance`` plus messages,
publishing and logging; the model part separately) and the period between callback starts.
Prints the sustained real-time factor (simulated / wall), mean/p50/p99/max tick time, the
margin 10 ms - p99 (the tick budget at 100 Hz), the period jitter, and the CPU use of the
node's process and of the ensemble worker (in cores). The first ``--warm-up`` seconds of
each run are left out. Not part of the test suite.
"""
from __future__ import annotations

import argparse
import os
import random
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]


def _isolate(folder: Path) -> None:
    """Own ROS domain (unless one is set), localhost only, ROS logs out of $HOME."""
    os.environ.setdefault('ROS_DOMAIN_ID', str(random.SystemRandom().randint(1, 101)))
    os.environ.setdefault('ROS_AUTOMATIC_DISCOVERY_RANGE', 'LOCALHOST')
    os.environ.setdefault('RMW_IMPLEMENTATION', 'rmw_fastrtps_cpp')
    os.environ['ROS_LOG_DIR'] = str(folder / 'ros_log')


def timed_node_class():
    from drill_twin.ros.twin_node import TwinNode

    class TimedTwinNode(TwinNode):
        """TwinNode whose timer callback and engine advance are timed (perf_counter, s)."""

        def __init__(self, engine, params, **kwargs):
            self.tick_start, self.tick_time, self.model_time = [], [], []
            self.tick_simulated = []
            super().__init__(engine, params, **kwargs)
            advance = self.engine.advance

            def timed_advance(steps):
                start = time.perf_counter()
                try:
                    return advance(steps)
                finally:
                    self.model_time.append(time.perf_counter() - start)

            self.engine.advance = timed_advance

        def _on_tick(self) -> None:
            start = time.perf_counter()
            super()._on_tick()
            self.tick_start.append(start)
            self.tick_time.append(time.perf_counter() - start)
            self.tick_simulated.append(self.engine.time_s)

    return TimedTwinNode


def run_node(fast: bool, seconds: float, warm_up_s: float, log_dir: Path | None,
             in_process: bool) -> dict:
    """Spin a timed twin node for ``seconds`` wall seconds; statistics after the warm-up."""
    import rclpy
    from rclpy.executors import SingleThreadedExecutor

    from drill_twin.ros.parameters import TwinParameters, validate_ros_arguments
    from drill_twin.ros.twin_node import create_twin_node

    args = ['twin_benchmark', '--ros-args', '--params-file', str(ROOT / 'config' / 'twin.yaml'),
            '-p', f'fast:={str(fast).lower()}',
            '-p', f'ensemble_process:={str(not in_process).lower()}']
    args += ['-p', f'log_dir:={log_dir}'] if log_dir else ['-p', 'log_enabled:=false']
    rclpy.init(args=args)
    executor = SingleThreadedExecutor()
    try:
        params = TwinParameters.from_values(validate_ros_arguments(args))
        node = create_twin_node(params, node_class=timed_node_class())
        executor.add_node(node)
        cpu_start, wall_start = time.process_time(), time.perf_counter()
        children_start = os.times()
        deadline = wall_start + seconds
        while time.perf_counter() < deadline:
            executor.spin_once(timeout_sec=0.05)
        wall = time.perf_counter() - wall_start
        cpu = (time.process_time() - cpu_start) / wall
        result = _statistics(node, warm_up_s, cpu)
        result['members'] = node.engine.ensemble.members
        result['log'] = str(node.log.path) if node.log else 'none'
        result['in_process'] = in_process
        node.close()                    # joins the worker: its CPU time counts from here on
        children = os.times()
        result['worker_cpu'] = (children.children_user + children.children_system
                                - children_start.children_user
                                - children_start.children_system) / wall
        node.destroy_node()
    finally:
        executor.shutdown()
        rclpy.try_shutdown()
    return result


def _statistics(node, warm_up_s: float, cpu: float) -> dict:
    starts = np.array(node.tick_start)
    keep = starts >= starts[0] + warm_up_s
    starts = starts[keep]
    ticks = np.array(node.tick_time)[keep] * 1e3
    model = np.array(node.model_time)[keep] * 1e3
    simulated = np.array(node.tick_simulated)[keep]
    wall = starts[-1] - starts[0]
    periods = np.diff(starts) * 1e3
    tick_ms = node.clock.tick_s * 1e3
    return {
        'ticks': len(starts), 'simulated_s': simulated[-1] - simulated[0], 'wall_s': wall,
        'rtf': (simulated[-1] - simulated[0]) / wall, 'tick_budget_ms': tick_ms,
        'catch_up_ticks': int(np.sum(np.diff(simulated) > 1.5 * node.clock.tick_s)),
        'tick': _quantiles(ticks), 'model': _quantiles(model), 'period': _quantiles(periods),
        'late_ticks': int(np.sum(periods > 1.5 * tick_ms)), 'cpu': cpu,
        'jitter_p99_ms': float(np.percentile(np.abs(periods - tick_ms), 99)),
    }


def _quantiles(values: np.ndarray) -> dict:
    return {'mean': float(np.mean(values)), 'p50': float(np.percentile(values, 50)),
            'p99': float(np.percentile(values, 99)), 'max': float(np.max(values)),
            'std': float(np.std(values))}


def print_report(results: dict, seconds: dict, load_before, load_after) -> None:
    print(f'machine: {os.cpu_count()} CPUs; load average (1, 5, 15 min) before '
          f'{load_before[0]:.2f} {load_before[1]:.2f} {load_before[2]:.2f}, after '
          f'{load_after[0]:.2f} {load_after[1]:.2f} {load_after[2]:.2f}')
    first = next(iter(results.values()))
    print(f'node: {first["members"]} ensemble members '
          f'({"in the node process" if first["in_process"] else "in a worker process"}) '
          f'+ mean model, '
          f'{first["tick_budget_ms"]:g} ms of simulated time a tick, log: '
          f'{"on" if first["log"] != "none" else "off"}, no subscribers')
    print()
    print(f'{"mode":<10} {"wall s":>7} {"ticks":>6} {"sim s":>7} {"RTF":>6} {"CPU":>5} '
          f'{"worker":>6} | '
          f'{"tick ms: mean":>13} {"p50":>6} {"p99":>6} {"max":>6} {"margin":>7} | '
          f'{"model p50":>9} {"p99":>6}')
    for mode, r in results.items():
        t, m = r['tick'], r['model']
        margin = r['tick_budget_ms'] - t['p99']
        print(f'{mode:<10} {seconds[mode]:>7.1f} {r["ticks"]:>6d} {r["simulated_s"]:>7.2f} '
              f'{r["rtf"]:>6.2f} {100 * r["cpu"]:>4.0f}% {100 * r["worker_cpu"]:>5.0f}% | '
              f'{t["mean"]:>13.2f} {t["p50"]:>6.2f} '
              f'{t["p99"]:>6.2f} {t["max"]:>6.2f} {margin:>7.2f} | {m["p50"]:>9.2f} '
              f'{m["p99"]:>6.2f}')
    print()
    print(f'{"mode":<10} {"period ms: mean":>15} {"std":>6} {"p50":>6} {"p99":>6} {"max":>6} '
          f'{"|jitter| p99":>13} {"late (>1.5x)":>13} {"catch-up ticks":>15}')
    for mode, r in results.items():
        p = r['period']
        print(f'{mode:<10} {p["mean"]:>15.2f} {p["std"]:>6.2f} {p["p50"]:>6.2f} {p["p99"]:>6.2f} '
              f'{p["max"]:>6.2f} {r["jitter_p99_ms"]:>13.2f} {r["late_ticks"]:>13d} '
              f'{r["catch_up_ticks"]:>15d}')
    print()
    print('margin = tick budget (10 ms at 100 Hz) - p99 tick time; RTF = simulated / wall '
          '(sustained after the warm-up); in fast mode the period is the tick time plus the '
          'executor overhead; catch-up ticks: ticks that took extra steps to catch up with '
          'the wall clock after a late one.')


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--seconds', type=float, default=30.0,
                        help='wall seconds of the real-time run (default 30)')
    parser.add_argument('--fast-seconds', type=float,
                        help='wall seconds of the fast run (default: --seconds)')
    parser.add_argument('--warm-up', type=float, default=1.0,
                        help='wall seconds left out at the start of each run (default 1)')
    parser.add_argument('--no-log', action='store_true', help='run without the MCAP log')
    parser.add_argument('--in-process', action='store_true',
                        help='the ensemble in the node\'s process (ensemble_process: false)')
    args = parser.parse_args()
    with tempfile.TemporaryDirectory(prefix='drill_twin_bench_') as folder:
        folder = Path(folder)
        _isolate(folder)
        from threadpoolctl import threadpool_limits

        import drill_twin.ros.twin_node  # noqa: F401  (BLAS loaded before limiting it)

        seconds = {'real time': args.seconds, 'fast': args.fast_seconds or args.seconds}
        load_before = os.getloadavg()
        results = {}
        with threadpool_limits(limits=1, user_api='blas'):
            for mode, fast in (('real time', False), ('fast', True)):
                log_dir = None if args.no_log else folder / mode.replace(' ', '_')
                results[mode] = run_node(fast, seconds[mode], args.warm_up, log_dir,
                                         args.in_process)
        print_report(results, seconds, load_before, os.getloadavg())


if __name__ == '__main__':
    main()
