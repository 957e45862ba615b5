"""What the plan and sweep figures draw, read back from matplotlib's artists: the propulsion
panel states the JSON's figures, the transmit power axis starts at zero, the sweep draws the
dual bound it is given, and the zones' margin is drawn where the clearance equals it."""

from __future__ import annotations

import numpy as np
import pytest

from uav_comm_planner import paper_scenario, plan
from uav_comm_planner.core.energy import JOULES_PER_WH
from uav_comm_planner.core.zones import KeepOutPolygon, OperatingArea, Zones
from uav_comm_planner.mission.energy import energy_record
from uav_comm_planner.tools import plots
from uav_comm_planner.vehicle.airframe import airframe_named

SCENARIO = dict(max_speed_mps=10.0, horizon_s=400.0, num_slots=40)


def test_a_plan_with_an_airframe_draws_the_json_s_propulsion_power_per_leg():
    result = plan(paper_scenario('I', **SCENARIO, airframe=airframe_named('zeng2019')))
    record = energy_record(result)
    figure = plots.draw_plan(result)
    assert len(figure.axes) == 4
    panel = figure.axes[3]
    assert panel.get_title() == 'propulsion power'
    drawn, mean = panel.lines
    np.testing.assert_allclose(drawn.get_ydata(), record['propulsion_power_w'], rtol=1e-12)
    np.testing.assert_allclose(drawn.get_xdata(), result.scenario.path_times_s[1:])
    duration_s = (result.scenario.num_slots + 1) * result.scenario.slot_s
    assert mean.get_ydata()[0] == pytest.approx(record['propulsion_energy_j'] / duration_s)
    assert f'{record["propulsion_energy_j"] / JOULES_PER_WH:.2f} Wh' in mean.get_label()
    assert panel.get_ylim()[0] == 0.0
    plots._pyplot().close(figure)


def test_without_an_airframe_three_panels_and_the_power_axis_from_zero():
    result = plan(paper_scenario('I', **SCENARIO))
    figure = plots.draw_plan(result)
    assert [ax.get_title() for ax in figure.axes] == ['trajectory', 'speed', 'transmit power']
    power = figure.axes[2]
    assert power.get_ylim()[0] == 0.0
    assert power.get_ylim()[1] >= max(line.get_ydata().max() for line in power.lines)
    plots._pyplot().close(figure)


def test_the_sweep_draws_the_dual_bound_it_is_given_so_labelled():
    budgets = [0.5, 1.0, 2.0]
    rows = {'proposed': [10.0, 12.0, 13.0], 'bound': [10.5, 12.4, 13.1]}
    figure = plots.draw_sweep(budgets, dict(rows), scenario=paper_scenario('I'))
    (ax,) = figure.axes
    by_label = {line.get_label(): line for line in ax.lines}
    bound = by_label['upper bound (dual over the flyable paths)']
    np.testing.assert_allclose(bound.get_ydata(), rows['bound'])
    assert 'upper bound (every channel at its best)' not in by_label
    plots._pyplot().close(figure)


def test_the_zones_margin_is_drawn_where_the_clearance_equals_it():
    zones = Zones(OperatingArea([(-200.0, -300.0), (2200.0, -300.0), (2200.0, 800.0),
                                 (-200.0, 800.0)]),
                  (KeepOutPolygon([(900.0, -250.0), (1100.0, -250.0), (1000.0, -150.0)]),),
                  margin_m=10.0)
    result = plan(paper_scenario('I', **SCENARIO, zones=zones))
    figure = plots.draw_plan(result)
    path_panel = figure.axes[0]
    margins = [line for line in path_panel.lines if line.get_linestyle() == ':']
    assert margins and margins[0].get_label() == '10 m margin'
    points = np.vstack([line.get_xydata() for line in margins])
    # A contour interpolated on a grid of 240 points a side (cells of 10 m by 5 m here): to
    # about a metre of the margin (0.87 m seen), far from the zones' edges (clearance 0).
    assert np.abs(zones.clearance(points) - 10.0).max() < 2.0
    labels = [text.get_text() for text in path_panel.get_legend().get_texts()]
    assert {'operating area', 'keep-out zone', '10 m margin'} <= set(labels)
    plots._pyplot().close(figure)
