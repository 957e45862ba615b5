"""Shared fixtures: a private rclpy context per test, so that tests never share ROS state."""

from __future__ import annotations

import os
from pathlib import Path
import sys
from typing import Iterator

import pytest

#: The checkout, whose devtools/ (SITL launchers, the benchmark, docgen) the tests import: it is
#: not installed with the package.
CHECKOUT = Path(__file__).resolve().parents[1]
if str(CHECKOUT) not in sys.path:
    sys.path.insert(0, str(CHECKOUT))

#: Where CI keeps its ArduCopter SITL binary: ../shared/sitl/ beside the checkout.
CHECKOUT_SITL = Path(__file__).resolve().parents[2] / 'shared' / 'sitl' / 'arducopter'
if 'UAV_COMM_PLANNER_SITL' not in os.environ and CHECKOUT_SITL.is_file():
    os.environ['UAV_COMM_PLANNER_SITL'] = str(CHECKOUT_SITL)


@pytest.fixture
def ros_context() -> Iterator[object]:
    """An initialised ``rclpy.Context`` without signal handlers, shut down after the test.

    The DDS domain is the one in ``ROS_DOMAIN_ID`` (the Makefile picks one per run).
    """
    # Imported here so that the core's tests run where ROS is not installed.
    import rclpy
    from rclpy.signals import SignalHandlerOptions

    context = rclpy.Context()
    rclpy.init(context=context, signal_handler_options=SignalHandlerOptions.NO)
    try:
        yield context
    finally:
        context.try_shutdown()


@pytest.fixture
def harness(ros_context):
    """Makes planner nodes on real rclpy (``helpers.Harness``); closes them after the test."""
    from helpers import Harness

    made = []

    def make(**options):
        made.append(Harness(ros_context, **options))
        return made[-1]
    yield make
    for each in made:
        each.close()
