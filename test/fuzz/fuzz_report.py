"""What the fuzz targets share: the seeded draws and the kinds of case, the command line run in
process and its exit judged, the counts and failures, the work folder, and the closing report
(counts per kind and outcome, then the failures)."""

from __future__ import annotations

import argparse
import collections
import contextlib
import io
from pathlib import Path
import random
import tempfile
import time
from typing import Callable

#: Failures printed at most (all are counted).
FAILURES_SHOWN = 30


def parse_arguments(argv: list[str] | None, doc: str) -> argparse.Namespace:
    """``--cases`` (10 000) and ``--seed`` (1), described by the first line of ``doc``."""
    parser = argparse.ArgumentParser(description=doc.splitlines()[0])
    parser.add_argument('--cases', type=int, default=10_000)
    parser.add_argument('--seed', type=int, default=1)
    return parser.parse_args(argv)


class SeededFuzzer:
    """Draws from ``seed``, works in ``folder``, counts outcomes by (kind, outcome) and keeps
    the failures."""

    def __init__(self, seed: int, folder: Path) -> None:
        self.rng = random.Random(seed)
        self.folder = folder
        self.counts: collections.Counter = collections.Counter()
        self.failures: list[str] = []

    #: The kinds of case: (method name, weight); :meth:`run` draws one a case.
    KINDS: tuple[tuple[str, float], ...] = ()

    def fail(self, kind: str, what: str, detail: str) -> None:
        self.counts[(kind, 'FAILED')] += 1
        self.failures.append(f'{kind}: {what}: {detail}')

    def run(self, cases: int) -> None:
        names, weights = zip(*self.KINDS)
        for _ in range(cases):
            getattr(self, self.rng.choices(names, weights)[0])()
            self.after_case()

    def after_case(self) -> None:
        """Checked after every case (nothing by default)."""

    def close(self) -> None:
        """Release what the fuzzer holds (nothing by default)."""

    def call_cli(self, kind: str, what: str, argv: list[str],
                 context: Callable[[], contextlib.AbstractContextManager] = (
                     contextlib.nullcontext)) -> tuple[int | None, str]:
        """The command line in process, its output captured, inside ``context()``: (exit
        status, stderr), or (None, '') when an exception escaped it (a failure)."""
        from uav_comm_planner.tools import cli

        stdout, stderr = io.StringIO(), io.StringIO()
        try:
            with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr), \
                    context():
                status = cli.main(argv)
        except BaseException as exc:  # noqa: B902 - an escaping exception is a traceback
            self.fail(kind, what, f'{type(exc).__name__} escaped: {str(exc)[:300]}')
            return None, ''
        return status, stderr.getvalue()

    def judge_exit(self, kind: str, what: str, status: int, err: str) -> None:
        """Exit 2 is a refusal (counted), one line ``uav-comm-planner: error: ...``; exit 0 is
        counted; any other status, or a traceback on stderr, is a failure."""
        if status == 2:
            self.counts[(kind, 'refused')] += 1
            if err.count('\n') != 1 or not err.startswith('uav-comm-planner: error: '):
                self.fail(kind, what, f'refusal not one line: {err[:400]!r}')
        elif status == 0:
            self.counts[(kind, 'ok')] += 1
        else:
            self.fail(kind, what, f'exit status {status}: {err[:400]!r}')
        if 'Traceback' in err:
            self.fail(kind, what, 'traceback on stderr')


def fuzz_main(make: Callable[[int, Path], SeededFuzzer], argv: list[str] | None, doc: str,
              prefix: str, *, kept: Callable[[Path], bool] = lambda path: True,
              widths: tuple[int, int] = (15, 40)) -> int:
    """A fuzz target's command: ``--cases`` drawn from ``--seed`` by the fuzzer ``make(seed,
    folder)`` in a temporary work folder, which must be left empty but for the paths
    ``kept`` passes over; the report (:func:`report`) and its exit status."""
    args = parse_arguments(argv, doc)
    began = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=prefix) as name:
        fuzzer = make(args.seed, Path(name))
        try:
            fuzzer.run(args.cases)
        finally:
            fuzzer.close()
        left = sorted(str(p.relative_to(name)) for p in Path(name).rglob('*')
                      if not kept(p.relative_to(name)))
    return report(args.cases, args.seed, time.perf_counter() - began, fuzzer.counts,
                  fuzzer.failures, left, widths=widths)


def report(cases: int, seed: int, elapsed_s: float, counts: collections.Counter,
           failures: list[str], left: list[str], *, widths: tuple[int, int] = (15, 40)) -> int:
    """Print the run's counts and failures (a work folder not left empty is one); return the
    exit status: 1 when anything failed, else 0."""
    print(f'{cases} cases, seed {seed}, {elapsed_s:.1f} s')
    for (kind, outcome), count in sorted(counts.items()):
        print(f'  {kind:<{widths[0]}} {outcome:<{widths[1]}} {count:>6}')
    if left:
        failures.append(f'left in the work folder: {left[:10]}')
    print(f'{len(failures)} failures')
    for failure in failures[:FAILURES_SHOWN]:
        print('  ' + failure.replace('\n', '\n    '))
    return 1 if failures else 0
