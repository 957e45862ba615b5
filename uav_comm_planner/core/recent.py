"""A small store of the values most recently used, by key, shared by the planner's threads."""

from __future__ import annotations

import collections
import threading
from typing import Generic, Hashable, TypeVar

Value = TypeVar('Value')


class RecentlyUsed(Generic[Value]):
    """At most ``size`` values by key, the least recently used dropped first; ``stored``: how
    many values were stored since the start (each one built)."""

    def __init__(self, size: int) -> None:
        self._lock = threading.Lock()
        self._kept: collections.OrderedDict[Hashable, Value] = collections.OrderedDict()
        self._size = size
        self.stored = 0

    def __contains__(self, key: Hashable) -> bool:
        with self._lock:
            return key in self._kept

    def clear(self) -> None:
        """Forget every value kept."""
        with self._lock:
            self._kept.clear()

    def get(self, key: Hashable) -> Value | None:
        """The value kept for ``key`` (None: none)."""
        with self._lock:
            value = self._kept.get(key)
            if value is not None:
                self._kept.move_to_end(key)
            return value

    def put(self, key: Hashable, value: Value) -> None:
        """Keep ``value`` for ``key``."""
        with self._lock:
            self.stored += 1
            self._kept[key] = value
            self._kept.move_to_end(key)
            while len(self._kept) > self._size:
                self._kept.popitem(last=False)


__all__ = ['RecentlyUsed']
