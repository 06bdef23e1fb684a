"""The strong behavior-cloning baseline: BehaviorCloning with a 2 x 64 network and Adam."""

from __future__ import annotations

import inspect
from typing import Any

import numpy as np
import pytest
import test_estimator_conformance as conformance  # tests/ is on sys.path (its conftest)

from behavior_hmm._estimator import clone
from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate import BehaviorCloning, StrongBehaviorCloning, evaluate_model
from behavior_hmm.generators import MotionGenerators
from behavior_hmm.generators._motion import AdamGenerators

# quick settings for the tests: fewer epochs, a larger step
QUICK = {"epochs": 40, "learning_rate": 3e-3, "patience": 10}


@pytest.fixture(scope="module")
def strong(turn_data: Dataset) -> StrongBehaviorCloning:
    return StrongBehaviorCloning(inputs=("angle",), **QUICK).fit(turn_data)


def test_defaults_are_a_wide_adam_trained_behavior_cloning() -> None:
    model = StrongBehaviorCloning()
    assert isinstance(model, BehaviorCloning)
    params = model.get_params()
    assert params["hidden"] == (64, 64) and params["optimizer"] == "adam"
    assert (params["learning_rate"], params["batch_size"], params["epochs"]) == (2e-3, 128, 300)
    assert params["patience"] == 20
    # the same parameters as BehaviorCloning, in the same order: only defaults differ
    names = list(inspect.signature(BehaviorCloning.__init__).parameters)
    assert list(inspect.signature(StrongBehaviorCloning.__init__).parameters) == names
    assert list(params) == names[1:]
    assert repr(model) == "StrongBehaviorCloning()"
    assert repr(StrongBehaviorCloning(("distance", "angle"), hidden=(32, 32))) == (
        "StrongBehaviorCloning(inputs=('distance', 'angle'), hidden=(32, 32))"
    )
    assert repr(clone(StrongBehaviorCloning(epochs=5))) == "StrongBehaviorCloning(epochs=5)"
    assert (model.kind, model.label) == ("BC-strong", "bc-strong")
    assert (BehaviorCloning.kind, BehaviorCloning.label) == ("BC", "bc")
    # plain BC keeps SGD with momentum and one layer
    bc = BehaviorCloning().get_params()
    assert (bc["optimizer"], bc["hidden"], bc["patience"], bc["init_range"]) == (
        "sgd",
        None,
        None,
        1.0,
    )


def test_fits_a_two_layer_adam_network(strong: StrongBehaviorCloning) -> None:
    net = strong.network_
    assert isinstance(net, AdamGenerators)
    assert net.hidden_sizes_ == (64, 64)
    assert net.n_test_[0] > 0  # the held-out episodes for early stopping
    best = int(net.best_epoch_[0])
    assert best == int(np.nanargmin(net.test_error_[0]))
    assert strong.feature_layout().width == net.n_features_in_


def test_is_behavior_cloning_with_other_defaults(turn_data: Dataset) -> None:
    strong = StrongBehaviorCloning(epochs=3).fit(turn_data)
    same = BehaviorCloning(
        hidden=(64, 64),
        learning_rate=2e-3,
        epochs=3,
        batch_size=128,
        optimizer="adam",
        patience=20,
        init_range=0.2,
    ).fit(turn_data)
    for a, b in zip(same.network_.coefs_, strong.network_.coefs_, strict=True):
        np.testing.assert_array_equal(a, b)
    assert isinstance(BehaviorCloning(epochs=2).fit(turn_data).network_, MotionGenerators)
    assert not isinstance(BehaviorCloning(epochs=2).fit(turn_data).network_, AdamGenerators)


def test_generates_to_the_goal_from_turn_starts(
    strong: StrongBehaviorCloning, kinematic_env: Any
) -> None:
    for angle in (-135.0, 75.0):  # between the training grid's starts
        trace = strong.generate(kinematic_env, start={"angle": angle, "distance": 0.5}, seed=0)
        assert trace.goal_reached and trace.reason == "goal"
        assert set(trace.component) == {"bc-strong"}


def test_evaluates_beside_bc(turn_data: Dataset, turn_model: Any, strong: Any) -> None:
    bc = BehaviorCloning(inputs=("angle",), epochs=40).fit(turn_data)
    starts = [{"angle": -95.0}, {"angle": 45.0}]
    result = evaluate_model(
        turn_model, starts, sim="kinematic", baselines={"bc": bc, "bc-strong": strong}
    )
    assert set(result["baselines"]) == {"bc", "bc-strong"}
    assert result["baselines"]["bc-strong"]["goal_reached"] == 2


def test_refuses_an_unknown_optimizer(turn_data: Dataset) -> None:
    with pytest.raises(ConfigError, match="optimizer"):
        StrongBehaviorCloning(optimizer="rmsprop").fit(turn_data)


# The estimator conformance checks (tests/test_estimator_conformance.py) on this estimator.
data = conformance.data  # that module's fixture: small kinematic turn data

STRONG = conformance.Case(
    StrongBehaviorCloning,
    lambda d: {"hidden": (4, 3), "epochs": 3, "random_state": 1},
    lambda d: (d.ds,),
    lambda d: (conformance.nan_dataset(d.ds),),
    lambda est, d: est.resolve_goal(None),
    {"epochs": 2, "patience": 5},
)

CHECKS = [
    conformance.test_fit_returns_self,
    conformance.test_refit_with_the_same_data_and_seed_learns_the_same,
    conformance.test_learned_methods_refuse_an_unfitted_model,
    conformance.test_nan_input_is_refused,
    conformance.test_clone_is_unfitted_with_equal_params,
    conformance.test_get_params_set_params_round_trip,
    conformance.test_repr_shows_the_class_and_the_changed_params,
]


@pytest.mark.parametrize("check", CHECKS, ids=lambda f: f.__name__.removeprefix("test_"))
def test_estimator_conformance(check: Any, data: Any) -> None:
    check(STRONG, data)
