"""Figures of the letter's evaluation, fit for a paper; matplotlib is imported only when drawing.

The file's suffix chooses the format (``.png``, ``.pdf`` or ``.svg``); a missing folder is
made. Titles name the case (or what differs from it), state the plan's settings (M, delta, T,
V, H, P_T) and whether a throughput is as planned or as the vehicle flies it, and give rates in
scaled units (bit/s, kbit/s, Mbit/s...); the sweep draws the upper bound beside the methods;
the static access point's caveat (it ignores launch and landing) stands beside it in every
legend; legends sit outside the axes. The files carry no date and no software version, and SVG ids
come from a fixed salt, so drawing the same plan twice writes the same bytes and
``make figures`` leaves unchanged figures unchanged.
"""

from __future__ import annotations

import dataclasses
import math
import os
from pathlib import Path
from typing import Sequence

import numpy as np

from uav_comm_planner.core.model import flown_path, speeds
from uav_comm_planner.core.optimizer import PlanResult, throughput_upper_bound
from uav_comm_planner.core.scenario import paper_scenario, Scenario
from uav_comm_planner.errors import PlannerError
from uav_comm_planner.files import write_with

METHOD_LABELS = {'proposed': 'proposed (joint power and trajectory)',
                 'straight': 'straight line, optimal power',
                 'static': 'static access point, optimal power',
                 'bound': 'upper bound (every channel at its best)'}
#: Said wherever the static point's number is shown: it hovers over the nodes' centroid for
#: the whole horizon, never flying from q0 nor to qF, as in the letter's comparison.
STATIC_CAVEAT = 'ignores launch and landing'

#: Suffix -> what the file omits so that the same figure gives the same bytes.
FIGURE_METADATA = {
    'png': {'Software': None},
    'pdf': {'Creator': None, 'Producer': None, 'CreationDate': None},
    'svg': {'Creator': None, 'Date': None},
}
FIGURE_FORMATS = tuple(FIGURE_METADATA)
#: Salt of the ids in SVG files (matplotlib draws a random one otherwise).
SVG_HASH_SALT = 'uav_comm_planner'
DPI = 150

_RATE_UNITS = ((1e12, 'Tbit/s'), (1e9, 'Gbit/s'), (1e6, 'Mbit/s'), (1e3, 'kbit/s'),
               (1.0, 'bit/s'))
_FREQUENCY_UNITS = ((1e9, 'GHz'), (1e6, 'MHz'), (1e3, 'kHz'), (1.0, 'Hz'))


def _scaled(value: float, units: Sequence[tuple[float, str]]) -> tuple[float, str]:
    """(factor, unit) of the largest unit not above |value| (the smallest unit below it)."""
    for factor, unit in units:
        if abs(value) >= factor:
            return factor, unit
    return units[-1]


def rate_unit(value_bps: float) -> tuple[float, str]:
    """(factor, unit) to show ``value_bps``: 841201.7 -> (1e3, 'kbit/s')."""
    return _scaled(value_bps, _RATE_UNITS)


def format_rate(value_bps: float) -> str:
    """A rate with four significant digits in its unit: 841201.683 -> '841.2 kbit/s'."""
    rounded = float(f'{value_bps:.4g}')   # 999.95 is shown as 1 kbit/s, not 1000 bit/s
    factor, unit = rate_unit(rounded)
    return f'{rounded / factor:.4g} {unit}'


def _frequency(value_hz: float) -> str:
    factor, unit = _scaled(value_hz, _FREQUENCY_UNITS)
    return f'{value_hz / factor:g} {unit}'


def _point(point: Sequence[float]) -> str:
    return f'({point[0]:g}, {point[1]:g}) m'


def legend_label(method: str, label: str | None = None) -> str:
    """``label`` (default: :data:`METHOD_LABELS`'s) of ``method``, with the static point's
    caveat."""
    label = label or METHOD_LABELS.get(method, method)
    return f'{label} ({STATIC_CAVEAT})' if method == 'static' else label


def settings_text(scenario: Scenario) -> str:
    """The settings every title states: 'M = 50 slots of 1 s (T = 50 s), V = 100 m/s,
    H = 100 m'."""
    return (f'M = {scenario.num_slots} slots of {scenario.slot_s:.4g} s '
            f'(T = {scenario.horizon_s:g} s), V = {scenario.max_speed_mps:g} m/s, '
            f'H = {scenario.altitude_m:g} m')


#: The settings :func:`settings_text` states, which titles leave out of the scenario's label.
STATED_SETTINGS = ('num_slots', 'horizon_s', 'max_speed_mps', 'altitude_m')


#: How a setting that differs from the letter's case is named in a title.
_SETTING_TEXT = {
    'altitude_m': lambda v: f'H = {v:g} m',
    'max_speed_mps': lambda v: f'V = {v:g} m/s',
    'horizon_s': lambda v: f'T = {v:g} s',
    'num_slots': lambda v: f'M = {v}',
    'bandwidth_hz': lambda v: f'B = {_frequency(v)}',
    'noise_psd_dbm_per_hz': lambda v: f'$\\sigma^2$ = {v:g} dBm/Hz',
    'reference_gain': lambda v: f'$\\beta_0$ = {10 * math.log10(v):.3g} dB',
    'start_m': lambda v: f'$q_0$ = {_point(v)}',
    'goal_m': lambda v: f'$q_F$ = {_point(v)}',
    'wind_speed_mps': lambda v: f'wind {v:g} m/s',
    'max_airspeed_mps': lambda v: f'airspeed {v:g} m/s',
    'zones': lambda v: 'with zones' if v is not None and not v.empty else 'no zones',
    'energy_budget_wh': lambda v: f'energy {v:g} Wh',
}
#: Settings a title leaves to the others (the wind's direction goes with its speed, the
#: airframe with the energy budget and the plan's energy figures).
_UNSTATED = {'ground_nodes_m', 'power_budget_w', 'wind_from_deg', 'airframe'}


def scenario_label(scenario: Scenario, *, besides: Sequence[str] = ()) -> str:
    """'case I', 'case II', 'case I, B = 1 MHz, beta0 = -60 dB' or 'N nodes, M slots'.

    The letter's case whose settings differ least (P_T aside, which titles give apart) names
    the scenario when the ground nodes are the letter's; the differing settings follow, except
    those named in ``besides`` (a title that states them apart).
    """
    best = None
    for case in ('I', 'II'):
        reference = paper_scenario(case, power_budget_w=scenario.power_budget_w)
        if reference.ground_nodes_m != scenario.ground_nodes_m:
            continue
        changed = [name for name in _SETTING_TEXT
                   if getattr(reference, name) != getattr(scenario, name)]
        unnamed = [f.name for f in dataclasses.fields(Scenario)
                   if f.name not in _SETTING_TEXT and f.name not in _UNSTATED
                   and getattr(reference, f.name) != getattr(scenario, f.name)]
        if not unnamed and (best is None or len(changed) < len(best[1])):
            best = (case, changed)
    if best is None:
        nodes = f'{scenario.num_nodes} ground nodes'
        return nodes if 'num_slots' in besides else f'{nodes}, M = {scenario.num_slots}'
    case, changed = best
    named = [_SETTING_TEXT[name](getattr(scenario, name)) for name in changed
             if name not in besides]
    return ', '.join([f'case {case}', *named])


def check_figure_path(path: str | os.PathLike) -> str:
    """The format named by the suffix of ``path``; a PlannerError for any other suffix."""
    suffix = Path(path).suffix.lower().lstrip('.')
    if suffix not in FIGURE_FORMATS:
        raise PlannerError(f'unknown figure format for {str(path)!r}: use a '
                           f'{", ".join("." + s for s in FIGURE_FORMATS)} file')
    return suffix


def make_folder(folder: str | os.PathLike) -> Path:
    """Make ``folder`` (and its parents) if missing; a PlannerError that says why when it
    cannot be made (a file in the way, no permission)."""
    folder = Path(folder)
    try:
        folder.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise PlannerError(f'cannot make the figure folder {str(folder)!r}: '
                           f'{exc.strerror or exc}') from None
    return folder


def _pyplot():
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    return plt


def save_figure(figure, path: str | os.PathLike) -> Path:
    """Write ``figure`` atomically in the format of the suffix, without date or version, in a
    folder made if missing."""
    import matplotlib

    fmt = check_figure_path(path)
    make_folder(Path(path).parent)
    with matplotlib.rc_context({'svg.hashsalt': SVG_HASH_SALT}):
        written = write_with(path, lambda temporary: figure.savefig(
            temporary, format=fmt, dpi=DPI, metadata=FIGURE_METADATA[fmt]))
    _pyplot().close(figure)
    return written


def _legend_below(ax, columns: int = 1) -> None:
    ax.legend(loc='upper center', bbox_to_anchor=(0.5, -0.13), ncol=columns, fontsize=8,
              frameon=False)


def plan_title(result: PlanResult, *, as_flown: bool = False) -> str:
    """Two lines: the scenario and its min throughput, said to be as planned or (``as_flown``:
    a vehicle-aware plan) as the vehicle flies it; the settings and P_T."""
    scenario = result.scenario
    how = 'as the vehicle flies it' if as_flown else 'as planned'
    return (f'{scenario_label(scenario, besides=STATED_SETTINGS)}: min average throughput '
            f'{format_rate(result.min_throughput)} {how}\n{settings_text(scenario)}, '
            f'$P_T$ = {scenario.power_budget_w:g} W')


def draw_plan(result: PlanResult, *, title: str = '', as_flown: bool = False):
    """The letter's Fig. 1 for one plan: trajectory, speed per leg, power per node per slot;
    and, when the scenario has an airframe, the propulsion power per leg (:func:`draw_propulsion`).

    The title (by default :func:`plan_title`) says whether the throughput is as planned or,
    ``as_flown``, as the vehicle flies it. Returns the matplotlib figure; :func:`plan_figure`
    draws and saves it.
    """
    plt = _pyplot()
    scenario = result.scenario
    panels = 3 if scenario.airframe is None else 4
    figure, axes = plt.subplots(1, panels, figsize=(5 * panels, 5.2), layout='constrained')
    ax_path, ax_speed, ax_power = axes[:3]
    path_xy = flown_path(result.trajectory, scenario)
    if scenario.zones is not None:
        _draw_zones(ax_path, scenario.zones, np.vstack([path_xy, scenario.nodes]))
    ax_path.plot(path_xy[:, 0], path_xy[:, 1], '.-', color='tab:blue', markersize=4,
                 label='UAV path')
    w = scenario.nodes
    ax_path.plot(w[:, 0], w[:, 1], '^', color='tab:red', markersize=10, label='ground nodes')
    for n, (x, y) in enumerate(w, start=1):
        ax_path.annotate(f'node {n}', (x, y), textcoords='offset points', xytext=(0, -16),
                         ha='center', va='top', fontsize=8,
                         bbox={'boxstyle': 'round,pad=0.2', 'fc': 'white', 'ec': 'none',
                               'alpha': 0.85})
    ax_path.plot(*scenario.start_m, 's', color='k', markersize=8, label='start $q_0$')
    ax_path.plot(*scenario.goal_m, '*', color='k', markersize=12, label='end $q_F$')
    ax_path.set(xlabel='x (m)', ylabel='y (m)', title='trajectory')
    ax_path.set_aspect('equal', adjustable='datalim')
    ax_path.margins(0.08)
    _legend_below(ax_path, columns=2)

    leg_end_times = scenario.path_times_s[1:]
    ax_speed.step(leg_end_times, speeds(result.trajectory, scenario), where='pre',
                  label='speed per leg')
    ax_speed.axhline(scenario.max_speed_mps, color='grey', linestyle=':',
                     label=f'speed limit V = {scenario.max_speed_mps:g} m/s')
    ax_speed.set_ylim(0.0, 1.12 * scenario.max_speed_mps)
    ax_speed.set(xlabel='time (s)', ylabel='speed (m/s)', title='speed')
    _legend_below(ax_speed)

    watts = 1.0 if result.power.max(initial=0.0) >= 0.1 else 1e-3
    styles = ('o-', 's--', '^:', 'd-.', 'v-')
    for n, p_n in enumerate(result.power, start=1):
        ax_power.plot(result.times, p_n / watts, styles[(n - 1) % len(styles)], markersize=3,
                      label=f'node {n}')
    ax_power.set(xlabel='time (s)', ylabel=f'transmit power ({"W" if watts == 1 else "mW"})',
                 title='transmit power')
    ax_power.set_ylim(bottom=0.0)            # from zero: a cut axis exaggerates differences
    _legend_below(ax_power, columns=min(scenario.num_nodes, 5))
    if scenario.airframe is not None:
        draw_propulsion(axes[3], result)
    figure.suptitle(title or plan_title(result, as_flown=as_flown))
    return figure


def draw_propulsion(ax, result: PlanResult) -> None:
    """The propulsion power of each leg q0 -> q[1] -> ... -> q[M] -> qF as the JSON result
    states it (``propulsion_power_w``: the leg flown at constant velocity over its slot, at its
    airspeed in the wind told), with its mean and the horizon's energy in the legend."""
    from uav_comm_planner.core.energy import JOULES_PER_WH
    from uav_comm_planner.mission.energy import energy_figures
    scenario = result.scenario
    figures = energy_figures(result)
    powers = np.asarray(figures.leg_powers_w)
    ax.step(scenario.path_times_s[1:], powers, where='pre', color='tab:orange',
            label=f'propulsion power ({scenario.airframe.name})')
    ax.axhline(powers.mean(), color='grey', linestyle=':',
               label=f'mean {powers.mean():.1f} W: {figures.horizon_j / JOULES_PER_WH:.2f} Wh '
                     f'over the horizon')
    ax.set_ylim(0.0, 1.12 * powers.max(initial=1.0))
    ax.set(xlabel='time (s)', ylabel='propulsion power (W)', title='propulsion power')
    _legend_below(ax)


#: Grid points per side on which the zones' margin is drawn (as the contour where the
#: clearance equals it), and points whose clearance is computed at once.
MARGIN_GRID = 240
MARGIN_CHUNK = 4096


def _draw_zones(ax, zones, points: np.ndarray) -> None:
    """The operating area's edge (green, dashed), the keep-out zones (red, filled) and, dotted,
    the line the plan keeps to: their margin (where the clearance from the zones equals it),
    over the box round the zones and ``points`` (K, 2) metres."""
    from uav_comm_planner.vehicle.fence import zone_outlines
    outlines = zone_outlines(zones)
    if zones.margin_m > 0 and outlines:
        corners = np.vstack([points, *(ring for _, ring in outlines)])
        low = corners.min(axis=0) - 2 * zones.margin_m
        high = corners.max(axis=0) + 2 * zones.margin_m
        gx, gy = np.meshgrid(np.linspace(low[0], high[0], MARGIN_GRID),
                             np.linspace(low[1], high[1], MARGIN_GRID))
        grid = np.column_stack([gx.ravel(), gy.ravel()])
        clearance = np.concatenate([zones.clearance(grid[i:i + MARGIN_CHUNK])
                                    for i in range(0, len(grid), MARGIN_CHUNK)])
        import contourpy              # matplotlib's own contouring, drawn as plain lines
        lines = contourpy.contour_generator(gx, gy, clearance.reshape(gx.shape)).lines(
            zones.margin_m)
        for k, line in enumerate(lines):
            ax.plot(line[:, 0], line[:, 1], ':', color='tab:red', linewidth=1.0,
                    label=None if k else f'{zones.margin_m:g} m margin')
    labelled = set()
    for kind, ring in outlines:
        label = None if kind in labelled else {'area': 'operating area',
                                               'keep_out': 'keep-out zone'}[kind]
        labelled.add(kind)
        if kind == 'area':
            ax.plot(ring[:, 0], ring[:, 1], '--', color='tab:green', linewidth=1.2,
                    label=label)
        else:
            ax.fill(ring[:, 0], ring[:, 1], color='tab:red', alpha=0.25, linewidth=1.0,
                    edgecolor='tab:red', label=label)


def plan_figure(result: PlanResult, path: str | os.PathLike, *, title: str = '',
                as_flown: bool = False) -> Path:
    """Draw :func:`draw_plan` into ``path`` (.png, .pdf or .svg) atomically."""
    check_figure_path(path)
    return save_figure(draw_plan(result, title=title, as_flown=as_flown), path)


def draw_sweep(budgets_w: Sequence[float], rows: dict[str, Sequence[float]], *,
               scenario: Scenario | None = None, title: str = ''):
    """The letter's Fig. 2: minimum average throughput against the power budget P_T.

    ``rows`` maps a method ('proposed', 'straight', 'static') to its min throughput at each
    budget, bit/s, and 'bound' to an upper bound there (the sweep command's: the dual bound
    over the flyable paths); the axis ticks are the budgets swept. With the ``scenario`` swept
    and no 'bound' row, the loose bound (every channel at its best,
    :func:`~uav_comm_planner.core.optimizer.throughput_upper_bound`) is drawn, so labelled;
    the title states the scenario's settings. Returns the matplotlib figure.
    """
    from matplotlib.ticker import FuncFormatter, NullLocator

    plt = _pyplot()
    figure, ax = plt.subplots(figsize=(6.4, 5.0), layout='constrained')
    rows = dict(rows)
    labels = {'bound': 'upper bound (dual over the flyable paths)'}
    if scenario is not None and 'bound' not in rows:
        rows['bound'] = [throughput_upper_bound(scenario.replace(power_budget_w=float(b)))
                         for b in budgets_w]
        labels['bound'] = 'upper bound (every channel at its best)'
    rows = {name: [math.nan if not math.isfinite(v) else v for v in values]
            for name, values in rows.items()}
    largest = max((abs(v) for values in rows.values() for v in values if math.isfinite(v)),
                  default=1.0)
    factor, unit = rate_unit(largest)
    markers = {'proposed': 'o-', 'straight': 's--', 'static': '^:', 'bound': 'k-.'}
    for name, values in rows.items():
        ax.plot(budgets_w, [v / factor for v in values], markers.get(name, '.-'),
                label=labels.get(name) or legend_label(name))
    ax.set_xscale('log')
    ax.set_xticks(list(budgets_w))
    ax.xaxis.set_major_formatter(FuncFormatter(lambda value, _: f'{value:g}'))
    ax.xaxis.set_minor_locator(NullLocator())
    if not title:
        title = 'min average throughput versus $P_T$'
        if scenario is not None:
            title = (f'{scenario_label(scenario, besides=STATED_SETTINGS)}: {title}\n'
                     f'{settings_text(scenario)}')
    ax.set(xlabel='power budget $P_T$ (W)', ylabel=f'min average throughput ({unit})',
           title=title)
    ax.grid(True, alpha=0.3)
    _legend_below(ax)
    return figure


def sweep_figure(budgets_w: Sequence[float], rows: dict[str, Sequence[float]],
                 path: str | os.PathLike, *, scenario: Scenario | None = None,
                 title: str = '') -> Path:
    """Draw :func:`draw_sweep` into ``path`` (.png, .pdf or .svg) atomically."""
    check_figure_path(path)
    return save_figure(draw_sweep(budgets_w, rows, scenario=scenario, title=title), path)
