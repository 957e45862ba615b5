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

USAGE = """usage: planner [-h] [--ros-args ROS_ARGUMENTS ...]

The uav_comm_planner ROS 2 node: plans the communication UAV's flight (trajectory and transmit
power) for the ground nodes, publishes it, writes it as a mission file and, with mavlink_url
set, uploads it to the vehicle and replans in flight. It runs until Ctrl-C.

options:
  -h, --help   show this help and exit (the node is not started)

ROS arguments follow --ros-args, e.g.
  planner --ros-args -p power_budget_w:=2.0 -p num_slots:=125
  planner --ros-args --params-file config/planner.yaml
Every parameter, topic and service: docs/node.md.
"""


def wants_help(args: list[str]) -> bool:
    """Whether the arguments before ``--ros-args`` (the node's own) ask for help."""
    own = args[:args.index('--ros-args')] if '--ros-args' in args else args
    return any(arg in ('-h', '--help') for arg in own)


def main(args: list[str] | None = None) -> int:
    """Run the planner node; returns the exit status (0 after Ctrl-C, or after ``--help``)."""
    if wants_help(sys.argv[1:] if args is None else list(args)):
        print(USAGE, end='')
        return 0
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
