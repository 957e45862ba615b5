"""Handing work between threads and the executor: one worker thread that takes the newest
request only, and one way back from any thread to the executor.

Both are generic: the node plans on a :class:`LatestOnlyWorker` and hands the outcomes back
through an :class:`ExecutorHandoff`; the vehicle link's thread hands its events back through
another.
"""

from __future__ import annotations

from collections import deque
import threading
from typing import Callable, Generic, TypeVar

from rclpy.node import Node

#: How long shutting down waits for a job in progress before leaving it to its daemon thread.
WORKER_STOP_TIMEOUT_S = 5.0

Item = TypeVar('Item')


class LatestOnlyWorker(Generic[Item]):
    """Runs ``job`` on one thread, one request at a time; newer requests replace waiting ones.

    Nothing queues up: at most one request waits while a job runs, and it is the newest.
    A running job may ask :meth:`superseded` between its steps and give up when a newer
    request waits (or the worker stops). ``job`` must not raise.
    """

    def __init__(self, job: Callable[[Item], None], *, name: str) -> None:
        self._job = job
        self._condition = threading.Condition()
        self._waiting: Item | None = None
        self._stopping = False
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, request: Item) -> bool:
        """Queue ``request`` in place of any waiting one; True if one was replaced."""
        with self._condition:
            replaced = self._waiting is not None
            self._waiting = request
            self._condition.notify()
        return replaced

    def superseded(self) -> bool:
        """True when the running job should give up: a newer request waits, or stopping."""
        return self._waiting is not None or self._stopping

    def stop(self, timeout_s: float = WORKER_STOP_TIMEOUT_S) -> None:
        """Drop any waiting request and wait up to ``timeout_s`` for the running job, which
        :meth:`superseded` asks to give up."""
        with self._condition:
            self._stopping = True
            self._waiting = None
            self._condition.notify()
        self._thread.join(timeout_s)

    def _next(self) -> Item | None:
        with self._condition:
            while self._waiting is None and not self._stopping:
                self._condition.wait()
            request, self._waiting = self._waiting, None
            return None if self._stopping else request

    def _run(self) -> None:
        while (request := self._next()) is not None:
            self._job(request)


class ExecutorHandoff(Generic[Item]):
    """Items put from any thread reach ``deliver`` on ``node``'s executor, in order, in
    batches (a guard condition wakes the executor).

    ``maxlen`` bounds the items waiting (the oldest go first); after :meth:`close`, items put
    are dropped, so that nothing reaches a node being destroyed.
    """

    def __init__(self, node: Node, deliver: Callable[[list[Item]], None], *,
                 maxlen: int | None = None) -> None:
        self._deliver = deliver
        self._items: deque[Item] = deque(maxlen=maxlen)
        self._lock = threading.Lock()
        self._closed = False
        self._guard = node.create_guard_condition(self._drain)

    def put(self, item: Item) -> None:
        """Any thread: hand ``item`` to the executor."""
        with self._lock:
            if self._closed:
                return
            self._items.append(item)
        self._guard.trigger()

    def close(self) -> None:
        """Drop what waits and everything put from now on."""
        with self._lock:
            self._closed = True
            self._items.clear()

    def _drain(self) -> None:
        with self._lock:
            items = list(self._items)
            self._items.clear()
        if items:
            self._deliver(items)


__all__ = ['ExecutorHandoff', 'LatestOnlyWorker', 'WORKER_STOP_TIMEOUT_S']
