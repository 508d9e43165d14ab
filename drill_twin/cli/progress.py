"""A progress bar on stderr, shown only on a terminal."""
from __future__ import annotations

import sys
import time


class ProgressBar:
    """Call with (done, total); draws ``[#####     ]  42 %  simulated 105/250 s  ETA 60 s``."""

    def __init__(self, label: str, stream=None, width: int = 30):
        self.stream = stream or sys.stderr
        self.enabled = self.stream.isatty()
        self.label = label
        self.width = width
        self.start = time.perf_counter()

    def __call__(self, done: float, total: float) -> None:
        if not self.enabled or total <= 0:
            return
        fraction = min(max(done / total, 0.0), 1.0)
        filled = int(round(fraction * self.width))
        elapsed = time.perf_counter() - self.start
        eta = elapsed * (1 - fraction) / fraction if fraction > 0 else float('nan')
        self.stream.write(f'\r{self.label} [{"#" * filled}{" " * (self.width - filled)}] '
                          f'{100 * fraction:3.0f} %  {done:.0f}/{total:.0f}  ETA {eta:4.0f} s')
        if fraction >= 1.0:
            self.stream.write('\n')
        self.stream.flush()
