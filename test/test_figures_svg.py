"""Every figure rendered to SVG and read back as text: its ticks, titles and legends, as a
reader of the paper sees them.

matplotlib writes text as ``<text>`` elements with ``svg.fonttype`` 'none', and a text with
mathematics (``$P_T$``) as glyphs preceded by a comment holding its source; each line of a
title is one of these in the title's group.
"""

from __future__ import annotations

import textwrap
import xml.etree.ElementTree as ElementTree

import matplotlib
import numpy as np
import pytest

from uav_comm_planner.core.optimizer import plan, throughput_upper_bound
from uav_comm_planner.core.scenario import paper_scenario
from uav_comm_planner.tools import plots
from uav_comm_planner.tools.study import plots as study_plots
from uav_comm_planner.tools.study.design import StudyDesign
from uav_comm_planner.tools.study.methods import METHODS
from uav_comm_planner.tools.study.tables import summary

SVG = '{http://www.w3.org/2000/svg}'
STATIC = 'static access point, optimal power (ignores launch and landing)'


@pytest.fixture(autouse=True)
def text_as_text():
    with matplotlib.rc_context({'svg.fonttype': 'none'}):
        yield


def _lines(group) -> list[str]:
    """The lines of one text group: a comment's source for mathematics, else the text."""
    lines, skip = [], False
    for child in group:
        if child.tag is ElementTree.Comment:
            lines.append(child.text.strip())
            skip = True                      # the glyphs drawn for it follow
        elif skip:
            skip = False
        elif child.tag == f'{SVG}text':
            lines.append(''.join(child.itertext()).strip())
    return lines


class Drawing:
    """An SVG figure of matplotlib's, read as text."""

    def __init__(self, path) -> None:
        parser = ElementTree.XMLParser(target=ElementTree.TreeBuilder(insert_comments=True))
        self.root = ElementTree.parse(path, parser).getroot()
        self.figure = self._group(self.root, 'figure_1')

    @staticmethod
    def _group(parent, gid):
        return next(g for g in parent.iter(f'{SVG}g') if g.get('id') == gid)

    @staticmethod
    def _texts(parent) -> list[str]:
        """The text of every text group directly inside ``parent``, lines joined by '\\n'."""
        return ['\n'.join(_lines(g)) for g in parent.findall(f'{SVG}g')
                if g.get('id', '').startswith('text_')]

    @property
    def suptitle(self) -> str:
        (title,) = self._texts(self.figure)
        return title

    def axes(self) -> list:
        return [g for g in self.figure.findall(f'{SVG}g') if g.get('id', '').startswith('axes_')]

    def ticks(self, axes, axis: str = 'x') -> list[str]:
        """The labels of the major ticks of ``axis`` ('x' or 'y')."""
        # The axes' two axis groups, x then y (numbered across the whole figure).
        group = [g for g in axes.findall(f'{SVG}g')
                 if g.get('id', '').startswith('matplotlib.axis_')]['xy'.index(axis)]
        labels = []
        for tick in group.findall(f'{SVG}g'):
            if tick.get('id', '').startswith(f'{axis}tick_'):
                labels += self._texts(tick)
        return labels

    def texts(self, axes) -> list[str]:
        """Title, axis labels, annotations and legend entries of ``axes``."""
        found = self._texts(axes)
        for group in axes.iter(f'{SVG}g'):
            # An axis label and legend entries sit directly in these (tick labels deeper).
            if group.get('id', '').startswith(('legend_', 'matplotlib.axis_')):
                found += self._texts(group)
        return found


def _integers(labels: list[str]) -> list[int]:
    assert labels and all(label.lstrip('−-').isdigit() for label in labels), labels
    return [int(label.replace('−', '-')) for label in labels]


# --- the letter's figures --------------------------------------------------------------------

@pytest.mark.parametrize('as_flown, how', [(False, 'as planned'),
                                           (True, 'as the vehicle flies it')])
def test_the_plan_figure_states_its_settings_and_how_its_value_was_had(
        tmp_path, as_flown, how):
    result = plan(paper_scenario('I', num_slots=12, horizon_s=36.0))
    drawing = Drawing(plots.plan_figure(result, tmp_path / 'plan.svg', as_flown=as_flown))
    assert drawing.suptitle == (
        f'case I: min average throughput {plots.format_rate(result.min_throughput)} {how}\n'
        'M = 12 slots of 3 s (T = 36 s), V = 100 m/s, H = 100 m, $P_T$ = 5 W')
    trajectory, speed, power = drawing.axes()
    assert 'trajectory' in drawing.texts(trajectory)
    assert 'speed limit V = 100 m/s' in drawing.texts(speed)
    assert _integers(drawing.ticks(speed, 'y')) == [0, 20, 40, 60, 80, 100]


def test_the_sweep_figure_has_the_upper_bound_and_the_plan_s_settings(tmp_path):
    scenario = paper_scenario('II')
    budgets = [0.5, 1.0, 2.0, 5.0]
    rows = {'proposed': [10.0, 11.0, 12.0, 13.0], 'straight': [9.0, 10.0, 11.0, 12.0],
            'static': [9.5, 10.5, 11.5, 12.5]}
    figure = plots.draw_sweep(budgets, rows, scenario=scenario)
    bound = figure.axes[0].lines[-1].get_ydata()
    assert list(bound) == [throughput_upper_bound(scenario.replace(power_budget_w=b))
                           for b in budgets]
    plots._pyplot().close(figure)
    drawing = Drawing(plots.sweep_figure(budgets, rows, tmp_path / 'sweep.svg',
                                         scenario=scenario))
    (axes,) = drawing.axes()
    assert drawing.ticks(axes) == ['0.5', '1', '2', '5']
    texts = drawing.texts(axes)
    assert ('case II: min average throughput versus $P_T$\n'
            'M = 50 slots of 1 s (T = 50 s), V = 100 m/s, H = 100 m') in texts
    for label in ('proposed (joint power and trajectory)', 'straight line, optimal power',
                  STATIC, 'upper bound (every channel at its best)'):
        assert label in texts, label


def test_a_figure_folder_is_made_when_missing(tmp_path):
    result = plan(paper_scenario('I', num_slots=6, horizon_s=30.0))
    written = plots.plan_figure(result, tmp_path / 'figs' / 'new' / 'plan.svg')
    assert written.is_file()
    (tmp_path / 'file').write_text('')
    with pytest.raises(plots.PlannerError, match="cannot make the figure folder .*file"):
        plots.plan_figure(result, tmp_path / 'file' / 'plan.svg')


# --- the study's figures ---------------------------------------------------------------------

def study_rows(design: StudyDesign, nodes, slots, count: int = 30) -> list[dict]:
    """Rows as a study's table holds them, with made-up values (the figures only draw)."""
    rng = np.random.default_rng(3)
    rows = []
    for _ in range(count):
        row = {'status': 'ok', 'nodes': int(rng.choice(nodes)), 'slots': int(rng.choice(slots)),
               'power_budget_w': float(np.exp(rng.uniform(np.log(0.5), np.log(20.0))))}
        base = rng.uniform(5.0, 10.0)
        for method, factor in (('default', 1.10), ('letter', 1.08), ('straight', 1.0),
                               ('static', 1.02), ('bound', 1.3), ('dual_bound', 1.2)):
            row[f'{method}_bps'] = base * factor * rng.uniform(0.98, 1.02)
            row[f'{method}_s'] = rng.uniform(0.05, 0.3)
        rows.append(row)
    return rows


SWEPT = StudyDesign(cases=30, draws={'nodes': '2:4', 'slots': '20,40', 'side_m': '800'})
SWEPT_TEXT = ('N = 2..4, M = {20, 40}, T = M s, H = 100 m, V = 100 m/s, $P_T$ = 5 W\n'
              '30 drops, nodes uniform in a square of side 800 m, flown from (0, 0) to '
              '(side, side)')
SINGLE = StudyDesign(cases=30, draws={'nodes': '8', 'slots': '30', 'power_budget_w': '0.5:20:log',
                                      'bandwidth_hz': '1e6'}, endpoints='across', area='disc')
SINGLE_TEXT = ('N = 8, M = 30, T = M s, H = 100 m, V = 100 m/s, $P_T$ = 0.5..20 W '
               '(log-uniform), B = 1e+06 Hz\n30 drops, nodes uniform in a disc of diameter '
               '1500 m, flown from (0, side/2) to (side, side/2)')


def test_the_cdf_states_the_study_design_and_the_static_point_s_caveat(tmp_path):
    rows = study_rows(SWEPT, [2, 3, 4], [20, 40])
    drawing = Drawing(study_plots.cdf_figure(SWEPT, rows, tmp_path / 'cdf.svg'))
    assert drawing.suptitle == f'CDF of the min throughput over 30 random scenarios\n{SWEPT_TEXT}'
    # N = 2, 3, 4 are three populations: a panel each, not one staircase.
    panels = drawing.axes()
    assert len(panels) == 3
    for axes, nodes in zip(panels, (2, 3, 4)):
        count = sum(row['nodes'] == nodes for row in rows)
        assert f'N = {nodes}: {count} scenarios' in drawing.texts(axes)
    texts = drawing.texts(panels[-1])
    assert STATIC in texts and 'upper bound' in texts


def test_the_cdf_of_one_population_is_one_panel(tmp_path):
    drawing = Drawing(study_plots.cdf_figure(SINGLE, study_rows(SINGLE, [8], [30]),
                                             tmp_path / 'cdf.svg'))
    assert len(drawing.axes()) == 1


def test_gain_against_an_integer_setting_has_integer_ticks(tmp_path):
    drawing = Drawing(study_plots.gain_figure(SWEPT, study_rows(SWEPT, [2, 3, 4], [20, 40]),
                                              tmp_path / 'gain.svg'))
    assert drawing.suptitle == f'mean gain with 95 % confidence intervals\n{SWEPT_TEXT}'
    straight, static = drawing.axes()
    for axes in (straight, static):
        assert _integers(drawing.ticks(axes)) == [2, 3, 4]
        assert 'number of ground nodes N' in drawing.texts(axes)
    assert f'over the {STATIC}' in drawing.texts(static)


def test_gain_at_a_single_value_is_a_bar_per_method(tmp_path):
    drawing = Drawing(study_plots.gain_figure(SINGLE, study_rows(SINGLE, [8], [30]),
                                              tmp_path / 'gain.svg'))
    assert drawing.suptitle == f'mean gain with 95 % confidence intervals\n{SINGLE_TEXT}'
    methods = [textwrap.fill(METHODS[m].label, 20) for m in ('default', 'letter')]
    for axes in drawing.axes():
        assert drawing.ticks(axes) == methods
        texts = drawing.texts(axes)
        assert 'number of ground nodes N = 8' in texts
        assert sum(text.endswith(' %') and text[0] in '+-' for text in texts) == 2


def test_time_at_a_single_m_is_a_labelled_point_per_method(tmp_path):
    drawing = Drawing(study_plots.time_figure(SINGLE, study_rows(SINGLE, [8], [30]),
                                              tmp_path / 'time.svg'))
    (axes,) = drawing.axes()
    assert drawing.ticks(axes) == [textwrap.fill(METHODS[m].label, 20)
                                   for m in ('default', 'letter')]
    texts = drawing.texts(axes)
    assert 'number of slots M = 30' in texts
    # Times within a decade on a linear axis from zero: no '6x10^-2' ticks.
    ticks = drawing.ticks(axes, 'y')
    assert ticks[0] == '0.00' and not any('10^' in tick or '10^{' in tick for tick in ticks)
    assert f'solve time per scenario (one worker core)\n{SINGLE_TEXT}' in texts


def test_time_against_m_is_ticked_at_the_values_of_m(tmp_path):
    drawing = Drawing(study_plots.time_figure(SWEPT, study_rows(SWEPT, [2, 3, 4], [20, 40]),
                                              tmp_path / 'time.svg'))
    (axes,) = drawing.axes()
    assert _integers(drawing.ticks(axes)) == [20, 40]


def test_all_figures_make_their_folder_and_the_summary_says_the_static_caveat(tmp_path):
    rows = study_rows(SWEPT, [2, 3, 4], [20, 40])
    written = study_plots.all_figures(SWEPT, rows, tmp_path / 'new' / 'figs', fmt='svg')
    assert [path.name for path in written] == ['cdf.svg', 'gain_vs_nodes.svg',
                                               'time_vs_slots.svg']
    lines = summary(SWEPT, rows).splitlines()
    static = [line for line in lines if line.startswith(('static', 'default over static'))]
    assert len(static) == 2
    assert all(line.endswith('(the static point ignores launch and landing)')
               for line in static)
