"""Every command README.md and docs/*.md show works as written.

The commands are read from the pages themselves (```sh blocks, and inline
`uav-comm-planner ...`, `.venv/bin/uav-comm-planner ...` and `make run ...`), never copied
here, and run in a temporary folder with only mechanical changes: `.venv/bin/` and a bare
`uav-comm-planner` become this venv's commands, `make run ARGS=...` becomes what the Makefile's
`run` target runs (`.venv/bin/planner ARGS` with the ROS environment), and a file of the
checkout a command names by a relative path (`config/planner.yaml`,
`docs/fence_example.geojson`) is copied into the folder first. Where a page quotes what a
command prints (a plain or ```text block right after its ```sh block, or right after the
paragraph naming it and ending in a colon; a sentence "`command` prints 11.5713 ..."), the
output is checked against the quote. A command that needs a vehicle, a running node, a ROS 2
installation or a long run is left out by :data:`NOT_RUN`, each with the reason.
"""

from __future__ import annotations

from dataclasses import dataclass, field
import os
from pathlib import Path
import re
import shlex
import shutil
import signal
import subprocess
import sys
import threading
import time

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = (ROOT / 'README.md', *sorted((ROOT / 'docs').glob('*.md')))
#: This venv's commands: what `.venv/bin/` means in the pages.
BIN = Path(sys.executable).parent
#: The environment the Makefile gives the node (ROS_ENV): discovery on this machine, and the
#: venv as the ament prefix; ROS_DOMAIN_ID is this run's.
ROS_ENV = {'ROS_AUTOMATIC_DISCOVERY_RANGE': 'LOCALHOST', 'AMENT_PREFIX_PATH': str(BIN.parent)}
COMMAND_TIMEOUT_S = 600.0
#: How long a node may take to log its first plan.
NODE_PLAN_TIMEOUT_S = 120.0

#: Commands the test does not run: (what the command starts with, or is when it ends in '$';
#: why). Kept short; every entry must still match a command of the pages
#: (test_every_command_left_out_is_still_in_the_pages).
NOT_RUN = (
    ('make test', 'the whole suite (25 minutes and more), this test included'),
    ('make figures', "rewrites the checkout's docs/*.png in place; its plan and sweep commands "
                     'are those run here, and test_results_and_figures draws the figures'),
    ('make install', 'builds the venv this test already runs in'),
    ('pip install', "installs from PyPI into the user's own environment"),
    ('ros2 ', 'the ros2 command line comes with a ROS 2 installation, not with the PyPI '
              'wheels; `ros2 run` is .venv/bin/planner (run here through `make run`) and the '
              "launch file's logic is tested in test_packaging"),
    ('.venv/bin/planner --ros-args -p mavlink_url:=', 'needs a vehicle on the MAVLink link'),
    ('uav-comm-planner upload', 'needs a vehicle at the --connect address'),
    ('send_ground_nodes', 'waits for a running planner node to take the nodes'),
    ('python -m uav_comm_planner.ros.send_ground_nodes', 'waits for a running planner node'),
    ('dask ', 'a Dask scheduler or worker: servers that run until stopped'),
    ('uav-comm-planner montecarlo --cases 200 --nodes 4:12 --seed 1 --out study.parquet '
     '--figure cdf.pdf --scheduler', 'needs the Dask scheduler at tcp://HOST:8786'),
    ('uav-comm-planner montecarlo --cases 200 ', 'a long run (1800 scenarios: 1.5 minutes on '
                                                 'two idle cores, 5 on two busy ones); the '
                                                 'study machinery runs in the --scaling --quick '
                                                 'form and in test_study'),
    ('uav-comm-planner montecarlo --scaling --cases 200', 'a long run (the full scaling study, '
                                                          "minutes); its --quick form runs"),
    ('uav-comm-planner montecarlo --out study.parquet$', 'resumes the table a study wrote '
                                                         'before (without one it runs a '
                                                         'default study: a long run)'),
    ('make bench', 'the benchmark (minutes even --quick, tens of minutes in full with its SITL '
                   'flights); test_bench runs its sections on small sizes'),
    ('uav-comm-planner fit-airframe flight.tlog', "fits the user's own flight log; "
                                                  'test_airframe runs the command on a '
                                                  'recorded SITL log'),
)


#: Files a page's command reads that the user brings, not the checkout: here with what the
#: page assumes they hold (a ground station's saved parameters: ArduCopter's defaults).
USER_FILES = {
    'copter.param': 'WPNAV_SPEED,1000\nWPNAV_ACCEL,250\nWPNAV_JERK,1\nATC_INPUT_TC,0.15\n',
}

#: Blocks the test does not run as a whole: (their first command, why).
BLOCKS_NOT_RUN = (
    ('source /opt/ros/jazzy/setup.bash', 'the colcon workspace: needs a ROS 2 Jazzy '
                                         'installation, sudo for rosdep and a clone of the '
                                         'repository'),
)


@dataclass
class Command:
    """One command of a page: its words, where it is, and what the page quotes of its output."""

    page: str
    line: int
    words: list[str]
    text: str
    quoted_lines: list[str] = field(default_factory=list)
    quoted_numbers: list[str] = field(default_factory=list)


@dataclass
class Example:
    """Commands the page shows together (one ```sh block, or one inline command): run in order
    in one folder, since a later one may read what an earlier one wrote."""

    page: str
    line: int
    commands: list[Command]

    @property
    def name(self) -> str:
        return f'{self.page}:{self.line}'


def _line_of(text: str, offset: int) -> int:
    return text.count('\n', 0, offset) + 1


def _shell_lines(block: str) -> list[tuple[int, str]]:
    """The logical lines of a shell block (continuations joined), with their first line's
    index in the block."""
    lines, current, start = [], '', 0
    for index, line in enumerate(block.splitlines()):
        if not current:
            start = index
        if line.rstrip().endswith('\\'):
            current += line.rstrip()[:-1] + ' '
            continue
        lines.append((start, current + line))
        current = ''
    if current:
        lines.append((start, current))
    return lines


def _commands_of_line(page: str, line: int, text: str) -> list[Command]:
    """The commands of one shell line: comments dropped, `a && b` split."""
    words = shlex.split(text, comments=True)
    commands, current = [], []
    for word in [*words, '&&']:
        if word == '&&':
            if current:
                commands.append(Command(page, line, current, shlex.join(current)))
            current = []
        else:
            current.append(word)
    return commands


#: An inline command: the command line's (the bare name, or with a subcommand only and no
#: .venv/bin/, names it: not a command), or `make run` with or without ARGS.
INLINE = re.compile(r'`((?:\.venv/bin/)?uav-comm-planner [^`]+|make run(?: [^`]*)?)`')
#: The languages of a fenced block that quotes what a command printed.
OUTPUT_BLOCKS = ('', 'text')
FENCE = re.compile(r'^```(\w*)\n(.*?)^```', re.S | re.M)


def examples() -> list[Example]:
    """Every command of the pages, with the output each page quotes for it."""
    found = []
    for path in PAGES:
        page = str(path.relative_to(ROOT))
        text = path.read_text(encoding='utf-8')
        blocks = list(FENCE.finditer(text))
        events: list[tuple[int, int, Example | None, re.Match]] = []
        for block in blocks:
            if block.group(1) == 'sh':
                first = _line_of(text, block.start()) + 1
                commands = [command for index, line in _shell_lines(block.group(2))
                            for command in _commands_of_line(page, first + index, line)]
                example = Example(page, first - 1, commands)
                found.append(example)
                events.append((block.start(), block.end(), example, block))
            elif block.group(1) in OUTPUT_BLOCKS:
                events.append((block.start(), block.end(), None, block))
        inside = [(block.start(), block.end()) for block in blocks]
        for match in INLINE.finditer(text):
            if any(start <= match.start() < end for start, end in inside):
                continue
            line = _line_of(text, match.start())
            (command,) = _commands_of_line(page, line, match.group(1))
            if command.words[0] == 'uav-comm-planner' and len(command.words) == 2 \
                    and not command.words[1].startswith('-'):
                continue        # `uav-comm-planner montecarlo`: a subcommand's name

            example = Example(page, line, [command])
            found.append(example)
            events.append((match.start(), match.end(), example, match))
            # "`command` prints 11.5713 bit/s ... against 11.2315 ...": the numbers it prints.
            after = text[match.end():]
            said = re.match(r'\s+prints ([^(.]*(?:\.\d[^(.]*)*)', after)
            if said:
                command.quoted_numbers = re.findall(r'\d+\.\d+', said.group(1))
        events.sort(key=lambda event: event[0])
        for index, (start, _end, example, block) in enumerate(events):
            if example is not None or index == 0:
                continue
            previous_start, previous_end, previous, _ = events[index - 1]
            if previous is None:
                continue
            between = text[previous_end:start]
            if isinstance(_, re.Match) and _.re is INLINE:
                # The quote follows the paragraph naming the command, which ends in a colon.
                paragraph_ends = between.find('\n\n')
                if paragraph_ends == -1 or between[:paragraph_ends].rstrip()[-1:] != ':' or \
                        between[paragraph_ends:].strip():
                    continue
            elif between.strip():
                continue
            previous.commands[-1].quoted_lines += [
                line for line in block.group(2).splitlines() if line.strip()]
    # An inline command shown again is run once, checked against every quote of it.
    first_of: dict[str, Command] = {}
    unique = []
    for example in found:
        if len(example.commands) == 1 and example.commands[0].text in first_of:
            first = first_of[example.commands[0].text]
            first.quoted_lines += example.commands[0].quoted_lines
            first.quoted_numbers += example.commands[0].quoted_numbers
            continue
        for command in example.commands:
            first_of.setdefault(command.text, command)
        unique.append(example)
    return unique


def not_run_reason(text: str) -> str | None:
    """Why the command (or the block it starts) is not run; None: it is run."""
    bare = text.removeprefix('.venv/bin/') if text.startswith('.venv/bin/uav-comm') else text
    words = shlex.split(text)
    while words and re.fullmatch(r'[A-Z_]+=\S*', words[0]):       # VAR=value command
        words.pop(0)
    without_env = shlex.join(words)
    for start, reason in NOT_RUN:
        for form in (bare, without_env, without_env.removeprefix('.venv/bin/')):
            if (form == start[:-1]) if start.endswith('$') else form.startswith(start):
                return reason
    return None


def block_not_run_reason(example: Example) -> str | None:
    """Why a whole block is not run; None: its commands are run unless NOT_RUN names them."""
    return next((reason for first, reason in BLOCKS_NOT_RUN
                 if example.commands and example.commands[0].text == first), None)


def _copy_checkout_files(words: list[str], folder: Path) -> None:
    """Copy each checkout file a word names by a relative path (`--fence docs/x.geojson`,
    `--params-file config/planner.yaml`, `-p name:=path`) into ``folder``."""
    for word in words:
        for candidate in re.split(r'[=]|:=', word):
            if not candidate or candidate.startswith(('/', '-', '~')):
                continue
            source = ROOT / candidate
            if source.is_file() and ROOT in source.resolve().parents:
                (folder / candidate).parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(source, folder / candidate)


def _program(words: list[str]) -> tuple[list[str], dict[str, str]]:
    """The argv this venv runs for a page's command, and the environment it adds."""
    env = {}
    while words and re.fullmatch(r'[A-Z_]+=\S*', words[0]):
        name, value = words[0].split('=', 1)
        env[name] = value
        words = words[1:]
    head, rest = words[0], words[1:]
    if head.startswith('.venv/bin/'):
        return [str(BIN / head.removeprefix('.venv/bin/')), *rest], env
    if head == 'uav-comm-planner':
        return [str(BIN / head), *rest], env
    if head == 'make' and rest[:1] == ['run']:
        # The Makefile's run target: $(ROS_ENV) ROS_DOMAIN_ID=... $(BIN)/planner $(ARGS).
        arguments = [word.split('=', 1)[1] for word in rest[1:] if word.startswith('ARGS=')]
        return [str(BIN / 'planner'), *shlex.split(''.join(arguments))], {**ROS_ENV, **env}
    raise AssertionError(f'no mechanical mapping for {shlex.join(words)!r}: run it in the test '
                         f'or give NOT_RUN a reason')


def _run_node(argv: list[str], env: dict[str, str], cwd: Path) -> tuple[int, str]:
    """Start the node, wait for its first plan line, stop it with Ctrl-C: (status, output)."""
    process = subprocess.Popen(argv, cwd=cwd, env=env, stdout=subprocess.PIPE,
                               stderr=subprocess.STDOUT, text=True)
    lines: list[str] = []
    reader = threading.Thread(target=lambda: lines.extend(process.stdout), daemon=True)
    reader.start()
    deadline = time.monotonic() + NODE_PLAN_TIMEOUT_S
    try:
        while (process.poll() is None and time.monotonic() < deadline
               and not any(': plan: ' in line for line in list(lines))):
            time.sleep(0.2)
        if process.poll() is None:
            process.send_signal(signal.SIGINT)
        status = process.wait(timeout=60)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    reader.join(timeout=10)
    return status, ''.join(lines)


def _run(command: Command, folder: Path) -> str:
    argv, added = _program(list(command.words))
    _copy_checkout_files(argv[1:], folder)
    for name, text in USER_FILES.items():
        if name in command.words:
            (folder / name).write_text(text)
    env = {**os.environ, **added}
    if Path(argv[0]).name == 'planner' and '--help' not in argv:
        status, output = _run_node(argv, env, folder)
        assert status == 0 and ': plan: ' in output, (
            f'{command.page}:{command.line}: {command.text}\n{output[-3000:]}')
        return output
    done = subprocess.run(argv, cwd=folder, env=env, capture_output=True, text=True,
                          timeout=COMMAND_TIMEOUT_S)
    output = done.stdout + done.stderr
    assert done.returncode == 0, (
        f'{command.page}:{command.line}: {command.text} exited {done.returncode}\n'
        f'{output[-3000:]}')
    return output


#: What a quoted line may differ in: `[...]` (anything), and how long planning took.
VARYING = re.compile(r'(\[\.\.\.\]|(?<=planned in )[0-9.]+(?= s)|(?<=plan time )[0-9.]+(?= s))')


def quoted_line_pattern(line: str) -> re.Pattern:
    """A quoted output line as a pattern: `[...]` stands for anything, run times vary."""
    parts = VARYING.split(line.strip())
    return re.compile(''.join(
        re.escape(part) if index % 2 == 0 else '.*?' if part == '[...]' else '[0-9.]+'
        for index, part in enumerate(parts)))


EXAMPLES = examples()


@pytest.mark.slow
@pytest.mark.parametrize('example', EXAMPLES, ids=lambda example: example.name)
def test_a_command_of_the_docs_works_as_written(example: Example, tmp_path: Path):
    ran = 0
    for command in example.commands:
        if block_not_run_reason(example) or not_run_reason(command.text):
            continue
        output = _run(command, tmp_path)
        ran += 1
        for line in command.quoted_lines:
            if line.strip() == '...':
                continue
            assert quoted_line_pattern(line).search(output), (
                f'{command.page}:{command.line}: {command.text}: the page quotes\n{line}\n'
                f'but it printed\n{output[-3000:]}')
        for number in command.quoted_numbers:
            assert re.search(rf'(?<![\d.]){re.escape(number)}(?![\d])', output), (
                f'{command.page}:{command.line}: the page says it prints {number}:\n{output}')
    if not ran:
        pytest.skip(block_not_run_reason(example) or '; '.join(
            f'{command.text}: {not_run_reason(command.text)}' for command in example.commands))


def test_the_commands_are_found_with_what_the_pages_quote():
    """The extraction itself: known commands and quotes are found (not copied: looked up)."""
    texts = {command.text: command for example in EXAMPLES for command in example.commands}
    readme_case_one = [command for text, command in texts.items()
                       if text.endswith('plan --case I --figure plan.png')]
    assert readme_case_one and len(readme_case_one[0].quoted_numbers) == 3
    make_run = [command for command in texts.values()
                if command.page == 'README.md' and command.text == 'make run']
    assert any(': plan: min throughput' in line for command in make_run
               for line in command.quoted_lines)
    assert any(command.quoted_lines and command.page == 'docs/flying.md'
               for command in texts.values())
    # The multi-line commands are joined, comments dropped.
    assert any('--home=-35.363262,149.165237,584' in command.words
               and command.words[-1] == 'docs/fences_case_I.png' for command in texts.values())
    assert not any('#' in word for command in texts.values() for word in command.words)
    run = [text for example in EXAMPLES if not block_not_run_reason(example)
           for text in (command.text for command in example.commands)
           if not not_run_reason(text)]
    assert len(run) >= 20, run


def test_every_command_left_out_is_still_in_the_pages():
    texts = [command.text for example in EXAMPLES for command in example.commands]
    for start, reason in NOT_RUN:
        assert reason and any(not_run_reason(text) == reason for text in texts), start
    for first, reason in BLOCKS_NOT_RUN:
        assert reason and any(block_not_run_reason(example) == reason
                              for example in EXAMPLES), first


def test_quoted_line_patterns_allow_only_what_varies():
    pattern = quoted_line_pattern('[INFO] [...] [uav_comm_planner]: plan: min throughput 11.19 '
                                  'bit/s; converged, planned in 0.06 s')
    assert pattern.search('[INFO] [1796.5] [uav_comm_planner]: plan: min throughput 11.19 '
                          'bit/s; converged, planned in 0.04 s')
    assert not pattern.search('[INFO] [1796.5] [uav_comm_planner]: plan: min throughput 11.20 '
                              'bit/s; converged, planned in 0.04 s')


def test_planner_help_prints_its_usage_and_does_not_start_the_node(tmp_path: Path):
    started = time.monotonic()
    done = subprocess.run([str(BIN / 'planner'), '--help'], cwd=tmp_path, capture_output=True,
                          text=True, timeout=60, env={**os.environ, **ROS_ENV})
    assert done.returncode == 0 and done.stdout.startswith('usage: planner')
    assert '--ros-args' in done.stdout and 'plan:' not in done.stdout + done.stderr
    assert time.monotonic() - started < 30
