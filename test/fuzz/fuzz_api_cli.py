"""Seeded fuzzing of the API, the command line and mission export (``make fuzz``).

Each case draws hostile input (wrong types, NaN, infinities, overflowing and underflowing
numbers, junk strings, bad files and paths) and checks that the package answers with a valid,
finite result or a typed error (:class:`~uav_comm_planner.errors.PlannerError`); the command
line with exit 0 or exit 2 and one line on stderr; and that no file is left behind by a
refusal, no temporary file by anything. Prints the counts per kind and outcome and every
failure; exits 1 if there was one.

    python test/fuzz/fuzz_api_cli.py --cases 10000 --seed 1
"""

from __future__ import annotations

import json
import math
from pathlib import Path
import sys
import tempfile
import traceback

from fuzz_report import fuzz_main, SeededFuzzer
import numpy as np

from uav_comm_planner import plan, PlannerError, Scenario, SolverSettings
from uav_comm_planner.core.model import leg_lengths
from uav_comm_planner.files import PARTIAL_MARK
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.serialize import result_to_dict
from uav_comm_planner.vehicle.geodesy import Home
from uav_comm_planner.vehicle.mavlink.files import export_mission
from uav_comm_planner.vehicle.mavlink.items import build_mission_items

FIELDS = ('altitude_m', 'max_speed_mps', 'horizon_s', 'num_slots', 'start_m', 'goal_m',
          'bandwidth_hz', 'noise_psd_dbm_per_hz', 'reference_gain', 'power_budget_w')
SETTINGS = ('tolerance_bps', 'relative_tolerance', 'max_outer_iterations',
            'max_inner_iterations', 'max_nodes', 'max_node_slots', 'compute_baselines',
            'starts')
FLAGS = ('--altitude', '--speed', '--horizon', '--slots', '--bandwidth', '--noise-dbm',
         '--beta0', '--budget', '--tolerance', '--max-nodes', '--max-node-slots', '--start',
         '--goal', '--nodes', '--home', '--case', '--mission-end', '--firmware', '--letter')
SPECIAL_FLOATS = (0.0, -0.0, 1e-300, 5e-324, 1e300, 1e308, -1e308, math.inf, -math.inf,
                  math.nan, 1e6, -1e6, 2.0 ** 63, 1e-9)


class Fuzzer(SeededFuzzer):

    # Values.

    def number(self) -> object:
        kind = self.rng.random()
        if kind < 0.3:
            return self.rng.choice(SPECIAL_FLOATS)
        if kind < 0.55:
            return 10.0 ** self.rng.uniform(-12, 12) * self.rng.choice((1, 1, 1, -1))
        if kind < 0.7:
            return self.rng.choice((0, 1, 2, 7, 50, -1, 10 ** 18, 10 ** 400, 3_000_000))
        return self.rng.choice((True, None, 'x', '12', [1.0], (1.0, 2.0, 3.0), {'a': 1},
                                np.float64(3.0), np.int64(5), np.nan, b'1'))

    def value(self) -> object:
        kind = self.rng.random()
        if kind < 0.6:
            return self.number()
        if kind < 0.85:
            return (self.number(), self.number()) if self.rng.random() < 0.5 else [
                self.number(), self.number()]
        return self.rng.choice(('12', [], [[1, 2], [1, 2]], None, [[0, 0]] * 3,
                                np.zeros((2, 2)), [[1e300, 0]], 'abc'))

    def small_scenario(self) -> dict:
        count = self.rng.randint(1, 4)
        span = 10.0 ** self.rng.uniform(0, 4)
        point = (lambda: (self.rng.uniform(-span, span), self.rng.uniform(-span, span)))
        slots = self.rng.randint(1, 8)
        horizon, speed = slots * 10.0 ** self.rng.uniform(0, 3), 10.0 ** self.rng.uniform(-1, 3)
        start, goal = point(), point()
        if self.rng.random() < 0.7:  # mostly a goal within reach, so that plans run
            reach = self.rng.uniform(0.0, 1.0) * (slots + 1) * speed * horizon / slots
            angle = self.rng.uniform(0.0, 2 * math.pi)
            goal = (start[0] + reach * math.cos(angle), start[1] + reach * math.sin(angle))
        fields = dict(ground_nodes_m=[point() for _ in range(count)], start_m=start,
                      goal_m=goal, num_slots=slots, horizon_s=horizon,
                      altitude_m=10.0 ** self.rng.uniform(-1, 4), max_speed_mps=speed,
                      bandwidth_hz=10.0 ** self.rng.uniform(-3, 9),
                      noise_psd_dbm_per_hz=self.rng.uniform(-250.0, 150.0),
                      reference_gain=10.0 ** self.rng.uniform(-15, 1),
                      power_budget_w=10.0 ** self.rng.uniform(-10, 5))
        for _ in range(self.rng.choice((0, 0, 1, 2))):
            fields[self.rng.choice(FIELDS)] = self.value()
        return fields

    # Checks.

    def check_result(self, kind: str, result, what: str) -> None:
        scenario = result.scenario
        arrays = (result.trajectory, result.power, result.rates)
        if not all(np.all(np.isfinite(a)) for a in arrays):
            self.fail(kind, what, 'non-finite plan')
        elif leg_lengths(result.trajectory, scenario).max() > scenario.max_step_m * (1 + 1e-9):
            self.fail(kind, what, 'a leg exceeds V delta')
        elif result.power.sum() > scenario.power_budget_w * (1 + 1e-9):
            self.fail(kind, what, 'power over the budget')
        else:
            try:
                json.loads(cli.json_text(result_to_dict(result)))
            except PlannerError as exc:
                self.fail(kind, what, f'result not finite JSON: {exc}')

    def typed(self, kind: str, what: str, call):
        """Run ``call``; a PlannerError is a refusal, anything else a failure."""
        try:
            value = call()
        except PlannerError as exc:
            self.counts[(kind, f'refused {type(exc).__name__}')] += 1
            return None
        except Exception as exc:  # noqa: B902 - any untyped exception is what we look for
            self.fail(kind, what, f'untyped {type(exc).__name__}: {exc}\n'
                      + ''.join(traceback.format_exc(limit=-3)))
            return None
        self.counts[(kind, 'ok')] += 1
        return value

    def leftovers(self, folder: Path, refused: bool) -> list[str]:
        names = sorted(p.name for p in folder.rglob('*') if p.is_file())
        stray = [n for n in names if PARTIAL_MARK in n]
        return stray + (names if refused else [])

    # Cases.

    def case_scenario(self) -> None:
        fields = self.small_scenario()
        if self.rng.random() < 0.3:
            fields['ground_nodes_m'] = self.value()
        scenario = self.typed('scenario', repr(fields)[:300], lambda: Scenario(**fields))
        if scenario is not None and self.rng.random() < 0.5:
            result = self.typed('plan', repr(fields)[:300], lambda: plan(scenario))
            if result is not None:
                self.check_result('plan', result, repr(fields)[:300])

    def case_settings(self) -> None:
        changes = {self.rng.choice(SETTINGS): self.value() for _ in range(self.rng.randint(1, 3))}
        self.typed('settings', repr(changes)[:300], lambda: SolverSettings(**changes))

    def case_plan_arguments(self) -> None:
        scenario = self.rng.choice((None, 5, 'I', Scenario(ground_nodes_m=[(0.0, 0.0)],
                                                           goal_m=(10.0, 0.0), num_slots=3)))
        settings = self.rng.choice((None, 'fast', SolverSettings(max_node_slots=2)))
        methods = dict(power_method=self.rng.choice(('waterfilling', 'newton', None, 3)),
                       trajectory_method=self.rng.choice(('clarabel', 'cvxpy', 'x', [1])))
        what = f'plan({scenario!r}, {settings!r}, {methods})'[:300]
        self.typed('plan-arguments', what, lambda: plan(scenario, settings, **methods))

    def case_mission(self) -> None:
        fields = self.small_scenario()
        try:
            result = plan(Scenario(**fields), SolverSettings(compute_baselines=False))
        except PlannerError:
            self.counts[('mission', 'no plan')] += 1
            return
        home = (self.rng.uniform(-90, 90), self.rng.uniform(-180, 180),
                self.rng.uniform(-1000, 10000))
        if self.rng.random() < 0.3:
            home = tuple(self.number() if self.rng.random() < 0.4 else v for v in home)
        firmware = self.rng.choice(('ardupilot', 'px4', 'inav'))
        name = self.rng.choice(('m.waypoints', 'm.plan', 'm.txt', 'sub', '.'))
        with tempfile.TemporaryDirectory(dir=self.folder) as folder:
            (Path(folder) / 'sub').mkdir()

            def export():
                anchor = Home(*home)
                items = build_mission_items(result, anchor, firmware=firmware)
                path = export_mission(result, Path(folder) / name, anchor, firmware=firmware)
                return items, path
            done = self.typed('mission', f'{fields!r} home={home} {firmware} {name}'[:300],
                              export)
            stray = self.leftovers(Path(folder), refused=done is None)
            if stray:
                self.fail('mission', name, f'files left: {stray}')
            if done is not None:
                items, path = done
                values = [v for item in items for v in (*item.params[:3], item.x, item.y,
                                                        item.z)]
                if not all(math.isfinite(v) for v in values):
                    self.fail('mission', str(path), 'non-finite row')

    def scenario_file(self, folder: Path) -> Path:
        path = folder / 'scenario.json'
        kind = self.rng.random()
        if kind < 0.2:
            size = self.rng.randint(0, 40)
            path.write_bytes(bytes(self.rng.randrange(256) for _ in range(size)))
        elif kind < 0.3:
            depth = self.rng.choice((10, 1000, 100_000))
            path.write_text('[' * depth + ']' * depth)
        else:
            fields = {k: v for k, v in self.small_scenario().items()}
            for key in list(fields):
                if isinstance(fields[key], (np.ndarray, bytes, np.floating, np.integer)):
                    fields[key] = str(fields[key])
            data = self.rng.choice((fields, fields, [fields], 5, None, {'scenario': fields}))
            path.write_text(json.dumps(data, default=str))
        return path

    def case_cli(self) -> None:
        with tempfile.TemporaryDirectory(dir=self.folder) as name:
            folder = Path(name)
            argv = [self.rng.choice(('plan', 'plan', 'plan', 'sweep', 'fly', ''))]
            if self.rng.random() < 0.8:
                argv += ['--slots', str(self.rng.randint(1, 8)), '--horizon', '40']
            for _ in range(self.rng.choice((0, 0, 1, 2, 3))):
                flag = self.rng.choice(FLAGS)
                argv.append(flag)
                if flag != '--letter':
                    argv.append(self.cli_value(flag))
            if self.rng.random() < 0.2:
                argv += ['--scenario', str(self.scenario_file(folder))]
            out = folder / 'out'
            out.mkdir()
            if argv[0] == 'sweep' and self.rng.random() < 0.5:
                argv += ['--budgets', ','.join(str(self.number()) for _ in range(2))]
            for flag, names in (('--json', ('r.json', 'r', 'no/r.json', '.', '/dev/null')),
                                ('--mission', ('m.waypoints', 'm.plan', 'm.txt')),
                                ('--figure', ('f.xyz', 'f'))):
                if self.rng.random() < 0.3 and (flag != '--mission' or argv[0] == 'plan'):
                    target = self.rng.choice(names)
                    argv += [flag, target if target.startswith('/') else str(out / target)]
            self.run_cli(argv, out)

    def cli_value(self, flag: str) -> str:
        if flag in ('--start', '--goal', '--home', '--nodes') and self.rng.random() < 0.6:
            parts = 3 if flag == '--home' else 2
            text = ','.join(repr(self.number()) if self.rng.random() < 0.5
                            else f'{self.rng.uniform(-500, 500):.3f}' for _ in range(parts))
            return text if flag != '--nodes' else text + ';' + text
        return self.rng.choice((repr(self.number()), str(self.number()), 'x', '', '1e999',
                                'I', 'rtl', 'px4', '-1', '0', '١'))

    def run_cli(self, argv: list[str], out: Path) -> None:
        what = ' '.join(argv)[:300]
        status, err = self.call_cli('cli', what, argv)
        if status is None:
            return
        self.judge_exit('cli', what, status, err)
        result = out / 'r.json'
        if status == 0 and result.is_file():
            text = result.read_text()
            if any(word in text for word in ('Infinity', 'NaN')):
                self.fail('cli', what, 'non-finite JSON written')
        stray = self.leftovers(out, refused=status != 0)
        if stray:
            self.fail('cli', what, f'files left: {stray}')

    KINDS = (('case_scenario', 0.35), ('case_settings', 0.1), ('case_plan_arguments', 0.05),
             ('case_mission', 0.1), ('case_cli', 0.4))


def main(argv: list[str] | None = None) -> int:
    return fuzz_main(Fuzzer, argv, __doc__, 'uav-fuzz-')


if __name__ == '__main__':
    sys.exit(main())
