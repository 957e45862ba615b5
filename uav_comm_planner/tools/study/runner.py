"""Running a Monte Carlo study on Dask: the cluster and its single-threaded workers, batches,
progress, resumption and Ctrl-C; and the measurement of how a study scales with its workers.
"""

from __future__ import annotations

import contextlib
from dataclasses import dataclass
import logging
import math
import os
from pathlib import Path
import signal
import statistics
import sys
import tempfile
import time
from typing import Iterator, Sequence, TextIO

from uav_comm_planner.core.numbers import counted
from uav_comm_planner.tools.study.design import StudyDesign, StudyError
from uav_comm_planner.tools.study.tables import failed_row, one_line, open_table, plan_batch

INSTALL_HINT = ("pip install 'uav_comm_planner[study]' (or `make install`, which includes the "
                'study extra)')
#: Environment of every worker process: one BLAS thread, since each worker is one core.
BLAS_ONE_THREAD = {'OMP_NUM_THREADS': '1', 'OPENBLAS_NUM_THREADS': '1', 'MKL_NUM_THREADS': '1'}
#: Largest number of scenarios per Dask task.
MAX_BATCH = 50


def require_extra(*, parquet: bool) -> None:
    """Raise StudyError with the install command when Dask (or pyarrow) is missing."""
    try:
        import dask  # noqa: F401
        import distributed  # noqa: F401
        if parquet:
            import pyarrow  # noqa: F401
    except ImportError as exc:
        raise StudyError(f'montecarlo needs the study extra ({exc.name} is missing): '
                         f'{INSTALL_HINT}') from None


@contextlib.contextmanager
def _blas_one_thread() -> Iterator[None]:
    """Give worker processes spawned inside one BLAS thread each, whatever the caller's
    environment says (Dask's nanny reads it before its pre-spawn defaults)."""
    saved = {name: os.environ.get(name) for name in BLAS_ONE_THREAD}
    os.environ.update(BLAS_ONE_THREAD)
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


def worker_info() -> dict:
    """Run on each worker before the study: imports the planner there (the first task does
    not pay for it) and reports the BLAS thread setting."""
    return {'pid': os.getpid(), 'omp_num_threads': os.environ.get('OMP_NUM_THREADS')}


def ignore_interrupts() -> bool:
    """Run on the embedded cluster's workers: Ctrl-C reaches the whole process group, but it
    is for the study's own process, which then stops the workers itself."""
    try:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    except ValueError:  # not the worker's main thread: leave it
        return False
    return True


@contextlib.contextmanager
def dask_client(*, workers: int | None = None, scheduler: str | None = None,
                connect_timeout_s: float = 30.0) -> Iterator[object]:
    """A ``distributed.Client``: on the cluster at ``scheduler``, or on an embedded
    LocalCluster of ``workers`` single-threaded worker processes (default: one per core)."""
    import distributed
    # Dask reports every start and stop at INFO; a study shows its own progress instead.
    dask_logger = logging.getLogger('distributed')
    level = dask_logger.level
    dask_logger.setLevel(logging.WARNING)
    cluster = client = None
    try:
        if scheduler:
            try:
                client = distributed.Client(scheduler, timeout=f'{connect_timeout_s}s')
                client.wait_for_workers(1, timeout=connect_timeout_s)
            except (OSError, TimeoutError) as exc:
                if client is None:
                    raise StudyError(f'cannot reach the Dask scheduler at {scheduler}: '
                                     f'{exc}') from None
                raise StudyError(f'no Dask worker joined {scheduler} within '
                                 f'{connect_timeout_s:g} s; start one with `dask worker '
                                 f'{scheduler} --nthreads 1`') from None
        else:
            # The scheduler's web server on a free port of this host only: several studies
            # on one machine do not fight over 8787.
            with _blas_one_thread():
                cluster = distributed.LocalCluster(
                    n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                    processes=True, dashboard_address='127.0.0.1:0',
                    silence_logs=logging.ERROR)
            client = distributed.Client(cluster)
            client.run(ignore_interrupts)
        yield client
    finally:
        if client is not None:
            client.close()
        if cluster is not None:
            cluster.close()
        dask_logger.setLevel(level)


def batches_of(indices: Sequence[int], size: int) -> list[list[int]]:
    return [list(indices[i:i + size]) for i in range(0, len(indices), size)]


def auto_batch_size(rows: int, slots: int) -> int:
    """About 8 tasks per worker slot (for balance at the end), at most :data:`MAX_BATCH`."""
    return max(1, min(MAX_BATCH, math.ceil(rows / (8 * max(1, slots)))))


class Progress:
    """One status line on ``stream``: rows done, a bar, rate and time left, failures.

    Redrawn in place on a terminal; elsewhere a line at most every ``every_s`` seconds.
    """

    def __init__(self, total: int, done: int, stream: TextIO | None, *,
                 every_s: float = 5.0) -> None:
        self.total, self.done, self.start_done = total, done, done
        self.failed = 0
        self.stream = stream
        self.tty = bool(stream is not None and getattr(stream, 'isatty', lambda: False)())
        self.every_s = every_s
        self.began = time.perf_counter()
        self.last_shown = -math.inf
        self.width = 0
        self.shown_done = -1

    @property
    def rate(self) -> float:
        elapsed = time.perf_counter() - self.began
        return (self.done - self.start_done) / elapsed if elapsed > 0 else 0.0

    def line(self) -> str:
        fraction = self.done / self.total if self.total else 1.0
        bar = '#' * int(24 * fraction)
        rate = self.rate
        left = (self.total - self.done) / rate if rate > 0 else math.inf
        left_text = f'{left:.0f} s left' if math.isfinite(left) else '-- s left'
        return (f'montecarlo {self.done}/{self.total} rows [{bar:<24}] {100 * fraction:3.0f}% '
                f'{rate:.2f} scenarios/s, {left_text}, {self.failed} failed')

    def update(self, rows: int, failed: int) -> None:
        self.done += rows
        self.failed += failed
        self.show()

    def show(self, *, final: bool = False) -> None:
        if self.stream is None:
            return
        now = time.perf_counter()
        if self.tty:
            line = self.line()
            self.stream.write('\r' + line.ljust(self.width) + ('\n' if final else ''))
            self.width = len(line)
        elif (final and self.done != self.shown_done) or now - self.last_shown >= self.every_s:
            self.stream.write(self.line() + '\n')
            self.last_shown, self.shown_done = now, self.done
        self.stream.flush()


@dataclass(frozen=True)
class StudyRun:
    """What one run of a study did: rows planned now, the table's size, times."""

    planned: int
    failed: int
    in_table: int
    total: int
    workers: int
    batch_size: int
    startup_s: float
    wall_s: float
    cpu_s: float
    coordinator_cpu_s: float = 0.0

    @property
    def rate(self) -> float:
        """Scenarios per second of wall time, from the first task to the last row written."""
        return self.planned / self.wall_s if self.wall_s > 0 else math.nan

    # coordinator_cpu_s: processor time of this process (client, and the embedded cluster's
    # scheduler) while the rows were planned.

    @property
    def cpu_share(self) -> float:
        """Processor time of the rows over wall time x workers: 1 when every worker planned
        on a core of its own all the time; less for scheduling, transfers, and other programs
        taking the cores."""
        return self.cpu_s / (self.wall_s * self.workers) if self.wall_s > 0 else math.nan


#: The schemes of a Dask scheduler's address a study connects to.
SCHEDULER_SCHEMES = ('tcp', 'tls')


def check_scheduler(address: str) -> None:
    """Refuse (StudyError) a scheduler address that is not ``tcp://HOST:PORT`` or
    ``tls://HOST:PORT``, before any table is opened or connection tried."""
    from urllib.parse import urlsplit
    text = str(address)
    shown = text if len(text) <= 80 else text[:80] + '...'
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError:
        parts, port = None, None
    if (parts is None or parts.scheme not in SCHEDULER_SCHEMES or not parts.hostname
            or port is None or parts.path not in ('', '/') or parts.query or parts.fragment):
        raise StudyError(f'--scheduler {shown!r} is not a Dask scheduler address: give '
                         f'tcp://HOST:PORT (or tls://HOST:PORT)')


def run_study(design: StudyDesign, out: str | os.PathLike, *, workers: int | None = None,
              scheduler: str | None = None, batch_size: int | None = None,
              limit: int | None = None, progress: TextIO | None = None) -> StudyRun:
    """Plan the rows of ``design`` that the table at ``out`` lacks, on Dask.

    ``limit`` plans at most that many rows in this run (the rest on the next); ``batch_size``
    scenarios go to each task (default :func:`auto_batch_size`). Rows are written as batches
    complete. KeyboardInterrupt stops the study after cancelling the queued tasks; the rows
    written so far stay, and the next run goes on from there.
    """
    require_extra(parquet=Path(out).suffix.lower() == '.parquet')
    if scheduler:
        check_scheduler(scheduler)
    if workers is not None and workers < 1:
        raise StudyError(f'--workers must be >= 1, got {workers}')
    if batch_size is not None and not 1 <= batch_size <= 10 * MAX_BATCH:
        raise StudyError(f'--batch must be in 1..{10 * MAX_BATCH}, got {batch_size}')
    if limit is not None and limit < 1:
        raise StudyError(f'--limit must be >= 1, got {limit}')
    table, done = open_table(out, design)
    todo = [i for i in range(design.total_rows) if i not in done]
    if limit is not None:
        todo = todo[:limit]
    in_table = len(done & set(range(design.total_rows)))
    if not todo:
        return StudyRun(0, 0, in_table, design.total_rows, 0, 0, 0.0, 0.0, 0.0)
    began = time.perf_counter()
    with dask_client(workers=workers, scheduler=scheduler) as client:
        try:
            infos = client.run(worker_info)
        except Exception as exc:
            raise StudyError(f'the workers cannot run the planner ({one_line(exc)}); install '
                             f'uav_comm_planner with the study extra where they run') from None
        threads = sum(client.nthreads().values())
        size = batch_size or auto_batch_size(len(todo), threads)
        startup_s = time.perf_counter() - began
        if progress is not None:
            pinned = all(info['omp_num_threads'] == '1' for info in infos.values())
            progress.write(f'montecarlo: {len(todo)} scenarios to plan ({in_table} of '
                           f'{design.total_rows} in {out}), {counted(len(infos), "worker")} with '
                           f'{threads} threads, batches of {size}; cluster ready in '
                           f'{startup_s:.1f} s'
                           + ('' if pinned else '; warning: OMP_NUM_THREADS is not 1 on every '
                              'worker') + '\n')
        bar = Progress(design.total_rows, in_table, progress)
        planned = failed = 0
        cpu = 0.0
        compute_began = time.perf_counter()
        coordinator_began = time.process_time()
        futures = {}
        for batch in batches_of(todo, size):
            future = client.submit(plan_batch, design, batch, pure=False)
            futures[future] = batch
        import distributed
        try:
            for future in distributed.as_completed(list(futures)):
                try:
                    rows = future.result()
                except Exception as exc:  # a worker died: the batch's rows carry the error
                    rows = [failed_row(design, i, f'task lost: {one_line(exc)}')
                            for i in futures[future]]
                table.append(rows)
                future.release()
                bad = sum(row['status'] != 'ok' for row in rows)
                planned += len(rows)
                failed += bad
                cpu += sum(row['cpu_s'] or 0.0 for row in rows)
                bar.update(len(rows), bad)
        except KeyboardInterrupt:
            client.cancel(list(futures))
            raise
        finally:
            bar.show(final=True)
        wall_s = time.perf_counter() - compute_began
        coordinator_cpu_s = time.process_time() - coordinator_began
    return StudyRun(planned, failed, in_table + planned, design.total_rows, len(infos), size,
                    startup_s, wall_s, cpu, coordinator_cpu_s)


# ---------------------------------------------------------------------------------------------
# Reports and scaling measurement.

def format_run(run: StudyRun) -> str:
    """What one run did, in the one line the command prints after it."""
    if run.planned == 0:
        return f'nothing to plan: {run.in_table} of {run.total} rows are in the table'
    return (f'planned {run.planned} scenarios ({run.failed} failed) in {run.wall_s:.1f} s on '
            f'{counted(run.workers, "worker")}: {run.rate:.2f} scenarios/s, batches of '
            f'{run.batch_size}, '
            f'workers on a core {100 * run.cpu_share:.0f} % of the time; cluster start '
            f'{run.startup_s:.1f} s; '
            f'{run.in_table} of {run.total} rows in the table')


def measure_scaling(design: StudyDesign, worker_counts: Sequence[int], repeats: int, *,
                    batch_size: int | None = None, out: TextIO = sys.stdout) -> dict[int, list]:
    """Run the whole study afresh ``repeats`` times with each worker count, alternating (and
    reversing the order every other round, so that a change of load on the machine falls on
    both sides); print each run and the median rates. Returns {workers: [StudyRun, ...]}."""
    runs: dict[int, list[StudyRun]] = {k: [] for k in worker_counts}
    with tempfile.TemporaryDirectory(prefix='study-scaling-') as folder:
        for repeat in range(repeats):
            order = list(worker_counts) if repeat % 2 == 0 else list(worker_counts)[::-1]
            for count in order:
                target = Path(folder) / f'run-{repeat}-{count}.parquet'
                run = run_study(design, target, workers=count, batch_size=batch_size)
                runs[count].append(run)
                print(f'round {repeat + 1}, {counted(count, "worker")}: '
                      f'{run.rate:.2f} scenarios/s ({run.planned} in {run.wall_s:.2f} s, '
                      f'workers on a core {100 * run.cpu_share:.0f} % of the time, this process '
                      f'{100 * run.coordinator_cpu_s / run.wall_s:.0f} % of a core, cluster '
                      f'start {run.startup_s:.1f} s)', file=out, flush=True)
    medians = {k: statistics.median(r.rate for r in v) for k, v in runs.items()}
    for count, rate in medians.items():
        print(f'{counted(count, "worker")}: median {rate:.2f} scenarios/s', file=out)
    base = min(medians)
    for count in medians:
        if count != base:
            ratios = [a.rate / b.rate for a, b in zip(runs[count], runs[base])]
            print(f'scaling {base} -> {count} workers: {medians[count] / medians[base]:.2f}x '
                  f'(median rates; per round {", ".join(f"{r:.2f}" for r in ratios)})',
                  file=out, flush=True)
            per_cpu = {k: statistics.median(r.planned / r.cpu_s for r in runs[k])
                       for k in (base, count)}
            share = per_cpu[count] / per_cpu[base]
            print(f'per second of worker processor time: {per_cpu[base]:.2f} scenarios with '
                  f'{base}, {per_cpu[count]:.2f} with {count} ({share:.2f} of it: what '
                  f'distributing costs when each worker has a core of its own)',
                  file=out, flush=True)
    return runs
