"""Evaluation: the thesis's success rate, the test protocol, baselines, experiments."""

from behavior_hmm.evaluate._baselines import BehaviorCloning, StrongBehaviorCloning
from behavior_hmm.evaluate._generator_sweeps import run_generator_sweeps
from behavior_hmm.evaluate._metrics import edm, success_rate, zero_floor
from behavior_hmm.evaluate._protocol import evaluate_model, reference_demonstration, split_start

__all__ = [
    "BehaviorCloning",
    "StrongBehaviorCloning",
    "edm",
    "evaluate_model",
    "reference_demonstration",
    "run_generator_sweeps",
    "split_start",
    "success_rate",
    "zero_floor",
]
