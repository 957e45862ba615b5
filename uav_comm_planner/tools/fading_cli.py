"""The command line's fading options: ``plan --fading rician|rayleigh`` judges the plan (made
on the expected gain) by Monte Carlo over the fading (:mod:`uav_comm_planner.core.fading`),
prints the ergodic min throughput and its spread, and adds them to the JSON result as
``fading``."""

from __future__ import annotations

import argparse

import numpy as np

from uav_comm_planner.core.fading import (DEFAULT_K_DB, DEFAULT_SAMPLES, evaluate_fading,
                                          Fading, FADING_MODELS, FadingEvaluation)
from uav_comm_planner.core.scenario import Scenario
from uav_comm_planner.errors import InvalidScenarioError


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """--fading, --fading-samples, --seed, --rician-k-db on the plan command."""
    group = parser.add_argument_group(
        'fading in the evaluation (docs/channel.md): the plan judged by Monte Carlo')
    group.add_argument('--fading', choices=FADING_MODELS,
                       help='rician: line of sight by the channel\'s P_LoS, Rician in line of '
                            'sight and Rayleigh out of it; rayleigh: every link Rayleigh')
    group.add_argument('--fading-samples', type=int, metavar='N',
                       help=f'draws of the whole horizon (default {DEFAULT_SAMPLES})')
    group.add_argument('--seed', type=int, metavar='S', help='the draws\' seed (default 0)')
    group.add_argument('--rician-k-db', type=float, metavar='K',
                       help=f'Rician factor of a line-of-sight link, dB (default '
                            f'{DEFAULT_K_DB:g})')


def fading_from(args: argparse.Namespace) -> Fading | None:
    """The fading the options ask for (None without --fading); the other options alone are a
    typed error."""
    extras = [flag for flag, value in (('--fading-samples', args.fading_samples),
                                       ('--seed', args.seed), ('--rician-k-db', args.rician_k_db))
              if value is not None]
    if args.fading is None:
        if extras:
            raise InvalidScenarioError(f'{extras[0]} needs --fading rician|rayleigh')
        return None
    return Fading(args.fading,
                  DEFAULT_K_DB if args.rician_k_db is None else args.rician_k_db,
                  DEFAULT_SAMPLES if args.fading_samples is None else args.fading_samples,
                  0 if args.seed is None else args.seed)


def evaluate(fading: Fading | None, q: np.ndarray, p: np.ndarray, scenario: Scenario,
             altitudes: np.ndarray | None = None) -> FadingEvaluation | None:
    """The plan under ``fading`` (None: no evaluation); its lines printed."""
    if fading is None:
        return None
    evaluation = evaluate_fading(q, p, scenario, fading, altitudes)
    print(format_fading(evaluation))
    return evaluation


def format_fading(evaluation: FadingEvaluation) -> str:
    """Two lines: the fading, and the ergodic min throughput with its spread."""
    fading = evaluation.fading
    model = (f'Rician (K = {fading.k_factor_db:g} dB) in line of sight, Rayleigh out of it'
             if fading.model == 'rician' else 'Rayleigh on every link')
    return (f'fading: {model}; {fading.samples} draws of the horizon, seed {fading.seed}\n'
            f'{"ergodic min throughput (bit/s)":<42}{evaluation.mean:>28.4f}\n'
            f'  std {evaluation.std:.4g}, 5th percentile {evaluation.fifth_percentile:.4f}, '
            f'min over nodes of their ergodic throughput {evaluation.min_node_ergodic:.4f} '
            f'(planned on the expected gain: {evaluation.planned:.4f})')


def fading_record(evaluation: FadingEvaluation | None) -> dict:
    """{'fading': ...} for the JSON result, or nothing."""
    return {} if evaluation is None else {'fading': evaluation.to_dict()}


__all__ = ['add_arguments', 'evaluate', 'fading_from', 'fading_record', 'format_fading']
