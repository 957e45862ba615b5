"""A plan's propulsion energy, and whether a battery flies its mission: what the command line
prints, the JSON result carries and the node logs and reports (docs/energy.md).

The horizon's energy is the airframe's (:mod:`uav_comm_planner.core.energy`); the mission's
adds its takeoff and landing. Without a battery stated, the verdict is for ArduCopter's default
battery (BATT_CAPACITY 3300 mAh at SITL's 12.6 V), less the 20 % reserve.
"""

from __future__ import annotations

from dataclasses import dataclass

from uav_comm_planner.core.energy import (Battery, horizon_allowance_wh, JOULES_PER_WH,
                                          least_horizon_energy_j, leg_powers,
                                          takeoff_landing_j)
from uav_comm_planner.core.optimizer import PlanResult
from uav_comm_planner.core.propulsion import Airframe
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InfeasibleHorizonError, InvalidScenarioError
from uav_comm_planner.vehicle.airframe import airframe_named, default_airframe

#: ArduCopter's default battery: BATT_CAPACITY 3300 mAh at SITL's 12.6 V, Wh.
DEFAULT_BATTERY_WH = 3.3 * 12.6


def with_energy(scenario: Scenario, airframe: Airframe, *, budget_wh: float | None = None,
                battery: Battery | None = None) -> Scenario:
    """``scenario`` with the airframe, its horizon capped by ``budget_wh`` and by what
    ``battery`` leaves after its reserve, takeoff and landing (the smaller); refuses
    (:class:`~uav_comm_planner.errors.InfeasibleHorizonError`, before any planning) a battery
    that cannot fly the horizon at the airframe's least power."""
    scenario = scenario.replace(airframe=airframe)
    caps = [] if budget_wh is None else [budget_wh]
    if battery is not None:
        allowance = horizon_allowance_wh(battery, airframe, scenario.altitude_m)
        least = least_horizon_energy_j(scenario, airframe) / JOULES_PER_WH
        if allowance <= least:
            up, down = takeoff_landing_j(airframe, scenario.altitude_m)
            raise InfeasibleHorizonError(
                f'the battery cannot fly this mission: it needs at least '
                f'{least + (up + down) / JOULES_PER_WH:.4g} Wh (takeoff '
                f'{up / JOULES_PER_WH:.3g}, the horizon at least {least:.4g}, landing '
                f'{down / JOULES_PER_WH:.3g}) and {battery.available_wh:.4g} Wh are available '
                f'({battery.usable_wh:g} Wh less the {battery.reserve:.0%} reserve); give a '
                f'larger battery (--battery-wh, battery_wh), a shorter horizon or a lower '
                f'altitude')
        caps.append(allowance)
    return scenario.replace(energy_budget_wh=min(caps)) if caps else scenario


def mission_airframe(scenario: Scenario, firmware: str | None) -> Airframe | None:
    """The airframe a mission for ``firmware`` (None: not a mission) is planned with when none
    is named: the firmware's default
    (:func:`~uav_comm_planner.vehicle.airframe.default_airframe`), for a mission it flies (a
    speed within its top airspeed; a faster vehicle is another airframe, and gets none)."""
    airframe = None if firmware is None else default_airframe(firmware)
    if airframe is None or scenario.max_speed_mps > airframe.top_airspeed_mps:
        return None
    return airframe


def with_named_airframe(scenario: Scenario, name: str, *, firmware: str | None,
                        budget_wh: float | None = None,
                        battery: Battery | None = None) -> Scenario:
    """:func:`with_energy` for an airframe by ``name`` (a name or a file; empty: the default
    of a mission for ``firmware``, :func:`mission_airframe`; ``none``: none, and then no
    budget or battery may be given)."""
    if name == 'none':
        airframe = None
    elif name:
        airframe = airframe_named(name)
    else:
        airframe = mission_airframe(scenario, firmware)
    if airframe is None:
        if budget_wh or battery is not None:
            raise InvalidScenarioError('an energy budget or a battery needs an airframe (its '
                                       'propulsion model): name one')
        return scenario
    return with_energy(scenario, airframe, budget_wh=budget_wh, battery=battery)


@dataclass(frozen=True)
class EnergyFigures:
    """A plan's propulsion energy: per leg (W), the horizon's, takeoff and landing (J)."""

    leg_powers_w: list[float]
    horizon_j: float
    takeoff_j: float
    landing_j: float

    @property
    def mission_j(self) -> float:
        return self.takeoff_j + self.horizon_j + self.landing_j


def energy_figures(result: PlanResult) -> EnergyFigures:
    """The energy of ``result``'s plan, by its scenario's airframe (which it must have)."""
    scenario = result.scenario
    airframe = scenario.airframe
    powers = leg_powers(result.trajectory, scenario, airframe)
    up, down = takeoff_landing_j(airframe, scenario.altitude_m)
    return EnergyFigures(powers.tolist(), float(powers.sum() * scenario.slot_s), up, down)


def battery_verdict(figures: EnergyFigures, battery: Battery | None) -> str:
    """Whether ``battery`` (None: ArduCopter's default) flies the mission, in words."""
    chosen = battery or Battery(DEFAULT_BATTERY_WH)
    name = ('battery' if battery is not None
            else "ArduCopter's default battery (3300 mAh at 12.6 V)")
    spare = chosen.available_wh - figures.mission_j / JOULES_PER_WH
    verdict = (f'flies it with {spare:.2f} Wh to spare' if spare >= 0
               else f'does not fly it: {-spare:.2f} Wh short')
    return (f'{name}: {chosen.usable_wh:.2f} Wh, {chosen.available_wh:.2f} Wh available with '
            f'the {chosen.reserve:.0%} reserve: {verdict}')


def energy_lines(result: PlanResult, battery: Battery | None = None) -> list[str]:
    """The plan's energy and the battery's verdict, two lines."""
    figures = energy_figures(result)
    scenario = result.scenario
    duration = (scenario.num_slots + 1) * scenario.slot_s
    budget = scenario.energy_budget_wh
    return [f'propulsion ({scenario.airframe.name}): horizon '
            f'{figures.horizon_j / JOULES_PER_WH:.2f} Wh, mean '
            f'{figures.horizon_j / duration:.1f} W over {duration:g} s; takeoff '
            f'{figures.takeoff_j / JOULES_PER_WH:.2f} Wh, landing '
            f'{figures.landing_j / JOULES_PER_WH:.2f} Wh; mission '
            f'{figures.mission_j / JOULES_PER_WH:.2f} Wh'
            + (f' (horizon budget {budget:.2f} Wh)' if budget is not None else ''),
            battery_verdict(figures, battery)]


def energy_record(result: PlanResult, battery: Battery | None = None) -> dict:
    """The JSON result's energy keys (none without an airframe)."""
    if result.scenario.airframe is None:
        return {}
    figures = energy_figures(result)
    record = {'propulsion_energy_j': figures.horizon_j,
              'propulsion_power_w': figures.leg_powers_w,
              'takeoff_energy_j': figures.takeoff_j, 'landing_energy_j': figures.landing_j,
              'mission_energy_j': figures.mission_j}
    if battery is not None:
        record['battery'] = {'usable_wh': battery.usable_wh, 'reserve': battery.reserve,
                             'available_wh': battery.available_wh}
    return record


__all__ = ['battery_verdict', 'DEFAULT_BATTERY_WH', 'energy_figures', 'energy_lines',
           'energy_record', 'EnergyFigures', 'mission_airframe', 'with_energy',
           'with_named_airframe']
