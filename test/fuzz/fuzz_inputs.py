"""Seeded fuzzing of vehicle parameter files, Monte Carlo study designs and study tables
resumed after a hand edit (``make fuzz``).

Each case draws one of: a parameter file (ArduPilot ``NAME,VALUE`` or ``NAME VALUE`` lines,
QGroundControl's tab-separated rows, PX4's names; values 0, negative, tiny, huge, NaN, integers
beyond a double, junk, bytes that are not UTF-8), read by ``read_parameter_file`` and by
``plan --vehicle --vehicle-params``; a study design (grids, ranges and counts up to and past
the bounds) built by ``StudyDesign``; or a small study's CSV table with a cell, a line or bytes
changed, resumed by ``montecarlo``. Each must end in a result or a typed error
(:class:`~uav_comm_planner.errors.PlannerError`) within :data:`SLOW_S`, the command line in
exit 0 or exit 2 with one line; limits accepted from a file with ``ATC_INPUT_TC`` have the
jerk time ArduCopter flies, 2 max(ATC_INPUT_TC, 0.1); a resumed table accepted holds only rows
its study could have written. Prints the counts per kind and outcome and every failure; exits
1 if there was one.

    python test/fuzz/fuzz_inputs.py --cases 500 --seed 1
"""

from __future__ import annotations

import contextlib
import csv
import io
import math
from pathlib import Path
import shutil
import sys
import tempfile
import time
import warnings

from fuzz_report import fuzz_main, SeededFuzzer

from uav_comm_planner import PlannerError
from uav_comm_planner.tools import cli
from uav_comm_planner.tools.study.design import MAX_ROWS, row_mismatch, StudyDesign
from uav_comm_planner.tools.study.tables import read_table
from uav_comm_planner.vehicle.limits import read_parameter_file

#: A case slower than this (seconds) is a failure: every input is bounded before work.
SLOW_S = 20.0
ARDUPILOT = ('WPNAV_SPEED', 'WPNAV_ACCEL', 'WPNAV_JERK', 'ATC_INPUT_TC')
PX4 = ('MPC_XY_CRUISE', 'MPC_ACC_HOR', 'MPC_JERK_AUTO', 'NAV_ACC_RAD')
VALUES = ('0', '-1', '0.05', '0.1', '0.3', '1', '2.5', '500', '1000', '2000', '1e-300',
          '1e308', '-1e308', '1e400', 'nan', 'inf', '-inf', '1' + '0' * 400, '0x10', '1_0',
          '', 'abc', '\u0661', '5e-324', '99999999999999999999')
SETTINGS = ('nodes', 'slots', 'horizon_s', 'altitude_m', 'max_speed_mps', 'power_budget_w',
            'side_m')
SPECS = ('5', '0', '-3', '1e400', 'nan', '2:4', '4:2', '1:1', '0.5:20:log', '1,2,3',
         '1,' * 3000 + '1', '100000000', '2:20000', '10,1000000', '1e-300', 'x', '',
         ','.join(str(v) for v in range(1, 1200)))


class Fuzzer(SeededFuzzer):

    def __init__(self, seed: int, folder: Path) -> None:
        super().__init__(seed, folder)
        self.study: Path | None = None

    def timed(self, kind: str, what: str, call) -> object:
        """``call()``: a result, or a PlannerError counted as refused; anything else, or a
        case slower than SLOW_S, is a failure."""
        began = time.perf_counter()
        try:
            with warnings.catch_warnings():
                warnings.simplefilter('error')
                result = call()
            self.counts[(kind, 'ok')] += 1
        except PlannerError:
            result = None
            self.counts[(kind, 'refused')] += 1
        except Exception as exc:  # noqa: B902 - anything untyped is what we look for
            result = None
            self.fail(kind, what, f'{type(exc).__name__}: {str(exc)[:300]}')
        if time.perf_counter() - began > SLOW_S:
            self.fail(kind, what, f'took {time.perf_counter() - began:.1f} s')
        return result

    def command(self, kind: str, what: str, argv: list[str]) -> int | None:
        """The command line in process: exit 0, or exit 2 with one line on stderr."""
        began = time.perf_counter()
        status, err = self.call_cli(kind, what, argv, context=_warnings_as_errors)
        if status is None:
            return None
        self.judge_exit(kind, what, status, err)
        if time.perf_counter() - began > SLOW_S:
            self.fail(kind, what, f'took {time.perf_counter() - began:.1f} s')
        return status

    # Parameter files.

    def parameter_text(self, names: tuple[str, ...]) -> tuple[str, dict[str, str]]:
        lines, given = [], {}
        for _ in range(self.rng.choice((0, 1, 2, 4, 8))):
            name = self.rng.choice(names + ('SYSID_THISMAV', 'ATC_INPUT_TC'))
            value = self.rng.choice(VALUES)
            style = self.rng.random()
            if style < 0.5:
                lines.append(f'{name},{value}')
            elif style < 0.8:
                lines.append(f'1\t1\t{name}\t{value}\t9')
            elif style < 0.9:
                lines.append(f'{name} {value} # a comment')
            else:
                lines.append(self.rng.choice(('#', '', name, ',,,', 'x' * 5000)))
            given[name] = value
        return '\n'.join(lines) + '\n', given

    def case_parameters(self) -> None:
        firmware = self.rng.choice(('ardupilot', 'px4'))
        text, _ = self.parameter_text(ARDUPILOT if firmware == 'ardupilot' else PX4)
        with tempfile.TemporaryDirectory(dir=self.folder) as name:
            path = Path(name) / 'vehicle.param'
            data = text.encode('utf-8')
            if self.rng.random() < 0.05:
                data += b'\xff\xfe\x00'
            path.write_bytes(data)
            what = f'{firmware}: {text[:200]!r}'
            limits = self.timed('parameters', what,
                                lambda: read_parameter_file(path, firmware=firmware))
            if limits is not None and firmware == 'ardupilot':
                self.check_jerk_time(what, text, limits.jerk_time_s)
            if self.rng.random() < 0.3:
                self.command('parameters cli', what, [
                    'plan', '--case', 'I', '--slots', '20', '--horizon', '400', '--speed', '5',
                    '--vehicle', '--firmware', firmware, '--vehicle-params', str(path)])

    def check_jerk_time(self, what: str, text: str, jerk_time_s: float) -> None:
        """ArduCopter's jerk time, 2 max(ATC_INPUT_TC, 0.1), from the last line that sets
        ATC_INPUT_TC (``NAME,VALUE``, ``NAME VALUE`` or ``SYS COMP NAME VALUE TYPE``)."""
        value = None
        for line in text.splitlines():
            fields = line.split('#', 1)[0].replace(',', ' ').split()
            if len(fields) >= 4 and fields[2] == 'ATC_INPUT_TC':
                value = float(fields[3])
            elif len(fields) >= 2 and fields[0] == 'ATC_INPUT_TC':
                value = float(fields[1])
        if value is None:
            return
        expected = 2.0 * max(value, 0.1)
        if not math.isclose(jerk_time_s, expected, rel_tol=1e-12):
            self.fail('parameters', what, f'jerk time {jerk_time_s} s, ArduCopter flies '
                                          f'{expected} s')

    # Study designs.

    def case_design(self) -> None:
        draws = {name: self.rng.choice(SPECS)
                 for name in self.rng.sample(SETTINGS, self.rng.choice((1, 2, 3)))}
        cases = self.rng.choice((1, 10, 1000, 10 ** 6, 10 ** 7, 0, -1))
        what = f'cases {cases}, {", ".join(f"{k}={v[:30]}" for k, v in draws.items())}'
        design = self.timed('design', what, lambda: StudyDesign(cases=cases, draws=draws))
        if design is not None and design.total_rows > MAX_ROWS:
            self.fail('design', what, f'{design.total_rows} rows, more than {MAX_ROWS}')

    # Study tables.

    def fresh_study(self) -> Path:
        """A small study's table (planned once per run, copied for each case)."""
        if self.study is None:
            self.study = self.folder / 'study' / 'study.csv'
            self.study.parent.mkdir()
            with contextlib.redirect_stdout(io.StringIO()):
                status = cli.main(self.study_argv(self.study, 2))
            if status != 0:
                raise RuntimeError(f'the seed study failed: {status}')
        return self.study

    @staticmethod
    def study_argv(out: Path, cases: int) -> list[str]:
        return ['montecarlo', '--cases', str(cases), '--nodes', '2:3', '--slots', '10',
                '--horizon', '40', '--workers', '1', '--quiet', '--methods', 'straight',
                '--out', str(out)]

    def case_table(self) -> None:
        source = self.fresh_study()
        with tempfile.TemporaryDirectory(dir=self.folder) as name:
            out = Path(name) / 'study.csv'
            shutil.copy(source, out)
            shutil.copy(source.with_name(source.name + '.json'),
                        out.with_name(out.name + '.json'))
            what = self.tamper(out)
            status = self.command('table', what, self.study_argv(out, 3))
            if status == 0:
                design, rows = read_table(out)
                wrong = [row_mismatch(design, row) for row in rows]
                if any(wrong):
                    self.fail('table', what, f'resumed with {next(w for w in wrong if w)}')

    def tamper(self, out: Path) -> str:
        """Change the table at ``out`` as a hand might; what was changed."""
        lines = out.read_text().splitlines()
        kind = self.rng.random()
        if kind < 0.6:
            names = lines[0].split(',')
            row = next(csv.reader([lines[1]]))
            column = self.rng.randrange(len(names))
            row[column] = self.rng.choice(VALUES + ('2', '3', '10', 'square', 'disc'))
            buffer = io.StringIO()
            csv.writer(buffer, lineterminator='').writerow(row)
            lines[1] = buffer.getvalue()
            what = f'{names[column]} = {row[column][:30]!r}'
        elif kind < 0.75:
            lines.append(lines[self.rng.randrange(1, len(lines))])
            what = 'a row twice'
        elif kind < 0.85:
            del lines[self.rng.randrange(0, len(lines))]
            what = 'a line removed'
        else:
            out.write_bytes('\n'.join(lines).encode() + self.rng.choice(
                (b'\n\xff\xfe', b'\n\x00\x00', b'\n"unterminated', b'\n' + b',' * 200)))
            return 'bytes appended'
        out.write_text('\n'.join(lines) + '\n')
        return what

    KINDS = (('case_parameters', 0.5), ('case_design', 0.3), ('case_table', 0.2))


@contextlib.contextmanager
def _warnings_as_errors():
    with warnings.catch_warnings():
        warnings.simplefilter('error')
        yield


def main(argv: list[str] | None = None) -> int:
    # The studies' own folder stays: a study resumes from it.
    return fuzz_main(Fuzzer, argv, __doc__, 'uav-fuzz-inputs-',
                     kept=lambda path: path.parts[0] == 'study')


if __name__ == '__main__':
    sys.exit(main())
