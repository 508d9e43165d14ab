"""
Compile, or load from the cache, every kernel of the time loop once.

    python -m drill_twin.dynamics.warm_up

``make setup`` runs it after installing, so the first ``make twin`` or test does not pay the
compilation (about a minute of CPU on a fresh machine, see :mod:`drill_twin.dynamics.compiled`)
and processes started together (Monte Carlo workers, the twin's ensemble worker) find the
kernels on disk instead of compiling them each at the same time.
"""
from __future__ import annotations

import sys
import time


def warm_up(steps: int = 3) -> float:
    """
    Step the default string as a mean model and as a batch of random members.

    Off and on the wall; returns the wall time it took (s).
    """
    from drill_twin.config.loader import load_config
    from drill_twin.dynamics.simulator import Simulator
    from drill_twin.uncertainty.germ import germs_for_realizations

    start = time.perf_counter()
    config = load_config()
    mean = Simulator(config)
    batch = Simulator(config, members=4, germs=germs_for_realizations(0.1, 0, range(4)),
                      system=mean.system)
    for simulator in (mean, batch):
        for _ in range(steps):
            simulator.step()
        simulator.observe()
    return time.perf_counter() - start


def main() -> int:
    """Warm the cache and say how long it took."""
    seconds = warm_up()
    print(f'drill_twin: time-loop kernels ready ({seconds:.1f} s)', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
