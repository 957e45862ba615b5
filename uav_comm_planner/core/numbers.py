"""Real numbers from user input: one check for the scenario's fields and the zones'; and
counts in words for messages."""

from __future__ import annotations

import numpy as np

from uav_comm_planner.errors import InvalidScenarioError


def real_number(name: str, value: object, unit: str = '') -> float:
    """``value`` as a float if it is a real number (int or float, not bool, str or None) that
    a double holds; InvalidScenarioError naming ``name`` (and its ``unit``) otherwise."""
    of = f' of {unit}' if unit else ''
    if isinstance(value, (bool, np.bool_)) or not isinstance(
            value, (int, float, np.integer, np.floating)):
        raise InvalidScenarioError(f'{name} must be a number{of}, got {value!r}')
    try:
        return float(value)
    except OverflowError:
        text = repr(value)
        shown = text if len(text) <= 40 else f'{text[:20]}... ({len(text)} digits)'
        raise InvalidScenarioError(f'{name} must be a finite number{of}, got {shown}') from None


def counted(count: int, noun: str) -> str:
    """``count`` and ``noun``, plural unless the count is one: '1 stop', '3 stops'."""
    return f'{count} {noun}' + ('' if count == 1 else 's')


__all__ = ['counted', 'real_number']
