"""The vehicle's own limits, as the node uses them: read over the link, logged, planned with.

The link reads the vehicle's limit parameters on each connection, off the executor
(:mod:`uav_comm_planner.vehicle.mavlink.parameters`), and hands the read to a
:class:`VehicleParameterWatch` on the executor. The node then plans with each value unless
that limit is set otherwise, by the one precedence rule
(:func:`~uav_comm_planner.mission.request.vehicle_limits`): a ``vehicle_*`` parameter set
explicitly, then ``vehicle_params_file``, then the vehicle's own value, then the firmware's
default. A read of another firmware than ``mission_firmware`` is kept but not used (the limits
are those of the firmware the plan is made for).

What was read is one line on the log, said when a read differs from the one before (a link
made again to the same vehicle says nothing), and a status on ``/diagnostics``
(:meth:`VehicleParameterWatch.status`): each name with its value and where the limit the plan
uses comes from. When the read changes the limits the plan is timed with, the node replans
through the path a changed ``vehicle_*`` parameter takes (the whole mission before its
clock runs, the rest of the mission in flight after). Values that would make no valid
configuration with the parameters (a waypoint speed below ``max_speed_mps``) are refused:
said on ``planner_status`` and ``/diagnostics``, the limits kept as they were, and tried
again at each accepted parameter change
(:meth:`~uav_comm_planner.ros.binding.ParameterBinding.use_vehicle`).
"""

from __future__ import annotations

from typing import Protocol

from diagnostic_msgs.msg import DiagnosticStatus

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.mission.request import limit_sources
from uav_comm_planner.ros.binding import ParameterBinding
from uav_comm_planner.ros.params import PlannerConfig, PREFIXES
from uav_comm_planner.vehicle.firmware import FIRMWARES
from uav_comm_planner.vehicle.limits import VehicleLimits, VehicleParameters
from uav_comm_planner.vehicle.px4_timing import timed_limits

#: The name of the vehicle's parameters as a request (planner_status) and a reason to replan.
SOURCE = 'vehicle parameters'
#: The prefix of the vehicle_* parameters.
PREFIX = PREFIXES[VehicleLimits]

OK, WARN = DiagnosticStatus.OK, DiagnosticStatus.WARN


class ParameterHost(Protocol):
    """What :class:`VehicleParameterWatch` asks of its node (the planner node provides it)."""

    config: PlannerConfig
    flight: object

    def get_logger(self): ...

    def refuse(self, request: str, message: str, *, nodes: str | None = None) -> None: ...


class VehicleParameterWatch:
    """The vehicle's limit parameters in ``node``, planned with through its parameters'
    ``binding`` (module docstring): ``read`` is the latest read (None before any),
    ``refusal`` why it was refused ('' when it is used), ``reads`` counts the reads that
    differed from the one before."""

    def __init__(self, node: ParameterHost, binding: ParameterBinding) -> None:
        self._node = node
        self._binding = binding
        self.read: VehicleParameters | None = None
        self.refusal = ''
        self.reads = 0
        self._sources: tuple[tuple, dict[str, str]] | None = None

    @property
    def used(self) -> bool:
        """Whether the configuration is made with :attr:`read` (a refused read is used once
        a parameter change makes it fit)."""
        return self.read is not None and self._binding.vehicle_read == self.read

    def add(self, read: VehicleParameters) -> None:
        """A read from the link (executor thread): planned with where nothing else sets a
        limit, logged, and replanned for if the limits the plan is timed with changed."""
        if read == self.read:
            return
        node = self._node
        self.read, self.reads = read, self.reads + 1
        before = timed_limits(node.config.vehicle)
        try:
            self._binding.use_vehicle(read)
        except PlannerError as exc:
            self.refusal = str(exc)
            node.refuse(SOURCE, f'{self.describe()}; not used: {exc}')
            return
        self.refusal = ''
        node.get_logger().info(self.describe())
        if node.config.node.vehicle_aware and timed_limits(node.config.vehicle) != before:
            node.flight.request_update(SOURCE)

    def sources(self) -> dict[str, str]:
        """Where each limit of ``mission_firmware``'s parameters comes from now (field -> a
        :data:`~uav_comm_planner.mission.request.SOURCES` entry); worked out again only when
        what it depends on changed (the parameter file is read then)."""
        node = self._node
        explicit = frozenset(name[len(PREFIX):] for name in self._binding.explicit
                             if name.startswith(PREFIX))
        output = node.config.node
        read = self._binding.vehicle_read
        key = (explicit, output.vehicle_params_file, output.mission_firmware, read)
        if self._sources is None or self._sources[0] != key:
            self._sources = (key, limit_sources(explicit, output.vehicle_params_file,
                                                firmware=output.mission_firmware, read=read))
        return self._sources[1]

    def describe(self) -> str:
        """One line: what the vehicle holds, and which of its values the plan uses."""
        read, sources = self.read, self.sources()
        fields = FIRMWARES[read.firmware].parameters
        firmware = self._node.config.node.mission_firmware
        applies = self.used and read.firmware == firmware
        parts = []
        for name, value in read.values.items():
            source = sources.get(fields[name][0]) if applies else None
            used = ('used' if source == 'vehicle' else
                    f'{PREFIX}{fields[name][0]} set explicitly wins' if source == 'explicit'
                    else 'vehicle_params_file wins' if source == 'parameter file'
                    else 'not used')
            parts.append(f'{name} {value:g} ({used})')
        line = f'vehicle parameters ({read.firmware}): ' + (', '.join(parts) or 'none answered')
        if read.missing:
            line += f'; not answered: {", ".join(read.missing)}'
        if read.firmware != firmware:
            line += f'; not used: the plan is made for mission_firmware {firmware}'
        return line

    def status(self) -> tuple[bytes, str, dict[str, object]]:
        """(level, message, values) for ``/diagnostics``: OK while the values read are used
        (or none read yet), WARN when some were refused, not answered, or are of another
        firmware than the plan's."""
        read = self.read
        if read is None:
            return OK, "waiting for the vehicle's parameters", {}
        values: dict[str, object] = {name: repr(value) for name, value in read.values.items()}
        values.update({f'{field}_from': source for field, source in self.sources().items()})
        values['not_answered'] = ', '.join(read.missing)
        line = self.describe()
        if not self.used and self.refusal:
            return WARN, f'{line}; not used: {self.refusal}', values
        firmware_differs = read.firmware != self._node.config.node.mission_firmware
        return (WARN if read.missing or firmware_differs else OK), line, values


__all__ = ['SOURCE', 'VehicleParameterWatch', 'timed_limits']
