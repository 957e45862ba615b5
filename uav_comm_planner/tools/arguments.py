"""Argument types of the command line: numbers, points, node lists, the wind and the home,
each refused with argparse's one line."""

from __future__ import annotations

import argparse
import math

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.vehicle.geodesy import Home


def _floats(text: str, count: int | None = None) -> list[float]:
    try:
        values = [float(v) for v in text.split(',')]
    except ValueError:
        raise argparse.ArgumentTypeError(f'expected comma-separated numbers, got {text!r}')
    if count is not None and len(values) != count:
        raise argparse.ArgumentTypeError(f'expected {count} comma-separated numbers, got {text!r}')
    return values


def _pair(text: str) -> tuple[float, float]:
    x, y = _floats(text, 2)
    return (x, y)


def _nodes(text: str) -> list[tuple[float, float]]:
    return [_pair(item) for item in text.split(';') if item.strip()]


def _ends(text: str) -> list[tuple[float, float]]:
    """One point X,Y, or one per UAV X,Y;X,Y;... (with --uavs)."""
    ends = _nodes(text)
    if not ends:
        raise argparse.ArgumentTypeError(f'expected X,Y or X,Y;X,Y;..., got {text!r}')
    return ends


def _wind(text: str) -> tuple[float, float]:
    speed, from_deg = _floats(text, 2)
    if not (math.isfinite(speed) and speed >= 0 and math.isfinite(from_deg)):
        raise argparse.ArgumentTypeError(
            f'expected a wind speed >= 0 m/s and a direction in degrees, got {text!r}')
    return speed, from_deg


def _home(text: str) -> Home:
    try:
        return Home.parse(text)
    except PlannerError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None
