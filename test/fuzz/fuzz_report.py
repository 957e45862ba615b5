"""What both fuzz targets share: the seeded draws, the counts and failures, and the closing
report (counts per kind and outcome, then the failures)."""

from __future__ import annotations

import argparse
import collections
from pathlib import Path
import random

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

    def fail(self, kind: str, what: str, detail: str) -> None:
        self.counts[(kind, 'FAILED')] += 1
        self.failures.append(f'{kind}: {what}: {detail}')


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
