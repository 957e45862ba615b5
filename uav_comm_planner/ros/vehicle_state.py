"""What the node knows of the vehicle beyond its position: its mode, its speed, its home (the
planning frame's origin when the home parameters are not set), whether the link is up, and
the telemetry gaps; and what the node does on each such event.

:class:`VehicleState` is the part of :class:`~uav_comm_planner.ros.vehicle.VehicleAdapter`
that the link's faults and the vehicle's home concern, with the upload (its items built for
the frame's origin; the plan in force uploaded again on a link made again unless that link and
home were verified to hold it); the adapter inherits it.
"""

from __future__ import annotations

from typing import Callable

from uav_comm_planner.ros.battery import BatteryWatch
from uav_comm_planner.ros.planning import PlanOutcome
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.items import Q0_SEQ
from uav_comm_planner.vehicle.mavlink.telemetry import (HomeReport, LinkEvent, MISSION_MODES,
                                                        ModeReport, VehicleBridge)


class VehicleState:
    """``mode`` is the vehicle's flight mode (None before its heartbeat), ``speed_mps`` its
    speed at the latest position, ``home`` the planning frame's origin (None while the
    vehicle's home is followed and not told yet), ``link_up`` whether the link is up now;
    ``telemetry_gaps`` counts the gaps said, ``last_gap_s`` the latest's length (autopilot
    seconds)."""

    _node: object
    _report: Callable[[str, bool], None]
    _bridge: VehicleBridge | None
    _position_ns: int | None
    battery: BatteryWatch
    stream: object

    def _init_uploads(self) -> None:
        self._pending_tag: int | None = None
        #: The link's (url, home) and the last upload verified on a link: (url, home, tag).
        self._link_key: tuple[str, Home | None] = ('', None)
        self._verified: tuple[str, Home | None, object] | None = None
        self.uploads_verified = 0
        self.last_error = ''
        self._upload_failed = False

    @property
    def upload_pending(self) -> bool:
        return self._pending_tag is not None

    def _reset_state(self, home: Home | None) -> None:
        self.mode: str | None = None
        self.speed_mps = float('nan')
        self.home = home
        self.link_up = False
        self._held: PlanOutcome | None = None
        self.telemetry_gaps = 0
        self.last_gap_s = 0.0

    @property
    def flying_mission(self) -> bool:
        """Whether the vehicle's mode flies the mission or the node's targets (AUTO or
        GUIDED; PX4's MISSION or OFFBOARD)."""
        return self.mode in MISSION_MODES

    def upload(self, outcome: PlanOutcome) -> None:
        """Put the plan's mission items (after its fence, if any), built for the planning
        frame's origin, on the vehicle (held until the vehicle tells its home when it is
        followed); a plan made in flight is flown from its q0 item."""
        plan = outcome.plan
        self._pending_tag = outcome.request.start_ns
        if self.home is None:
            self._held = outcome            # uploaded once the vehicle tells its home
            return
        request = plan.request
        zones = request.planned_scenario.zones
        if request.home != self.home and zones is not None and not zones.empty:
            # The zones were read in metres from the home parameters; moved to the vehicle's
            # home they would no longer be where the fence file puts them.
            self._pending_tag = None
            self._report(f'mission upload refused: its zones were placed from the home '
                         f'parameters {_where(request.home)}, the vehicle\'s home is '
                         f'{_where(self.home)}; set home_latitude_deg, home_longitude_deg and '
                         f'home_altitude_m to the vehicle\'s home to fly a fence', True)
            return
        if request.home != self.home:
            plan = plan.for_output(home=self.home, end=request.end, firmware=request.firmware)
        if plan.items is None:
            self._pending_tag = None
            self._report(f'mission upload skipped, the plan cannot be flown: '
                         f'{plan.items_error}', True)
            return
        in_flight = plan.request.in_flight is not None
        self._bridge.upload(plan.items, current_seq=Q0_SEQ if in_flight else None,
                            tag=outcome.request.start_ns, fence=plan.fence)

    def _upload_again(self, outcome: PlanOutcome | None) -> None:
        """On a link made (again): the plan in force ``outcome``, unless this link and home
        were verified to hold it."""
        if outcome is None or self._verified == (*self._link_key, outcome.request.start_ns):
            return
        self._report('vehicle link made again: the plan in force is uploaded again', False)
        self.upload(outcome)

    def _on_mode(self, event: ModeReport) -> None:
        self.mode = event.mode
        self._node.get_logger().info(f'vehicle mode {event.mode}')
        self.battery.on_mode(event.mode)

    def telemetry_age_s(self, now_ns: int) -> float | None:
        """Seconds on the node's clock since the latest position (None before any)."""
        return None if self._position_ns is None else (now_ns - self._position_ns) / 1e9

    def end_mission(self, action: str) -> None:
        """Tell the vehicle to end its mission by ``action`` (rtl, land, hold; a stream
        running stops first)."""
        if self._bridge is None:
            return
        if self.stream is not None and self.stream.active:
            self.stop_stream('the battery ended the mission')
        self._bridge.ending.ask(action)

    def _on_home(self, event: HomeReport) -> None:
        home = event.home
        where = _where(home)
        if not event.adopted:
            self._node.get_logger().info(f'vehicle home {where}')
            return
        self.home = home
        self._node.get_logger().info(f"planning frame origin: the vehicle's home {where}")
        held, self._held = self._held, None
        if held is not None:
            self.upload(held)

    def _on_link_event(self, event: LinkEvent) -> None:
        if self._on_fault(event):
            return
        if event.kind == 'error':
            if event.tag is not None and event.tag == self._pending_tag:
                self._pending_tag = None
            self.last_error = event.message
            self._upload_failed = event.tag is not None
            self._report(event.message, True)
            return
        # A verified upload ends any error; the link up again ends a link error, not a failed
        # upload (the plan in force is still not on the vehicle).
        if event.kind == 'uploaded' or (event.kind == 'connected' and not self._upload_failed):
            self.last_error = ''
            self._upload_failed = False
        if event.kind == 'uploaded':
            self.uploads_verified += 1
            if event.tag == self._pending_tag:
                self._pending_tag = None
            self._verified = (*self._link_key, event.tag)
        self._report(event.message, False)

    def _on_fault(self, event: LinkEvent) -> bool:
        """A telemetry gap (a warning) or the link lost (an error, once); False for any other
        link event."""
        if event.kind == 'gap':
            self.telemetry_gaps += 1
            self.last_gap_s = event.seconds
            self._node.get_logger().warning(event.message)
            return True
        if event.kind == 'lost':
            self.link_up = False
            self.last_error = event.message
            self._report(event.message, True)
            return True
        if event.kind == 'connected':
            self.link_up = True
        return False


def _where(home: Home) -> str:
    return f'({home.latitude_deg:.7f}, {home.longitude_deg:.7f}, {home.altitude_m:.1f} m)'


__all__ = ['VehicleState']
