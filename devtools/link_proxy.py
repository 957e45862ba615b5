"""A TCP proxy between a ground station and a vehicle's MAVLink port whose link can be cut.

It holds one connection to the vehicle (``upstream_port`` on 127.0.0.1) for its whole life and
serves one ground-station connection at a time on ``port``. While it is cut, the ground
station's connection is closed (it reads EOF), every new one is closed as soon as it is
accepted, and the vehicle's bytes are read and dropped: the vehicle flies on, unheard. Restored,
the next connection is served again. ``cut_at`` and ``restored_at`` are the monotonic times of
the last cut and restoration. Both sides send at once (TCP_NODELAY, as the package's own TCP
link does): a stream's small targets are not held back by Nagle's algorithm, which at a
simulator's speed-up would make them late by several times its delay in autopilot time.
"""

from __future__ import annotations

import select
import socket
import threading
import time


class LinkProxy:
    """The proxy (module docstring); :meth:`close` ends it and joins its thread."""

    def __init__(self, upstream_port: int) -> None:
        self._upstream = socket.create_connection(('127.0.0.1', upstream_port), timeout=10)
        self._upstream.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._server = socket.create_server(('127.0.0.1', 0))
        self.port = self._server.getsockname()[1]
        self.connections = 0
        self.refused = 0
        self.cut_at: float | None = None
        self.restored_at: float | None = None
        self._cut = threading.Event()
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name='link-proxy', daemon=True)
        self._thread.start()

    @property
    def url(self) -> str:
        return f'tcp:127.0.0.1:{self.port}'

    def cut(self) -> None:
        self.cut_at = time.monotonic()
        self._cut.set()

    def restore(self) -> None:
        self.restored_at = time.monotonic()
        self._cut.clear()

    def close(self) -> None:
        self._stop.set()
        self._thread.join(5.0)
        self._server.close()
        self._upstream.close()

    def _run(self) -> None:
        client = None
        while not self._stop.is_set():
            sockets = [self._server, self._upstream] + ([client] if client else [])
            readable, _, _ = select.select(sockets, [], [], 0.02)
            if self._cut.is_set() and client is not None:
                client.close()
                client = None
                continue
            for ready in readable:
                if ready is self._server:
                    accepted, _ = self._server.accept()
                    if self._cut.is_set() or client is not None:
                        accepted.close()
                        self.refused += 1
                    else:
                        accepted.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
                        client = accepted
                        self.connections += 1
                elif ready is self._upstream:
                    data = self._upstream.recv(65536)
                    if not data:
                        self._stop.set()
                    elif client is not None:
                        try:
                            client.sendall(data)
                        except OSError:
                            client.close()
                            client = None
                elif client is not None:
                    try:
                        data = client.recv(65536)
                    except OSError:
                        data = b''
                    if data:
                        self._upstream.sendall(data)
                    else:
                        client.close()
                        client = None
        if client is not None:
            client.close()
