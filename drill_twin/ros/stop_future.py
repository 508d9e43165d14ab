"""The twin node's ``done`` future, safe to await for hours (rclpy 7.1 workaround)."""
from __future__ import annotations

from rclpy.task import Future


class StopFuture(Future):
    """
    The node's ``done`` future, registering each distinct done callback once.

    rclpy 7.1 (Jazzy) adds a fresh ``lambda x: self.wake()`` to the awaited future on every
    turn of ``Executor.spin_until_future_complete`` (ros2/rclpy#1374, #1702): a future awaited
    for hours collects one closure per tick, about 200 bytes, the node's whole memory growth
    (1.2 MB/min at 100 Hz). Callbacks of the same code and the same captured objects
    do the same thing; the first one is kept, the repeats are dropped.
    """

    def __init__(self, **kwargs):
        super().__init__(**kwargs)
        self._registered = set()

    def add_done_callback(self, callback):
        code = getattr(callback, '__code__', None)
        if code is not None and self._pending():
            cells = tuple(id(cell.cell_contents) for cell in callback.__closure__ or ())
            key = (code, cells)
            if key in self._registered:
                return
            self._registered.add(key)
        super().add_done_callback(callback)
