"""Entry point of ``ros2 run uav_comm_planner planner``: Ctrl-C handled from the first instant.

Loading the node's modules (rclpy, numpy, cvxpy) takes a second or more, before
:func:`uav_comm_planner.ros.node.main` can handle anything; this module imports nothing
heavy, so a Ctrl-C while they load, while a plan runs, or again while the node shuts down
ends the process quietly. Ctrl-C is the normal way to stop a node: the exit status is 0, as
for the ROS 2 demo nodes (2 for invalid parameters).
"""

from __future__ import annotations

import os
import signal
import sys
import threading


def _interrupt_once(_signum: int, _frame: object) -> None:
    """The first Ctrl-C interrupts; every later one is ignored while the process ends."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    raise KeyboardInterrupt


def _stop_after_loading(_signum: int, _frame: object) -> None:
    """A Ctrl-C while the modules load is kept for later: an exception raised inside the
    import machinery can land in a finaliser, which only prints it and goes on."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _STOP_REQUESTED.set()


_STOP_REQUESTED = threading.Event()


def main(args: list[str] | None = None) -> int:
    """Run the planner node; returns the exit status (0 after Ctrl-C)."""
    signal.signal(signal.SIGINT, _stop_after_loading)
    from uav_comm_planner.ros.node import main as run_node
    if _STOP_REQUESTED.is_set():
        return 0
    signal.signal(signal.SIGINT, _interrupt_once)
    try:
        status = run_node(args)
    except KeyboardInterrupt:
        status = 0
    if threading.active_count() > 1:
        # A daemon thread still inside native code (a solver, the middleware) can abort the
        # interpreter's finalisation ("exception not rethrown"); end without it.
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(status)
    return status


if __name__ == '__main__':
    sys.exit(main())
