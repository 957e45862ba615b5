"""Figures of a Monte Carlo study, drawn from its table; matplotlib is imported only here, and
only when a figure is drawn.

* :func:`cdf_figure`: the empirical CDF of min_n R_n of every method over the scenarios.
* :func:`gain_figure`: the mean gain of each optimised method over each baseline,
  100 (R_method / R_baseline - 1) %, against a setting, with 95 % confidence intervals.
* :func:`time_figure`: the solve time of each optimised method against M.

Only rows with status 'ok' (every method succeeded) are drawn, so that each method is shown
on the same scenarios. Every title states the study's design (:func:`design_text`); an
integer setting (N, M) gets integer ticks; a setting with a single value is drawn as such
(bars or points per method, the value in the axis label), not on a stretched axis; the static
access point's caveat (it ignores launch and landing) stands beside it.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Sequence

import numpy as np
from scipy import stats

from uav_comm_planner.errors import PlannerError
from uav_comm_planner.tools.plots import _pyplot, legend_label, make_folder, save_figure
from uav_comm_planner.tools.study.design import Draw, SETTINGS, StudyDesign
from uav_comm_planner.tools.study.methods import BASELINES, BOUNDS, METHODS

#: Confidence level of the intervals.
CONFIDENCE = 0.95
#: A setting with more distinct values than this is grouped into this many equal-count bins.
MAX_GROUPS = 8
#: A swept setting with at most this many values gets one CDF panel per value.
MAX_CDF_PANELS = 4
STYLES = {'default': 'o-', 'letter': 's--'}
LINES = {'default': '-', 'letter': '--', 'straight': ':', 'static': '-.',
         'bound': (0, (6, 2, 1, 2)), 'dual_bound': (0, (2, 2))}
#: How titles write each setting: its symbol and unit.
SYMBOLS = {'nodes': ('N', ''), 'slots': ('M', ''), 'horizon_s': ('T', ' s'),
           'max_speed_mps': ('V', ' m/s'), 'altitude_m': ('H', ' m'),
           'power_budget_w': ('$P_T$', ' W'), 'bandwidth_hz': ('B', ' Hz'),
           'noise_psd_dbm_per_hz': ('$\\sigma^2$', ' dBm/Hz'),
           'reference_gain': ('$\\beta_0$', ''), 'side_m': ('side', ' m')}
#: The settings every title states; the radio's only where they are not the study defaults.
ALWAYS_STATED = ('nodes', 'slots', 'horizon_s', 'max_speed_mps', 'altitude_m',
                 'power_budget_w')
ENDPOINT_TEXT = {'diagonal': 'flown from (0, 0) to (side, side)',
                 'across': 'flown from (0, side/2) to (side, side/2)',
                 'centre': 'a loop from the centre', 'random': 'start and goal drawn in it'}


def draw_text(draw: Draw, unit: str = '') -> str:
    """A setting's draw as a title writes it, with its ``unit``: '5 W', '{1, 2, 5} W',
    '2..4 W' (uniform), or '0.5..20 W (log-uniform)'."""
    if not draw.is_range:
        values = [f'{draw.cast(v):g}' for v in draw.grid]
        text = values[0] if len(values) == 1 else '{' + ', '.join(values) + '}'
        return text + unit
    return f'{draw.cast(draw.low):g}..{draw.cast(draw.high):g}{unit}' + (
        ' (log-uniform)' if draw.log else '')


def design_text(design: StudyDesign) -> str:
    """The study's design in two lines: its settings ('N = 2..4, M = 20, T = M s, ...'), and
    the area, the endpoints and the drops."""
    parts = []
    for name in SETTINGS:
        draw = design.draws.get(name)
        if name == 'side_m' or (name not in ALWAYS_STATED
                                and draw == Draw.parse(SETTINGS[name].default)):
            continue
        symbol, unit = SYMBOLS[name]
        parts.append(f'{symbol} = M s' if draw is None else f'{symbol} = {draw_text(draw, unit)}')
    side = draw_text(design.draws['side_m'], ' m')
    area = f'square of side {side}' if design.area == 'square' else f'disc of diameter {side}'
    return (', '.join(parts) + '\n' + f'{design.cases} drops, nodes uniform in a {area}, '
            f'{ENDPOINT_TEXT[design.endpoints]}')


def _setting_ticks(ax, values: np.ndarray, integer: bool) -> None:
    """x ticks at a few values of a setting themselves, else integer ones for N or M."""
    from matplotlib.ticker import MaxNLocator
    values = np.unique(values)
    if values.size <= MAX_GROUPS:
        ax.set_xticks(values, [f'{v:g}' for v in values])
    elif integer:
        ax.xaxis.set_major_locator(MaxNLocator(integer=True))


def _method_ticks(ax, methods: Sequence[str]) -> np.ndarray:
    """Positions 0..K-1 ticked with the methods' labels: one value is drawn as such."""
    import textwrap
    positions = np.arange(len(methods))
    ax.set_xticks(positions, [textwrap.fill(METHODS[m].label, 20) for m in methods],
                  fontsize=8)
    ax.set_xlim(-0.6, len(methods) - 0.4)
    return positions


def _ok(rows: Sequence[dict]) -> list[dict]:
    ok = [row for row in rows if row['status'] == 'ok']
    if not ok:
        raise PlannerError('the study has no row where every method succeeded; nothing to draw')
    return ok


def optimised_methods(design: StudyDesign) -> list[str]:
    """The methods that plan a trajectory (not a baseline, not the bound)."""
    return [m for m in design.methods if m not in BASELINES and m not in BOUNDS]


def mean_interval(values: np.ndarray, confidence: float = CONFIDENCE) -> tuple[float, float]:
    """Sample mean and the half-width of its Student-t interval, t_{(1+c)/2, n-1} s / sqrt(n)
    (NaN half-width for one value)."""
    values = np.asarray(values, dtype=float)
    mean = float(values.mean())
    if values.size < 2:
        return mean, float('nan')
    spread = float(values.std(ddof=1)) / np.sqrt(values.size)
    return mean, float(stats.t.ppf(0.5 + confidence / 2.0, values.size - 1) * spread)


def groups(x: np.ndarray, max_groups: int = MAX_GROUPS) -> list[np.ndarray]:
    """Index arrays of the rows sharing each value of ``x`` (sorted), or of ``max_groups``
    equal-count bins of it when it takes more values (a drawn range)."""
    values = np.unique(x)
    if values.size <= max_groups:
        return [np.flatnonzero(x == value) for value in values]
    order = np.argsort(x, kind='stable')
    return [chunk for chunk in np.array_split(order, max_groups) if chunk.size]


def gain_table(design: StudyDesign, rows: Sequence[dict], against: str
               ) -> dict[tuple[str, str], list[tuple[float, float, float, int]]]:
    """{(method, baseline): [(x, mean gain %, CI half-width %, n), ...]} by group of the
    setting ``against`` (x is the group's mean setting)."""
    ok = _ok(rows)
    x = np.array([row[against] for row in ok], dtype=float)
    index_groups = groups(x)
    table = {}
    for method in optimised_methods(design):
        for baseline in (b for b in BASELINES if b in design.methods):
            value = np.array([row[f'{method}_bps'] for row in ok])
            base = np.array([row[f'{baseline}_bps'] for row in ok])
            gain = 100.0 * (value / np.where(base > 0, base, np.nan) - 1.0)
            points = []
            for members in index_groups:
                finite = members[np.isfinite(gain[members])]
                if finite.size:
                    mean, half = mean_interval(gain[finite])
                    points.append((float(x[finite].mean()), mean, half, int(finite.size)))
            table[(method, baseline)] = points
    return table


def cdf_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike, *,
               against: str | None = None) -> Path:
    """Empirical CDF of the min throughput of every method over the study's scenarios: one
    panel per value of the swept setting ``against`` when it takes a few values (N = 2, 3, 4
    pooled would draw a staircase of three populations, not one distribution)."""
    ok = _ok(rows)
    against = against or default_against(design)
    setting = np.array([row[against] for row in ok], dtype=float)
    values = np.unique(setting)
    panels = values if 1 < values.size <= MAX_CDF_PANELS else np.array([np.nan])
    plt = _pyplot()
    several = panels.size > 1
    figure, axes = plt.subplots(1, panels.size, figsize=(4.2 * panels.size + 2.2 * several + 2.2,
                                                         4.6),
                                squeeze=False, sharey=True)
    for ax, value in zip(axes[0], panels):
        members = [row for row, x in zip(ok, setting) if np.isnan(value) or x == value]
        _draw_cdf(ax, design, members)
        if not np.isnan(value):
            symbol, unit = SYMBOLS.get(against, (against, ''))
            ax.set_title(f'{symbol} = {value:g}{unit}: {len(members)} scenarios', fontsize=9)
    axes[0][0].set_ylabel('fraction of scenarios')
    # Beside the panels when there are several (inside, it would hide a panel's lines).
    axes[0][-1].legend(fontsize=8, **({'loc': 'upper left', 'bbox_to_anchor': (1.02, 1.0)}
                                      if several else {'loc': 'best'}))
    figure.suptitle(f'CDF of the min throughput over {len(ok)} random scenarios\n'
                    f'{design_text(design)}', fontsize=9)
    figure.tight_layout()
    return save_figure(figure, path)


def _draw_cdf(ax, design: StudyDesign, rows: Sequence[dict]) -> None:
    """The empirical CDF of each method's min throughput over ``rows`` on ``ax``."""
    lowest, highest = np.inf, 0.0
    for method in design.methods:
        values = np.sort([row[f'{method}_bps'] for row in rows])
        fraction = np.arange(1, values.size + 1) / values.size
        ax.step(values, fraction, where='post', label=legend_label(method, METHODS[method].label),
                linestyle=LINES.get(method, '-'))
        positive = values[values > 0]
        if positive.size:
            lowest, highest = min(lowest, positive[0]), max(highest, positive[-1])
    if highest > 0 and highest / lowest > 30:
        ax.set_xscale('log')
    ax.set(xlabel='min average throughput (bit/s)', ylim=(0, 1.02))
    ax.grid(True, alpha=0.3)


def gain_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike, *,
                against: str = 'nodes') -> Path:
    """Mean gain over each baseline against ``against``, with 95 % confidence intervals."""
    if against not in SETTINGS:
        raise PlannerError(f'cannot draw against {against!r}; choose one of {list(SETTINGS)}')
    table = gain_table(design, rows, against)
    baselines = [b for b in BASELINES if b in design.methods]
    if not table or not baselines:
        raise PlannerError('the gain figure needs an optimised method and a baseline')
    methods = optimised_methods(design)
    values = np.unique([row[against] for row in _ok(rows)])
    plt = _pyplot()
    figure, axes = plt.subplots(1, len(baselines), figsize=(6.0 * len(baselines), 4.8),
                                squeeze=False)
    for ax, baseline in zip(axes[0], baselines):
        if values.size == 1:
            positions = _method_ticks(ax, methods)
            for position, method in zip(positions, methods):
                ((_, mean, half, _),) = table[(method, baseline)]
                half = float(np.nan_to_num(half))
                ax.bar(position, mean, width=0.6, yerr=half, capsize=4, color=f'C{position}')
                # The value beyond the end of its interval, clear of the bar and its cap.
                ax.annotate(f'{mean:+.1f} %', (position, mean + np.sign(mean or 1) * half),
                            textcoords='offset points', xytext=(0, 5 if mean >= 0 else -12),
                            ha='center', fontsize=8)
            ax.axhline(0.0, color='k', linewidth=0.8)
            ax.margins(y=0.15)
            ax.set_xlabel(f'{SETTINGS[against].help} = {values[0]:g}')
        else:
            for method in methods:
                x, mean, half, _ = np.array(table[(method, baseline)]).T
                ax.errorbar(x, mean, yerr=np.nan_to_num(half), fmt=STYLES.get(method, 'o-'),
                            capsize=3, label=METHODS[method].label)
            _setting_ticks(ax, values, SETTINGS[against].integer)
            ax.set_xlabel(SETTINGS[against].help)
            ax.legend(loc='best', fontsize=8)
        ax.set_ylabel('mean gain (%)')
        ax.set_title(f'over the {legend_label(baseline, METHODS[baseline].label)}', fontsize=9)
        ax.grid(True, axis='y' if values.size == 1 else 'both', alpha=0.3)
    figure.suptitle(f'mean gain with {100 * CONFIDENCE:.0f} % confidence intervals\n'
                    f'{design_text(design)}', fontsize=10)
    figure.tight_layout()
    return save_figure(figure, path)


def time_figure(design: StudyDesign, rows: Sequence[dict], path: str | os.PathLike) -> Path:
    """Solve time of each optimised method against M: every scenario, and the mean per group
    with its 95 % confidence interval; with a single M, one labelled point per method."""
    ok = _ok(rows)
    methods = optimised_methods(design)
    if not methods:
        raise PlannerError('the time figure needs an optimised method')
    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(7.6, 4.8))
    slots = np.array([row['slots'] for row in ok], dtype=float)
    single = np.unique(slots).size == 1
    if single:
        positions = _method_ticks(ax, methods)
        ax.set_xlabel(f'number of slots M = {slots[0]:g}')
    for index, method in enumerate(methods):
        seconds = np.array([row[f'{method}_s'] for row in ok], dtype=float)
        if single:
            # Every scenario spread evenly across the method's slot, its mean on top.
            spread = positions[index] + np.linspace(-0.2, 0.2, seconds.size)
            ax.plot(spread, seconds, '.', alpha=0.25, color=f'C{index}')
            mean, half = mean_interval(seconds)
            ax.errorbar(positions[index], mean, yerr=np.nan_to_num(half), fmt='o',
                        color=f'C{index}', capsize=4)
            ax.annotate(f'{mean:.3g} s', (positions[index], mean), textcoords='offset points',
                        xytext=(14, 0), va='center', fontsize=8)
            continue
        dots = ax.plot(slots, seconds, '.', alpha=0.25)[0]
        points = [(slots[m].mean(), *mean_interval(seconds[m])) for m in groups(slots)]
        x, mean, half = np.array(points).T
        ax.errorbar(x, mean, yerr=np.nan_to_num(half), fmt=STYLES.get(method, 'o-'),
                    color=dots.get_color(), capsize=3, label=METHODS[method].label)
    # A log axis only where the times span a decade: within one, it labels 6x10^-2.
    times = np.array([row[f'{method}_s'] for row in ok for method in methods], dtype=float)
    times = times[np.isfinite(times) & (times > 0)]
    if times.size and times.max() / times.min() >= 10.0:
        ax.set_yscale('log')
    else:
        ax.set_ylim(bottom=0.0)
    if not single:
        _setting_ticks(ax, slots, integer=True)
        ax.set_xlabel('number of slots M')
        ax.legend(loc='best', fontsize=8)
    ax.set_ylabel('solve time (s)')
    ax.set_title(f'solve time per scenario (one worker core)\n{design_text(design)}',
                 fontsize=9)
    ax.grid(True, which='both', alpha=0.3)
    figure.tight_layout()
    return save_figure(figure, path)


def default_against(design: StudyDesign) -> str:
    """The first swept setting, N when nothing is swept."""
    swept = [name for name in design.swept if name != 'side_m'] or design.swept
    return swept[0] if swept else 'nodes'


def all_figures(design: StudyDesign, rows: Sequence[dict], folder: str | os.PathLike, *,
                fmt: str = 'pdf', against: str | None = None) -> list[Path]:
    """cdf.FMT, gain_vs_SETTING.FMT and time_vs_slots.FMT in ``folder`` (made if missing)."""
    folder = make_folder(folder)
    against = against or default_against(design)
    written = [cdf_figure(design, rows, folder / f'cdf.{fmt}', against=against)]
    if optimised_methods(design):
        if any(b in design.methods for b in BASELINES):
            written.append(gain_figure(design, rows, folder / f'gain_vs_{against}.{fmt}',
                                       against=against))
        written.append(time_figure(design, rows, folder / f'time_vs_slots.{fmt}'))
    return written
