"""A plan round zones of thousands of vertices stops when asked, within one step: no ask of
``should_stop`` and no visibility test after the one that said stop, whether it comes while
the visibility graph is built, while the paths round the zones are searched for the starts,
or between the trajectory steps; and a graph cut short is not kept."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_detour_scaling import star

from uav_comm_planner import paper_scenario
from uav_comm_planner.core import detour
from uav_comm_planner.core.detour import corner_graph, GRAPHS
from uav_comm_planner.core.optimizer import plan
from uav_comm_planner.core.zones import Zones
from uav_comm_planner.errors import PlanCancelledError

#: Four 1000-vertex stars along the way (4000 vertices, the most zones may have).
FOUR_STARS = Zones(keep_out=tuple(star(500, centre, 150.0, 100.0) for centre in
                                  ((500.0, 50.0), (900.0, -60.0), (1300.0, 80.0),
                                   (1700.0, -40.0))), margin_m=5.0)


def graph_asks(zones: Zones) -> int:
    """How many times building the graph afresh asks its check."""
    asks = []
    GRAPHS.clear()
    corner_graph(zones, lambda: asks.append(True))
    GRAPHS.clear()
    return len(asks)


@pytest.fixture(scope='module')
def asks_in_graph() -> int:
    return graph_asks(FOUR_STARS)


@pytest.mark.parametrize('when', ['first', 'graph', 'after graph', 'later'])
def test_a_plan_round_four_thousand_vertex_stars_stops_at_the_ask_that_says_stop(
        when, asks_in_graph, monkeypatch):
    assert asks_in_graph >= 3
    stop_at = {'first': 1, 'graph': asks_in_graph // 2 + 1, 'after graph': asks_in_graph + 1,
               'later': asks_in_graph + 4}[when]
    scenario = dataclasses.replace(paper_scenario('I'), zones=FOUR_STARS, horizon_s=80.0)
    asked, tests_after = [], []
    clear = detour.segments_clear

    def counted(*args, **kwargs):
        if len(asked) >= stop_at:
            tests_after.append(True)
        return clear(*args, **kwargs)
    monkeypatch.setattr(detour, 'segments_clear', counted)

    def should_stop() -> bool:
        asked.append(True)
        return len(asked) >= stop_at
    GRAPHS.clear()
    with pytest.raises(PlanCancelledError):
        plan(scenario, should_stop=should_stop)
    print(f'{asks_in_graph} asks in the graph; stopped at ask {stop_at}')
    assert len(asked) == stop_at and not tests_after
    assert (FOUR_STARS in GRAPHS) == (stop_at > asks_in_graph)


def test_the_graph_of_four_stars_asks_between_chunks_of_at_most_its_chunk_of_pairs(
        monkeypatch):
    """Between two asks the graph tests at most GRAPH_CHUNK corner pairs."""
    tested, between = [0], []
    clear = detour.segments_clear

    def counted(zones, a, b, **kwargs):
        tested[0] += len(np.atleast_2d(a))
        return clear(zones, a, b, **kwargs)
    monkeypatch.setattr(detour, 'segments_clear', counted)

    def check() -> None:
        between.append(tested[0])
        tested[0] = 0
    GRAPHS.clear()
    corner_graph(FOUR_STARS, check)
    between.append(tested[0])
    GRAPHS.clear()
    # The corners' own test (one zero-length segment each) comes between the first two.
    print(f'segments tested between asks: {between[0]} before the first, then at most '
          f'{max(between[2:])} pairs')
    assert between[0] == 0 and max(between[2:]) <= detour.GRAPH_CHUNK
