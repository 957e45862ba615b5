"""The documentation: generated parameter tables, a short front page, links that resolve."""

from __future__ import annotations

from pathlib import Path
import re
import shutil

import pytest
import yaml

from devtools import docgen
from uav_comm_planner.ros.params import parameter_specs

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
NODE_DOC = ROOT / 'docs' / 'node.md'
PAGES = (README, *sorted((ROOT / 'docs').glob('*.md')))
#: A Markdown link or image; ``a_n[m](q^k)`` in a formula is not one.
LINK = re.compile(r'(?<![\w\]])\[[^\]]*\]\(([^)\s]+)\)')


def test_node_md_parameter_tables_are_what_the_code_generates():
    text = NODE_DOC.read_text(encoding='utf-8')
    assert docgen.replace_section(text, docgen.parameter_tables()) == text, (
        'docs/node.md is out of date: run python -m devtools.docgen')
    assert docgen.main(['--check', str(NODE_DOC)]) == 0


def test_every_parameter_has_a_row_with_its_type_and_default():
    tables = docgen.parameter_tables()
    for spec in parameter_specs():
        row = next(line for line in tables.splitlines() if line.startswith(f'| `{spec.name}` |'))
        cells = [cell.strip() for cell in row.strip('|').split(' | ')]
        assert cells[1] == docgen.ROS_TYPES[spec.kind]
        assert yaml.safe_load(cells[2].strip('`')) == spec.default
        assert cells[3].startswith(spec.descriptor().description.replace('|', '\\|'))
    assert '| `num_slots` | integer | `100` |' in tables
    assert 'range 1 to 100000' in tables


def test_a_stale_table_is_found_and_rewritten(tmp_path, capsys):
    copy = tmp_path / 'node.md'
    shutil.copy(NODE_DOC, copy)
    text = copy.read_text()
    copy.write_text(text.replace('| `num_slots` | integer | `100` |',
                                 '| `num_slots` | integer | `60` |'))
    assert docgen.main(['--check', str(copy)]) == 1
    assert 'differ from the code' in capsys.readouterr().err
    assert docgen.main([str(copy)]) == 0
    assert copy.read_text() == text
    no_markers = tmp_path / 'plain.md'
    no_markers.write_text('# nothing to fill\n')
    assert docgen.main([str(no_markers)]) == 2
    assert no_markers.read_text() == '# nothing to fill\n'


def test_readme_is_a_short_front_page_with_the_topic_diagram_and_the_two_commands():
    from uav_comm_planner.ros.node import TOPIC_GROUND_NODES, TOPIC_UAV_POSE
    from uav_comm_planner.ros.publishing import (TOPIC_MARKERS, TOPIC_MIN_THROUGHPUT,
                                                 TOPIC_PATH, TOPIC_POWER)

    text = README.read_text(encoding='utf-8')
    assert len(text.splitlines()) <= 130
    assert 'make run' in text and 'make test' in text
    (diagram,) = re.findall(r'```mermaid\n(.*?)```', text, re.S)
    for topic in (TOPIC_GROUND_NODES, TOPIC_UAV_POSE, TOPIC_PATH, TOPIC_POWER,
                  TOPIC_MIN_THROUGHPUT, TOPIC_MARKERS):
        assert f'"{topic}<br/>' in diagram, topic
    assert 'mission file' in diagram and 'MAVLink' in diagram
    for page in ('model', 'node', 'missions', 'benchmark', 'extending', 'usage'):
        assert f'(docs/{page}.md)' in text, page
    assert 'make test' in (ROOT / '.ci' / 'run').read_text()


def _anchors(page: Path) -> set[str]:
    """GitHub's heading anchors: lower case, punctuation dropped, spaces as hyphens."""
    headings = re.findall(r'^#+ (.+)$', page.read_text(encoding='utf-8'), re.M)
    return {re.sub(r'[^\w\- ]', '', heading.lower()).replace(' ', '-') for heading in headings}


@pytest.mark.parametrize('page', PAGES, ids=lambda p: p.name)
def test_every_relative_link_and_anchor_resolves(page):
    broken = []
    for target in LINK.findall(page.read_text(encoding='utf-8')):
        if re.match(r'[a-z]+:', target):
            continue
        path, _, anchor = target.partition('#')
        resolved = (page.parent / path).resolve() if path else page
        if not resolved.exists():
            broken.append(target)
        elif anchor and resolved.suffix == '.md' and anchor not in _anchors(resolved):
            broken.append(target)
    assert broken == []


def test_the_colcon_pip_line_uses_setup_py_ranges():
    """The pip-only packages of the colcon route, with the ranges setup.py requires."""
    (line,) = [line for line in NODE_DOC.read_text().splitlines()
               if line.startswith('python -m pip install')]
    requirements = re.findall(r"'([^']+)'", line)
    setup_text = (ROOT / 'setup.py').read_text()
    assert {r.split('>')[0] for r in requirements} == {'cvxpy', 'clarabel', 'pymavlink'}
    for requirement in requirements:
        assert f"'{requirement}'" in setup_text, requirement
