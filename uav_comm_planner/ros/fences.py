"""A node's fence file, read into zones anchored at its home, once per file, home and margin."""

from __future__ import annotations

from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import FenceFileError, InvalidScenarioError
from uav_comm_planner.vehicle.fence import read_zones
from uav_comm_planner.vehicle.geodesy import Home


class FenceReader:
    """The zones of a node's ``fence_file`` anchored at its home (None without a file), read
    once per file, home and margin: a node keeps one, so that its file is read when it starts
    and again only when ``home_*`` or ``fence_margin_m`` changes, not at every parameter
    change. A bad file is an InvalidScenarioError naming it."""

    def __init__(self) -> None:
        self._key: tuple[str, Home, float] | None = None
        self._zones: Zones | None = None

    def __call__(self, node) -> Zones | None:
        if not node.fence_file:
            return None
        key = (node.fence_file, node.home, float(node.fence_margin_m))
        if key != self._key:
            try:
                zones = read_zones(node.fence_file, node.home, margin_m=node.fence_margin_m)
            except FenceFileError as exc:
                raise InvalidScenarioError(str(exc)) from None
            self._key, self._zones = key, zones
        return self._zones


__all__ = ['FenceReader']
