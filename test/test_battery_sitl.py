"""A battery that drains faster than planned, on ArduCopter SITL: the mission ends at qF or in a
clear end, the reason on /diagnostics and the vehicle told ``battery_action``.

The SITL's frame model is given a 3.3 Ah battery (``battCapacityAh``: the simulated battery
then sags and empties, and ArduCopter's BATT_CAPACITY follows it, so its charge remaining is
the battery's own; BATT_MONITOR 4, copter.parm's, reads it), while the node is told a battery
of 60 Wh (``battery_wh``): the plan for the letter's case I from q0 = (300, 0) m to qF over
320 s fits the stated battery with its 20 % reserve and not the real one. The node must see it
from the vehicle's reports once its clock runs, and either replan a rest that reaches qF with
the reserve or end the mission. Everything is measured in autopilot time on the test's own
link: the mode the vehicle was put in and when, where it came down, the battery's charge
left there. SITL instances 40-49, a fresh folder per flight, the SITL ended by its PID.
"""

from __future__ import annotations

import math

from diagnostic_msgs.msg import DiagnosticStatus
import pytest
from sitl_node import flights, LinkedNode, Telemetry

from devtools.sitl import set_mode, take_off, why_not_runnable
from uav_comm_planner.ros.diagnostics import BATTERY
from uav_comm_planner.vehicle.mavlink.battery import END_MODES

pytestmark = [pytest.mark.sitl,
              pytest.mark.skipif(bool(why_not_runnable()), reason=why_not_runnable())]

INSTANCES = (40, 49)
#: The real battery (the SITL's) and the one the node is told.
REAL_AH = 3.3
STATED_WH = 60.0
RESERVE = 0.2
START_M = (300.0, 0.0)
#: Wall-clock limit of one flight, generous: about 15 s at the SITL's speedup.
WALL_LIMIT_S = 240.0
#: A vehicle is down when this low (m above home) and this slow (m/s) after the end.
DOWN_M = 0.5


#: The node's parameters of the first flight: case I from START_M over 320 s, told STATED_WH.
TOLD = {'max_speed_mps': 10.0, 'horizon_s': 320.0, 'num_slots': 80, 'start_m': list(START_M),
        'compute_baselines': False, 'battery_wh': STATED_WH, 'battery_reserve': RESERVE}


class BatteryFlight(LinkedNode):
    """A SITL with a REAL_AH battery (and ``sitl`` parameters), the node told ``parameters``
    over TOLD, a probe of its outputs."""

    def __init__(self, ros_context, folder, sitl: dict[str, float] | None = None,
                 **parameters) -> None:
        super().__init__(ros_context, folder, {**TOLD, **parameters}, instances=INSTANCES,
                         sitl_parameters=sitl, frame={'battCapacityAh': REAL_AH},
                         limit_s=WALL_LIMIT_S)

    @property
    def battery_states(self) -> list[tuple[bytes, str, dict[str, str]]]:
        """The battery's /diagnostics level, message and values."""
        return self.states_of(BATTERY)

    def fly(self) -> Telemetry:
        """Take off, AUTO, and watch until the vehicle is down after an end of the mission, or
        has reached qF."""
        self.wait(lambda: self.node.vehicle.uploads_verified >= 1, 'mission on the vehicle')
        take_off(self.link, 100.0)
        set_mode(self.link, 'AUTO')
        watch = Telemetry(self.link)

        def ended() -> bool:
            progress = self.node.progress
            over = progress.started and progress.over(watch.now_s) and not progress.ended
            down = (watch.rows and progress.ended and watch.rows[-1][3] < DOWN_M
                    and watch.rows[-1][4] < DOWN_M)
            return bool(over or down)
        self.watch(watch, ended, 'end of the flight')
        return watch


@pytest.fixture
def battery_flight(ros_context, tmp_path):
    yield from flights(ros_context, tmp_path, BatteryFlight)


def check_the_end(f: BatteryFlight, watch: Telemetry, action: str, reserve: float) -> dict:
    """The flight ended at qF with the reserve, or clearly: the reason on /diagnostics and
    planner_status, the vehicle in ``action``'s mode, down where that puts it at the landing
    speed with the reserve left. Returns the figures (autopilot seconds after the clock's
    start)."""
    progress = f.node.progress
    clock_s = progress.segments[0].start_s
    used = [(t - clock_s, j / 3600.0, pct) for t, j, pct in watch.battery if t >= clock_s]
    checks = [(float(values['time_s']) - clock_s, level, values['battery_decision'])
              for level, _, values in f.battery_states if 'battery_decision' in values]
    changes = [check for k, check in enumerate(checks) if k == 0 or check[1:] != checks[k - 1][1:]]
    print(f'\nclock started at {clock_s:.1f} s with {used[0][1]:.2f} Wh used, {used[0][2]} % '
          f'left; checks (s after the start, level, decision) as they changed: {changes}; '
          f'{len(progress.segments)} plans')
    figures = {'clock_s': clock_s, 'used': used, 'checks': changes}
    if not progress.ended:
        print(f'reached qF with {used[-1][1]:.2f} Wh used, {used[-1][2]} % left')
        assert used[-1][2] >= 100 * reserve
        return figures
    print('ended:', progress.ended)
    assert 'cannot reach qF with its reserve' in progress.ended
    errors = [(message, values) for level, message, values in f.battery_states
              if level == DiagnosticStatus.ERROR]
    assert errors and errors[-1][0] == progress.ended
    values = errors[-1][1]
    print({key: values[key] for key in ('capacity_wh', 'checked_allowance_wh',
                                        'checked_needed_wh', 'checked_least_wh')})
    # Ended by the check, or by the failure of the replan it asked for.
    assert values['battery_action'] == action and values['battery_decision'] in ('end', 'replan')
    if values['battery_decision'] == 'end':
        assert float(values['checked_least_wh']) > float(values['checked_allowance_wh'])
    assert f'refused: {progress.ended}' in f.statuses
    ended_at = watch.mode_at(END_MODES[action])
    assert ended_at is not None, f'the vehicle never took {END_MODES[action]}: {watch.modes}'
    # Where it came down: home for rtl, where it was told for land; with the reserve left.
    _, east, north, up, _ = watch.rows[-1]
    told = min(watch.rows, key=lambda row: abs(row[0] - ended_at))
    where = (0.0, 0.0) if action == 'rtl' else (told[1], told[2])
    print(f'{END_MODES[action][0]} {ended_at - clock_s:.1f} s after the clock\'s start at '
          f'({told[1]:.1f}, {told[2]:.1f}) m; down at ({east:.1f}, {north:.1f}) m, '
          f'{math.dist((east, north), where):.1f} m from '
          f'{"home" if action == "rtl" else "where it was told"}, {used[-1][1]:.2f} Wh used, '
          f'{used[-1][2]} % left')
    assert math.dist((east, north), where) <= 5.0 and up < DOWN_M
    assert used[-1][2] >= 100 * reserve
    # Down at the landing speed, not fallen (the simulator says how fast it hit the ground).
    hits = [float(text.split(' at ')[1].split()[0]) for _, text in watch.texts
            if 'Hit ground' in text]
    assert all(speed <= 1.0 for speed in hits), hits
    figures.update(ended_at=ended_at, values=values)
    return figures


@pytest.mark.parametrize('action', ['land', 'rtl'])
def test_a_battery_smaller_than_told_ends_the_mission_at_q0(battery_flight, action):
    f = battery_flight(battery_action=action)
    figures = check_the_end(f, f.fly(), action, RESERVE)
    # With this battery the plan cannot be flown: it ends, decided at the first check (within
    # a replan interval of the clock's start), having seen the battery smaller than told.
    assert f.node.progress.ended and figures['values']['battery_decision'] == 'end'
    assert figures['ended_at'] - figures['clock_s'] <= f.node.config.node.replan_interval_s
    assert float(figures['values']['capacity_wh']) < 0.75 * STATED_WH


def test_a_wind_stronger_than_told_ends_at_qf_with_the_reserve_or_clearly(battery_flight):
    """The node told the battery the autopilot's charge implies and still air, the SITL blows
    7 m/s across the track: the flight costs more than planned as it goes, which only the
    battery's reports show (ArduCopter SITL estimates no wind)."""
    f = battery_flight(sitl={'SIM_WIND_SPD': 7.0, 'SIM_WIND_DIR': 0.0, 'SIM_WIND_TURB': 0.0},
                       battery_wh=38.0, battery_reserve=0.15, start_m=[0.0, 0.0],
                       goal_m=[1400.0, 0.0], horizon_s=180.0, num_slots=45,
                       battery_action='rtl')
    check_the_end(f, f.fly(), 'rtl', 0.15)


def test_a_battery_that_flies_the_plan_is_kept_to_qf(battery_flight):
    """The control of the wind flight: the same mission and battery in still air is kept at
    every check and reaches qF with more than the reserve, the drain as the model says."""
    f = battery_flight(battery_wh=38.0, battery_reserve=0.15, start_m=[0.0, 0.0],
                       goal_m=[1400.0, 0.0], horizon_s=180.0, num_slots=45,
                       battery_action='rtl')
    figures = check_the_end(f, f.fly(), 'rtl', 0.15)
    battery = f.node.vehicle.battery
    print(f'drain ratio {battery.ratio:.4f}; decision {battery.decision.reason}')
    assert not f.node.progress.ended and battery.replans == 0
    assert {decision for _, _, decision in figures['checks']} == {'keep'}
    assert battery.ratio <= 1.03
