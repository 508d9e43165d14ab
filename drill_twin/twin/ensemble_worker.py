"""
The online ensemble's worker process: ``python -m drill_twin.twin.ensemble_worker FD``.

Started by :class:`~drill_twin.twin.ensemble.EnsembleProcess` with its end of a socket pair
as file descriptor FD; receives the configuration, the ensemble settings and the reduced
system, then one tick's work at a time (see :func:`~drill_twin.twin.ensemble.serve`).
"""
from __future__ import annotations

import multiprocessing.connection
import sys

from drill_twin.twin.ensemble import serve


def main(argv: list[str]) -> int:
    serve(multiprocessing.connection.Connection(int(argv[1])))
    return 0


if __name__ == '__main__':
    sys.exit(main(sys.argv))
