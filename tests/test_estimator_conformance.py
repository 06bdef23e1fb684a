"""Every estimator follows the same scikit-learn style conventions (the Estimator base).

One table of estimators, each with small kinematic training data, and the checks of
scikit-learn's ``check_estimator`` in spirit: ``fit`` returns ``self`` and is
deterministic; learned methods refuse an unfitted model; NaN input is refused;
``clone``, ``get_params`` / ``set_params`` and ``repr`` behave alike everywhere.
"""

from __future__ import annotations

import inspect
import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import pytest

from behavior_hmm._estimator import Estimator, clone, is_fitted
from behavior_hmm.cobart import CobART, HierarchicalCobART
from behavior_hmm.data import CommandScaler, Dataset, SignalPipeline
from behavior_hmm.errors import BehaviorHMMError, ConfigError, DatasetError, NotFittedError
from behavior_hmm.evaluate._baselines import BehaviorCloning
from behavior_hmm.generators import MotionGenerators, make_windows
from behavior_hmm.hmm import BehaviorHMM
from behavior_hmm.models import CBLM, SBLM

# ------------------------------------------------------------------ training data


@dataclass(frozen=True)
class Data:
    """Small kinematic turn demonstrations in the forms the estimators take."""

    ds: Dataset  # raw demonstrations
    tagged: Dataset  # the same, every row tagged as the sub-behavior "turn" (for a CBLM)
    x: np.ndarray  # filtered, normalized (angle, angular_velocity)
    lengths: np.ndarray
    states: np.ndarray  # motion-primitive labels (for the Behavior-HMM, the generators)
    observations: np.ndarray  # observation-category labels
    windows: np.ndarray  # generator inputs
    y: np.ndarray  # normalized commands
    component: SBLM  # a fitted SBLM, the state of the CBLM


def with_nan(a: np.ndarray, where: tuple[int, ...]) -> np.ndarray:
    out = np.array(a, dtype=np.float64, copy=True)
    out[where] = np.nan
    return out


def nan_dataset(ds: Dataset) -> Dataset:
    """``ds`` with one NaN angle, past the validation of ``Dataset`` (which refuses it)."""
    cols = {k: np.array(v, copy=True) for k, v in ds.to_columns().items()}
    cols["angle"][5] = np.nan
    with pytest.raises(DatasetError, match="NaN"):
        Dataset(cols, ds.metadata)
    # the estimators must not rely on that: a dataset built without the checks
    return Dataset._trusted(cols, ds.metadata)


@pytest.fixture(scope="module")
def data(turn_data: Dataset, turn_model: SBLM) -> Data:
    ds = turn_data.subset(list(range(0, len(turn_data), 3)))  # 6 demonstrations
    tagged = Dataset.from_episodes(
        [{**ep.to_dict(), "behavior": "turn"} for ep in ds.episodes()],
        metadata={"behavior": "turn-only"},
    )
    x = SignalPipeline(("angle", "angular_velocity")).transform(ds)
    lengths = ds.lengths
    states = CobART.motion_primitives().fit_predict(x[:, :1], lengths)
    observations = CobART.observations().fit_predict(x[:, :1], lengths)
    y = CommandScaler().fit(ds.commands).transform(ds.commands)
    windows = make_windows(x[:, :1], lengths, 10)
    return Data(ds, tagged, x, lengths, states, observations, windows, y, turn_model)


# ------------------------------------------------------------------ the estimators


@dataclass(frozen=True)
class Case:
    """How to build, fit and use one estimator."""

    cls: type[Estimator]
    params: Callable[[Data], dict[str, Any]]  # constructor arguments, all non-default
    fit_args: Callable[[Data], tuple[Any, ...]]
    nan_args: Callable[[Data], tuple[Any, ...]]  # fit_args with a NaN
    use: Callable[[Any, Data], Any]  # a method that needs the fitted state
    tweak: Mapping[str, Any]  # a set_params call (deep names allowed)
    nan_match: str = "NaN"

    def make(self, data: Data) -> Any:
        return self.cls(**self.params(data))

    def fitted(self, data: Data) -> Any:
        return self.make(data).fit(*self.fit_args(data))

    def __str__(self) -> str:
        return self.cls.__name__


CASES = [
    Case(
        CobART,
        lambda d: {"rho": 0.8, "window": 4},
        lambda d: (d.x, d.lengths),
        lambda d: (with_nan(d.x, (7, 1)), d.lengths),
        lambda est, d: est.predict(d.x, d.lengths),
        {"rho": 0.7},
    ),
    Case(
        HierarchicalCobART,
        lambda d: {
            "layers": {"angle": CobART(window=3), "rate": CobART(window=3)},
            "channels": {"angle": [0], "rate": [1]},
            "w_f": 0.3,
            "relation": CobART(rho=0.9),
        },
        lambda d: (d.x, d.lengths),
        lambda d: (with_nan(d.x, (7, 0)), d.lengths),
        lambda est, d: est.predict(d.x, d.lengths),
        {"w_f": 0.5, "relation__rho": 0.8},
    ),
    Case(
        BehaviorHMM,
        lambda d: {"smoothing": 0.5, "counting": "steps"},
        lambda d: (d.states, d.observations, d.lengths),
        # float labels with a NaN: refused as labels that are not integers
        lambda d: (d.states, with_nan(d.observations, (3,)), d.lengths),
        lambda est, d: est.viterbi(d.observations[:20]),
        {"path_self_loops": "keep"},
        nan_match="integer labels",
    ),
    Case(
        MotionGenerators,
        lambda d: {"hidden": 4, "epochs": 3, "random_state": 1},
        lambda d: (d.windows, d.y, d.states),
        lambda d: (with_nan(d.windows, (9, 2)), d.y, d.states),
        lambda est, d: est.predict(d.windows[:5], 0),
        {"epochs": 2},
    ),
    Case(
        CommandScaler,
        lambda d: {},
        lambda d: (d.ds.commands,),
        lambda d: (with_nan(d.ds.commands, (4, 0)),),
        lambda est, d: est.transform(d.ds.commands),
        {},
    ),
    Case(
        BehaviorCloning,
        lambda d: {"hidden": 4, "epochs": 3, "random_state": 1},
        lambda d: (d.ds,),
        lambda d: (nan_dataset(d.ds),),
        lambda est, d: est.resolve_goal(None),
        {"epochs": 2},
    ),
    Case(
        SBLM,
        lambda d: {"epochs": 3, "random_state": 1},
        lambda d: (d.ds,),
        lambda d: (nan_dataset(d.ds),),
        lambda est, d: est.goal_category({"angle": 0.0}),
        {"epochs": 2, "smoothing": 0.1},
    ),
    Case(
        CBLM,
        lambda d: {"components": [d.component], "inputs": ("angle",), "switch_cycles": 4},
        lambda d: (d.tagged,),
        lambda d: (nan_dataset(d.tagged),),
        lambda est, d: est.resolve_goal(None),
        {"switch_cycles": 2},
    ),
]

by_estimator = pytest.mark.parametrize("case", CASES, ids=str)


# ------------------------------------------------------------------ comparisons


def learned(est: Any) -> dict[str, Any]:
    """The learned attributes: public names ending in ``_`` (properties included)."""
    names = [n for n in dir(est) if n.endswith("_") and not n.startswith("_")]
    return {n: getattr(est, n) for n in names if hasattr(est, n)}


def same(a: Any, b: Any, depth: int = 0) -> bool:
    """Deep equality of parameters / learned state (arrays exact, NaN equal to NaN)."""
    assert depth < 12, "structure too deep to compare"
    if a is b:
        return True
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        a, b = np.asarray(a), np.asarray(b)
        nan_ok = a.dtype.kind in "fc" and b.dtype.kind in "fc"
        return (
            a.shape == b.shape
            and a.dtype == b.dtype
            and bool(np.array_equal(a, b, equal_nan=nan_ok))
        )
    if type(a) is not type(b):
        return False
    if isinstance(a, Mapping):
        return a.keys() == b.keys() and all(same(a[k], b[k], depth + 1) for k in a)
    if isinstance(a, list | tuple):
        return len(a) == len(b) and all(same(u, v, depth + 1) for u, v in zip(a, b, strict=True))
    if isinstance(a, float):
        return a == b or (math.isnan(a) and math.isnan(b))
    if isinstance(a, Estimator):
        return same(a.get_params(deep=False), b.get_params(deep=False), depth + 1) and same(
            learned(a), learned(b), depth + 1
        )
    if hasattr(a, "__dict__"):
        return same(vars(a), vars(b), depth + 1)
    return bool(a == b)


def top_level_names(text: str) -> list[str]:
    """Parameter names shown by ``Name(p=.., q=..)`` (not those of nested reprs)."""
    names: list[str] = []
    depth, token = 0, ""
    for ch in text:
        if ch in "([{":
            depth, token = depth + 1, ""
        elif ch in ")]}":
            depth, token = depth - 1, ""
        elif depth == 1 and ch == "=":
            names.append(token.strip())
        elif depth == 1:
            token = "" if ch == "," else token + ch
    return names


# ------------------------------------------------------------------ the checks


@by_estimator
def test_fit_returns_self(case: Case, data: Data) -> None:
    est = case.make(data)
    assert not is_fitted(est)
    assert est.fit(*case.fit_args(data)) is est
    assert is_fitted(est) and learned(est)


@by_estimator
def test_refit_with_the_same_data_and_seed_learns_the_same(case: Case, data: Data) -> None:
    once = case.fitted(data)
    twice = case.fitted(data).fit(*case.fit_args(data))
    first, second = learned(once), learned(twice)
    assert first.keys() == second.keys()
    different = [name for name in first if not same(first[name], second[name])]
    assert not different, f"{case}: refitting changed {different}"


@by_estimator
def test_learned_methods_refuse_an_unfitted_model(case: Case, data: Data) -> None:
    with pytest.raises(NotFittedError, match=f"{case.cls.__name__}.*not fitted"):
        case.use(case.make(data), data)
    case.use(case.fitted(data), data)  # and work once fitted


@by_estimator
def test_nan_input_is_refused(case: Case, data: Data) -> None:
    with pytest.raises(BehaviorHMMError, match=case.nan_match) as info:
        case.make(data).fit(*case.nan_args(data))
    assert "\n" not in str(info.value)


@by_estimator
def test_clone_is_unfitted_with_equal_params(case: Case, data: Data) -> None:
    est = case.fitted(data)
    copy = clone(est)
    assert type(copy) is type(est) and copy is not est
    assert not is_fitted(copy)
    with pytest.raises(NotFittedError):
        case.use(copy, data)
    assert same(copy.get_params(deep=True), est.get_params(deep=True))
    assert is_fitted(est)  # the original is untouched


@by_estimator
def test_get_params_set_params_round_trip(case: Case, data: Data) -> None:
    est = case.make(data)
    params = est.get_params(deep=False)
    init = inspect.signature(case.cls.__init__).parameters
    assert list(params) == [n for n in init if n != "self"]  # derived from __init__
    rebuilt = case.cls(**case.make(data).get_params(deep=False))
    assert same(rebuilt.get_params(deep=True), est.get_params(deep=True))
    assert rebuilt.set_params(**case.tweak) is rebuilt
    deep = rebuilt.get_params(deep=True)
    assert all(same(deep[k], v) for k, v in case.tweak.items())
    rebuilt.set_params(**est.get_params(deep=True))  # deep names are accepted too
    assert same(rebuilt.get_params(deep=True), est.get_params(deep=True))
    with pytest.raises(ConfigError, match=f"unknown parameter 'colour' for {case.cls.__name__}"):
        rebuilt.set_params(colour="red")
    with pytest.raises(ConfigError) as info:
        rebuilt.set_params(colour="red")
    message = str(info.value)
    assert "\n" not in message
    assert all(name in message for name in params) or "no parameters" in message


@by_estimator
def test_repr_shows_the_class_and_the_changed_params(case: Case, data: Data) -> None:
    est = case.make(data)
    text = repr(est)
    assert text.startswith(f"{case.cls.__name__}(") and text.endswith(")")
    init = inspect.signature(case.cls.__init__).parameters
    changed = case.params(data)  # every one differs from its default
    assert top_level_names(text) == [name for name in init if name in changed]
    required = [name for name, p in init.items() if p.default is inspect.Parameter.empty]
    required.remove("self")
    plain = case.cls(**{name: getattr(est, name) for name in required})
    assert top_level_names(repr(plain)) == required
    assert repr(clone(est)) == text
