"""
Stopping on SIGINT or SIGTERM under rclpy.

rclpy installs its own handlers of both signals: on one it shuts the default context down on
its own thread, while Python raises KeyboardInterrupt in the main thread at once.
"""
from __future__ import annotations

import time

import rclpy


def let_the_signal_handler_finish(timeout_s: float = 1.0) -> None:
    """
    Wait until rclpy's signal handler has shut the context down (at most ``timeout_s``).

    On SIGINT or SIGTERM rclpy shuts the context down on its own thread while Python raises
    KeyboardInterrupt here at once; shutting the context down again at the same time corrupted
    the heap or raised "rcl_shutdown already called" (3 runs in 60 of a signal during start-up,
    test_signal_while_starting).
    """
    deadline = time.monotonic() + timeout_s
    while rclpy.ok() and time.monotonic() < deadline:
        time.sleep(0.005)
