"""The altitude study: its hover altitudes against the search, its plans, its figure and JSON."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ElementTree

import matplotlib
import numpy as np

from uav_comm_planner.tools import altitude_study, cli


def test_altitude_study_command_writes_its_figure_and_numbers(tmp_path, capsys):
    figure, numbers = tmp_path / 'study.svg', tmp_path / 'study.json'
    with matplotlib.rc_context({'svg.fonttype': 'none'}):       # text as <text> elements
        assert cli.main(['altitude-study', '--slots', '20', '--figure', str(figure), '--json',
                         str(numbers)]) == 0
    out = capsys.readouterr()[0]
    assert 'los:highrise-urban' in out and 'case I with altitudes' in out
    data = json.loads(numbers.read_text())
    for name, row in data['hover'].items():
        planned, searched = np.array(row['planned_m']), np.array(row['searched_m'])
        assert np.abs(planned - searched).max() <= 5.0, name
        # The best elevation angle is the environment's: h / r the same at every distance.
        ratio = searched / np.array(data['distances_m'])
        assert ratio.max() - ratio.min() <= 0.01 * ratio.mean(), name
    searched_300 = [data['hover'][f'los:{env}']['searched_m'][2]
                    for env in ('suburban', 'urban', 'dense-urban', 'highrise-urban')]
    assert searched_300 == sorted(searched_300)         # a harsher city, a higher UAV
    assert searched_300[2] == altitude_study.searched_altitude('los:dense-urban', 300.0)
    case = data['case_I']
    assert set(case) == {'free-space', 'los:suburban', 'los:urban', 'los:dense-urban',
                         'los:highrise-urban'}
    assert np.allclose(case['free-space']['altitudes_m'], 30.0)
    for row in case.values():
        assert row['min_throughput'] >= row['fixed_altitude_throughput']
        assert len(row['altitudes_m']) == 20
    text = ''.join(ElementTree.parse(figure).getroot().itertext())
    assert 'best hover altitude over one node' in text and 'case I with altitudes' in text
    for name in case:
        assert name in text
