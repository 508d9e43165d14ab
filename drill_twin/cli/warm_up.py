"""
Compile, or load from the cache, every kernel of the time loop once.

    python -m drill_twin.cli.warm_up

``make setup`` runs it after installing, so the first ``make twin`` or test does not pay the
compilation (about a minute of CPU on a fresh machine, see :mod:`drill_twin.numerics.compiled`)
and processes started together (Monte Carlo workers, the twin's ensemble worker) find the
kernels on disk instead of compiling them each at the same time.
"""
from __future__ import annotations

from dataclasses import replace
import sys
import time

import numpy as np

from drill_twin.analysis import kpi
from drill_twin.config.loader import load_config
from drill_twin.integrator.simulator import Simulator
from drill_twin.rig.rig import Rig
from drill_twin.uncertainty.germ import germs_for_realizations


def warm_up(steps: int = 3) -> float:
    """
    Step the default string as a mean model and as a batch of random members.

    Off and on the wall; and the twin's KPI window. Returns the wall time it took (s).
    """
    start = time.perf_counter()
    config = load_config()
    mean = Simulator(config)
    batch = Simulator(config, members=4, germs=germs_for_realizations(0.1, 0, range(4)),
                      system=mean.system)
    for simulator in (mean, batch):
        rig = Rig(simulator)
        for _ in range(steps):
            rig.step()
        simulator.observe()
    _observe_layouts(batch)
    kpi.window_means(np.zeros(2), 0.0, *np.zeros((4, 2)))     # the twin's KPI window
    return time.perf_counter() - start


def _observe_layouts(simulator) -> None:
    """
    Observe once with each layout of the forces and of the surface the time loop can hand over.

    The step's f_NL is column-major, a merged one (contact refinement, retries) row-major; the
    flat bottom's surface is read-only, a lobed one's is not: each pair is a signature of
    :func:`~drill_twin.integrator.observed_bit.derive`.
    """
    integrator, last = simulator.integrator, simulator.last
    flat = integrator.bottom_surface
    try:
        for full in (np.asfortranarray(last.full), np.ascontiguousarray(last.full)):
            simulator.last = replace(last, full=full)
            for writeable in (False, True):
                if writeable:
                    integrator.bottom_surface = lambda state, omega=None: tuple(
                        np.array(x) for x in flat(state, omega))
                simulator.observe()
            integrator.bottom_surface = flat
    finally:
        simulator.last = last
        integrator.bottom_surface = flat


def main() -> int:
    """Warm the cache and say how long it took."""
    seconds = warm_up()
    print(f'drill_twin: time-loop kernels ready ({seconds:.1f} s)', file=sys.stderr)
    return 0


if __name__ == '__main__':
    sys.exit(main())
