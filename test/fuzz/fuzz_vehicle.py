"""Seeded fuzzing of the vehicle link against a fake vehicle (``make fuzz``).

A MAVLink peer on 127.0.0.1 (``test/fake_vehicle.py``) answers with seeded garbage, loops,
silences, wrong acknowledgements, wrong counts and wrong read-backs; each case connects and
uploads a mission through the API (``connect``, ``upload_and_verify``) or the command line
(``uav-comm-planner upload``, in process), or checks a random link URL. Every answer must be
success or a typed error (:class:`~uav_comm_planner.errors.VehicleLinkError` or
:class:`~uav_comm_planner.errors.MissionFileError`), the command line exit 0 or 2 with one line
and no traceback, no case may run past its deadline, and no thread, descriptor or file may be
left behind. Prints the counts per kind and outcome and every failure; exits 1 if there was
one.

    python test/fuzz/fuzz_vehicle.py --cases 10000 --seed 1
"""

from __future__ import annotations

import contextlib
import io
import os
from pathlib import Path
import re
import string
import sys
import threading
import time
import traceback

# The fake vehicle lives beside the tests, the report beside this file.
sys.path[:0] = [str(Path(__file__).resolve().parents[1]), str(Path(__file__).resolve().parent)]

from fake_vehicle import BEHAVIOURS, FakeVehicle  # noqa: E402
from fuzz_report import fuzz_main, SeededFuzzer  # noqa: E402

from uav_comm_planner.errors import MissionFileError, VehicleLinkError  # noqa: E402
from uav_comm_planner.tools import cli  # noqa: E402
from uav_comm_planner.vehicle.mavlink.items import MissionItem, NAV_WAYPOINT  # noqa: E402
from uav_comm_planner.vehicle.mavlink.link import (connect, LinkSettings,  # noqa: E402
                                                   upload_and_verify)
from uav_comm_planner.vehicle.mavlink.urls import parse_link_url  # noqa: E402

#: Every case must end within its deadline plus this (seconds): thread switches, a slow CI.
SLACK_S = 1.5
CONNECT_TIMEOUT_S = 0.3
SETTINGS = LinkSettings(timeout_s=0.05, retries=1, busy_retries=1, busy_pause_s=0.01,
                        deadline_s=0.6)
MISSION = ('QGC WPL 110\n' + ''.join(
    f'{k}\t{int(k == 0)}\t{0 if k == 0 else 3}\t16\t0\t0\t0\t0\t{47 + k * 1e-4:.7f}\t8.0000000'
    f'\t{10.0 * k:.1f}\t1\n' for k in range(5)))


class Fuzzer(SeededFuzzer):
    """Draws the cases against one fake vehicle, runs them and keeps the counts and the
    failures."""

    def __init__(self, seed: int, folder: Path) -> None:
        super().__init__(seed, folder)
        self.vehicle = FakeVehicle('good')
        self.mission = folder / 'm.waypoints'
        self.mission.write_text(MISSION)
        self.threads = set(threading.enumerate())
        self.descriptors = len(os.listdir('/proc/self/fd'))

    def close(self) -> None:
        self.vehicle.close()

    def items(self) -> list[MissionItem]:
        count = self.rng.choice((1, 2, 5, 20))
        return [MissionItem(NAV_WAYPOINT, 0, x=47.0 + k * 1e-4, y=8.0, z=10.0 * k,
                            current=k == 0) for k in range(count)]

    def behaviour(self) -> str:
        weights = {'garbage': 6, 'good': 1, 'mute': 0.3}
        return self.rng.choices(BEHAVIOURS, [weights.get(b, 1) for b in BEHAVIOURS])[0]

    def case_api(self) -> None:
        behaviour = self.behaviour()
        self.vehicle.reset(behaviour, seed=self.rng.randrange(2**32))
        what = f'{behaviour}'
        began = time.monotonic()
        try:
            link = connect(self.vehicle.url, timeout_s=CONNECT_TIMEOUT_S)
            try:
                upload_and_verify(link, self.items(), SETTINGS)
            finally:
                link.close()
            outcome = 'uploaded'
        except VehicleLinkError as exc:
            outcome = 'refused: ' + re.sub(r'\d+', 'N', str(exc).split(':')[0])[:44]
        except Exception:  # noqa: B902 - anything else is the failure looked for
            self.fail('api', what, traceback.format_exc(limit=4))
            return
        self.counts[('api ' + behaviour, outcome)] += 1
        if behaviour not in ('good', 'garbage', 'impatient') and outcome == 'uploaded':
            self.fail('api', what, 'a misbehaving vehicle took the mission')
        if behaviour in ('good', 'impatient') and outcome != 'uploaded':
            self.fail('api', what, f'a good vehicle was refused: {outcome}')
        self.within(began, CONNECT_TIMEOUT_S + SETTINGS.deadline_s, 'api', what)

    def case_cli(self) -> None:
        behaviour = self.behaviour()
        self.vehicle.reset(behaviour, seed=self.rng.randrange(2**32))
        before = sorted(p.name for p in self.folder.iterdir())
        argv = ['upload', str(self.mission), '--connect', self.vehicle.url, '--timeout', '0.05',
                '--retries', '1', '--connect-timeout', str(CONNECT_TIMEOUT_S)]
        stdout, stderr = io.StringIO(), io.StringIO()
        began = time.monotonic()
        try:
            with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
                status = cli.main(argv)
        except BaseException:  # noqa: B902 - an escape is the failure looked for
            self.fail('cli', behaviour, traceback.format_exc(limit=4))
            return
        err = stderr.getvalue()
        self.counts[('cli ' + behaviour, f'exit {status}')] += 1
        if status == 2 and (err.count('\n') != 1 or 'uav-comm-planner: error: ' not in err):
            self.fail('cli', behaviour, f'refusal not one line: {err!r}')
        if status not in (0, 2) or 'Traceback' in err:
            self.fail('cli', behaviour, f'exit {status}: {err!r}')
        if sorted(p.name for p in self.folder.iterdir()) != before:
            self.fail('cli', behaviour, 'a file was written')
        # The command line's deadline: the connect, then the default 300 s transfer deadline
        # is never reached with 0.05 s answers; what bounds it is retries x timeout per step.
        self.within(began, CONNECT_TIMEOUT_S + 60 * 0.1 + SETTINGS.deadline_s, 'cli',
                    behaviour)

    def case_url(self) -> None:
        draw = self.rng
        alphabet = string.ascii_letters + string.digits + ':/.,-_ \t\n\x00@[]'
        prefix = draw.choice(('tcp:', 'udpin:', 'udpout:', '/dev/', 'tcp:127.0.0.1:', '',
                              'csv:', 'uds:', 'ws:'))
        if draw.random() < 0.3:
            # Well-formed but for the port, which may lie outside 1..65535.
            text = (f'{draw.choice(("tcp", "udpin", "udpout", "tcpin"))}:'
                    f'{draw.choice(("127.0.0.1", "localhost", "0.0.0.0", "gcs.local"))}:'
                    f'{draw.choice((draw.randrange(-5, 70000), 5760, 14550))}')
        else:
            text = prefix + ''.join(draw.choice(alphabet) for _ in range(draw.randrange(24)))
        try:
            parse_link_url(text)
            outcome = 'accepted'
        except VehicleLinkError:
            outcome = 'refused'
        except Exception:  # noqa: B902
            self.fail('url', repr(text), traceback.format_exc(limit=3))
            return
        self.counts[('url', outcome)] += 1

    def case_missing_file(self) -> None:
        """A refused mission (here, one that is a FIFO) never reaches the vehicle."""
        fifo = self.folder / f'fifo-{self.rng.randrange(10**9)}.waypoints'
        os.mkfifo(fifo)
        received = self.vehicle.received
        try:
            from uav_comm_planner.vehicle.mavlink.upload import upload_file
            upload_file(fifo, self.vehicle.url, connect_timeout_s=CONNECT_TIMEOUT_S)
            self.fail('file', 'fifo', 'a FIFO was uploaded')
        except MissionFileError:
            self.counts[('file', 'refused before connecting')] += 1
        except Exception:  # noqa: B902
            self.fail('file', 'fifo', traceback.format_exc(limit=3))
        finally:
            fifo.unlink()
        if self.vehicle.received != received:
            self.fail('file', 'fifo', 'the vehicle heard from a refused upload')

    def within(self, began: float, deadline_s: float, kind: str, what: str) -> None:
        elapsed = time.monotonic() - began
        if elapsed > deadline_s + SLACK_S:
            self.fail(kind, what, f'took {elapsed:.2f} s, past its deadline of {deadline_s:g} s')

    def check_leaks(self) -> None:
        deadline = time.monotonic() + 2.0
        while True:
            threads = [t for t in threading.enumerate()
                       if t not in self.threads and t.is_alive()]
            descriptors = len(os.listdir('/proc/self/fd'))
            if not threads and descriptors <= self.descriptors:
                return
            if time.monotonic() > deadline:
                self.fail('leak', '', f'threads {threads}, descriptors {descriptors} (were '
                                      f'{self.descriptors})')
                self.threads |= set(threads)
                self.descriptors = descriptors
                return
            time.sleep(0.01)

    KINDS = (('case_api', 0.55), ('case_cli', 0.1), ('case_url', 0.3),
             ('case_missing_file', 0.05))

    def after_case(self) -> None:
        self.check_leaks()


def main(argv: list[str] | None = None) -> int:
    return fuzz_main(Fuzzer, argv, __doc__, 'uav-fuzz-vehicle-',
                     kept=lambda path: path.name == 'm.waypoints', widths=(20, 48))


if __name__ == '__main__':
    sys.exit(main())
