"""A fleet's vehicle links: one MAVLink bridge per ``mavlink_urls`` entry, each uploading its
own vehicle's mission.

Every bridge (:class:`~uav_comm_planner.vehicle.mavlink.telemetry.VehicleBridge`) runs on its
own thread and builds nothing: it puts the items it is given on its vehicle and reads them back.
The fleet's planning frame is anchored at the home parameters (their defaults: the firmware's
simulator home) for every vehicle, never at one vehicle's home, so that all missions share one
frame; a mission whose home or first waypoint is farther than ``home_distance_limit_m`` from its
vehicle is refused by that vehicle's bridge. The links' events come back to the executor through
an :class:`~uav_comm_planner.ros.handoff.ExecutorHandoff`, each with its vehicle's index; what
a link says (up, lost, uploaded, refused) goes to ``report(k, message, is_error)``.
"""

from __future__ import annotations

from typing import Callable, Sequence

from rclpy.node import Node

from uav_comm_planner.ros.handoff import ExecutorHandoff
from uav_comm_planner.ros.planning import PlanOutcome
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.telemetry import Event, LinkEvent, VehicleBridge

#: Link events kept for the executor at most (the oldest go first).
EVENTS_KEPT = 10_000
#: report(k, message, is_error): what vehicle k's link says (k 0-based).
LinkReporter = Callable[[int, str, bool], None]


class FleetLinks:
    """The links of a fleet node (module docstring): ``uploads_verified[k]`` counts vehicle
    k's uploads read back, ``verified_tag[k]`` is the plan stamp of its latest one (None
    before any), ``link_up[k]`` whether its link is up, ``last_error[k]`` its latest error
    ('' when none, or since its latest verified upload)."""

    def __init__(self, node: Node, report: LinkReporter) -> None:
        self._report = report
        self._events: ExecutorHandoff[tuple[int, int, Event]] = ExecutorHandoff(
            node, self._drain, maxlen=EVENTS_KEPT)
        self._bridges: list[VehicleBridge] = []
        self._key: tuple | None = None
        #: Counts the links made: an event of an older one is not drained.
        self._generation = 0
        self._counters(0)

    def _counters(self, count: int) -> None:
        self.uploads_verified = [0] * count
        self.verified_tag: list[object] = [None] * count
        self.link_up = [False] * count
        self.last_error = [''] * count

    @property
    def linked(self) -> bool:
        return bool(self._bridges)

    def connect(self, urls: Sequence[str], home: Home, home_limit_m: float) -> bool:
        """(Re)make the links for ``urls`` (none when empty) in ``home``'s frame, unless they
        are the links already made; whether they were made."""
        key = (tuple(urls), home, float(home_limit_m))
        if key == self._key:
            return False
        self.stop()
        self._key = key
        self._counters(len(urls))
        put, generation = self._events.put, self._generation
        for k, url in enumerate(urls):
            def on_event(event: Event, k: int = k) -> None:
                put((generation, k, event))
            self._bridges.append(VehicleBridge(url, home, on_event,
                                               home_limit_m=home_limit_m))
            self._report(k, f'vehicle link: connecting to {url} (planning frame origin: the '
                            f'home parameters)', False)
        return bool(urls)

    def upload(self, vehicles: Sequence[PlanOutcome], tag: object) -> None:
        """Put vehicle k's mission items on link k, for every link; a vehicle whose items
        could not be built is said and skipped."""
        for k, (bridge, outcome) in enumerate(zip(self._bridges, vehicles)):
            items = outcome.plan.items
            if items is None:
                self._report(k, f'mission upload skipped, the plan cannot be flown: '
                                f'{outcome.plan.items_error}', True)
                continue
            bridge.upload(items, tag=tag)

    def stop(self) -> None:
        """End every link; events they have not handed on yet are dropped."""
        self._generation += 1
        for bridge in self._bridges:
            bridge.stop()
        self._bridges = []
        self._key = None

    def close(self) -> None:
        """Stop, and deliver nothing more (the node is being destroyed)."""
        self._events.close()
        self.stop()

    def _drain(self, events: list[tuple[int, int, Event]]) -> None:
        """Executor thread: the link events of the links made last (positions and the other
        telemetry are not used by a fleet node)."""
        for generation, k, event in events:
            if generation == self._generation and isinstance(event, LinkEvent):
                self._on_link_event(k, event)

    def _on_link_event(self, k: int, event: LinkEvent) -> None:
        if event.kind == 'gap':
            return                  # telemetry is not used: its gaps are nobody's concern
        if event.kind in ('connected', 'lost'):
            self.link_up[k] = event.kind == 'connected'
        if event.kind == 'uploaded':
            self.uploads_verified[k] += 1
            self.verified_tag[k] = event.tag
            self.last_error[k] = ''
        failed = event.kind in ('error', 'lost')
        if failed:
            self.last_error[k] = event.message
        self._report(k, event.message, failed)


__all__ = ['FleetLinks', 'LinkReporter']
