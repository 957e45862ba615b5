"""The node's parameters: declared from the specs, validated as a whole, applied on change."""

from __future__ import annotations

import contextlib
from typing import Callable, Sequence

from rcl_interfaces.msg import SetParametersResult
from rclpy.node import Node
from rclpy.parameter import Parameter

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.ros.params import (coerced_value, config_from_parameters, FenceReader,
                                         parameter_specs, PlannerConfig)
from uav_comm_planner.vehicle.limits import VehicleParameters


#: The ROS type of an array parameter whose default is empty.
EMPTY_ARRAYS = {'pair': Parameter.Type.DOUBLE_ARRAY, 'pairs': Parameter.Type.DOUBLE_ARRAY,
                'strings': Parameter.Type.STRING_ARRAY}


def _unset(node: Node, name: str) -> bool:
    """Whether parameter ``name`` of ``node`` holds no value yet."""
    return node.get_parameter_or(name).type_ == Parameter.Type.NOT_SET


def _overrides(node: Node) -> frozenset[str]:
    """The names of the parameters given to ``node`` at start-up: ``--ros-args -p``, a
    parameter file, or the constructor's ``parameter_overrides``.

    rclpy keeps them in ``Node._parameter_overrides`` (it has no public accessor); they are
    read from there rather than guessed from a value differing from its default.
    """
    return frozenset(getattr(node, '_parameter_overrides', {}))


class ParameterBinding:
    """Keeps a node's :class:`PlannerConfig` in step with its ROS parameters.

    Declares every parameter of :func:`parameter_specs` on ``node`` with its descriptor,
    refuses a change that does not make a valid configuration (with the reason, also given to
    ``on_refused`` with the names), and after an accepted change rebuilds :attr:`config` and
    calls ``on_change`` with the changed names. A value of the habitual other numeric type (an
    integer for a double, a whole-number double for an integer;
    :func:`~uav_comm_planner.ros.params.coerced_value`) is taken as the declared type, from
    the command line, a parameters file or a set.
    Raises :class:`~uav_comm_planner.errors.PlannerError` when the initial values are invalid.
    """

    def __init__(self, node: Node, on_change: Callable[[list[str]], None], *,
                 on_refused: Callable[[list[str], str], None] | None = None) -> None:
        self._node = node
        self._on_change = on_change
        self._on_refused = on_refused
        self._fences = FenceReader()
        specs = parameter_specs()
        self._kinds = {spec.name: spec.kind for spec in specs}
        # Overrides (-p NAME:=VALUE, --params-file) are applied when declaring, where rclpy
        # calls no pre-set callback: converted here first.
        overrides = getattr(node, '_parameter_overrides', {})
        for name in self._kinds.keys() & overrides.keys():
            overrides[name] = self._coerced(overrides[name])
        node.add_pre_set_parameters_callback(self._coerce)
        node.declare_parameters('', [(spec.name, EMPTY_ARRAYS[spec.kind] if spec.default == []
                                      else spec.default, spec.descriptor()) for spec in specs])
        # Declared by type alone (rclpy would take [] for a byte array), then set empty unless
        # given at start-up (a parameters file's [] comes as no value).
        node.set_parameters([Parameter(spec.name, EMPTY_ARRAYS[spec.kind], []) for spec in specs
                             if spec.default == [] and _unset(node, spec.name)])
        self._names = tuple(spec.name for spec in specs)
        # Set explicitly: given at start-up (any value, the default's own included) or set
        # since. A value equal to a default is no sign of being unset: ArduCopter's waypoint
        # speed given for PX4 must win over PX4's default.
        self._explicit = {spec.name for spec in specs if spec.name in _overrides(node)}
        #: The limit parameters read from the vehicle that the configuration uses (None: none),
        #: and a later read refused (tried again at each accepted change).
        self.vehicle_read: VehicleParameters | None = None
        self._vehicle_refused: VehicleParameters | None = None
        self.config: PlannerConfig = self._config(self._values(), self._explicit, None)
        node.add_on_set_parameters_callback(self._check)
        node.add_post_set_parameters_callback(self._changed)

    def _config(self, values: dict[str, object], explicit: set[str],
                read: VehicleParameters | None) -> PlannerConfig:
        """The configuration of ``values`` with the vehicle's parameters ``read``."""
        return config_from_parameters(values, explicit, fences=self._fences, vehicle_read=read)

    def use_vehicle(self, read: VehicleParameters | None) -> None:
        """Plan with the limit parameters ``read`` from the vehicle (None: none) where no
        explicit parameter nor ``vehicle_params_file`` sets them
        (:func:`~uav_comm_planner.mission.request.vehicle_limits`). Raises
        :class:`~uav_comm_planner.errors.PlannerError` when they do not make a valid
        configuration with the parameters; the configuration is then kept as it was, and
        ``read`` is tried again at each accepted parameter change."""
        self._vehicle_refused = read
        self.config = self._config(self._values(), self._explicit, read)
        self.vehicle_read, self._vehicle_refused = read, None

    @property
    def explicit(self) -> frozenset[str]:
        """The parameters set explicitly: given at start-up (whatever the value) or set
        since."""
        return frozenset(self._explicit)

    def _coerced(self, parameter: Parameter) -> Parameter:
        kind = self._kinds.get(parameter.name)
        if kind is None or parameter.type_ == Parameter.Type.NOT_SET:
            return parameter
        value = coerced_value(parameter.value, kind)
        return parameter if value is parameter.value else Parameter(parameter.name, value=value)

    def _coerce(self, changes: list[Parameter]) -> list[Parameter]:
        """Pre-set callback: each change in its declared numeric type where it was given in
        the other."""
        return [self._coerced(p) for p in changes]

    def _values(self, changes: Sequence[Parameter] = ()) -> dict[str, object]:
        values = {name: self._node.get_parameter(name).value for name in self._names}
        values.update({p.name: p.value for p in changes if p.name in self._names})
        return values

    def _check(self, changes: list[Parameter]) -> SetParametersResult:
        """Refuse a change that does not make a valid configuration, saying why."""
        try:
            self._config(self._values(changes), self._explicit | {p.name for p in changes},
                         self.vehicle_read)
        except PlannerError as exc:
            if self._on_refused is not None:
                self._on_refused([p.name for p in changes], str(exc))
            return SetParametersResult(successful=False, reason=str(exc))
        return SetParametersResult(successful=True)

    def _changed(self, changes: list[Parameter]) -> None:
        names = [p.name for p in changes if p.name in self._names]
        if names:
            self._explicit.update(names)
            self.config = self._config(self._values(), self._explicit, self.vehicle_read)
            if self._vehicle_refused is not None:
                with contextlib.suppress(PlannerError):     # still refused: as it was
                    self.use_vehicle(self._vehicle_refused)
            self._on_change(names)
