"""Hierarchically integrated CobART networks (thesis §3.2.1) on tiny synthetic data."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from cobart_testing import turn_dataset

from behavior_hmm.cobart import CobART, HierarchicalCobART
from behavior_hmm.errors import ConfigError, NotFittedError


def _combos(n: int = 20) -> tuple[np.ndarray, list[int]]:
    """Four constant episodes: robot in {-0.5, 0.5} x object in {-0.5, 0.5}."""
    eps = [np.tile([r, o], (n, 1)) for r in (-0.5, 0.5) for o in (-0.5, 0.5)]
    return np.concatenate(eps), [n] * 4


def _net(**kw: Any) -> HierarchicalCobART:
    args: dict[str, Any] = {
        "layers": {"robot": CobART(window=3), "object": CobART(window=3)},
        "channels": {"robot": [0], "object": [1]},
    }
    return HierarchicalCobART(**{**args, **kw})


def test_relation_categorizes_combinations() -> None:
    x, lengths = _combos()
    h = _net().fit(x, lengths)
    assert h.layers_["robot"].n_categories_ == 2
    assert h.layers_["object"].n_categories_ == 2
    assert h.n_categories_ == 4
    per_episode = h.labels_.reshape(4, -1)
    assert all(len(set(row)) == 1 for row in per_episode.tolist())
    assert len(set(per_episode[:, 0].tolist())) == 4
    np.testing.assert_array_equal(h.predict(x, lengths), h.labels_)


def test_layer_weights_decide_what_the_relation_sees() -> None:
    x, lengths = _combos()
    h = _net(weights={"robot": 1.0, "object": 0.0}).fit(x, lengths)
    assert h.n_categories_ == 2  # the object no longer matters
    assert h.weights_ == {"robot": 1.0, "object": 0.0}
    h = _net(weights={"robot": 3.0, "object": 1.0}).fit(x, lengths)
    assert h.weights_ == {"robot": 0.75, "object": 0.25}


def test_relation_prototypes_are_stacks_of_layer_prototypes() -> None:
    x, lengths = _combos()
    h = _net().fit(x, lengths)
    rel = h.relation_prototypes_
    assert rel["robot"].shape == (4, 3, 1) and rel["object"].shape == (4, 3, 1)
    for name in ("robot", "object"):
        layer = h.layers_[name].prototypes_
        for proto in rel[name]:
            assert np.min(np.abs(layer - proto).max(axis=(1, 2))) < 1e-12
    assert h.relation_counts_.sum() == len(x)


def test_associations_count_co_wins() -> None:
    x, lengths = _combos()
    h = _net().fit(x, lengths)
    for name in ("robot", "object"):
        table = h.associations_[name]
        assert table.shape == (h.n_categories_, h.layers_[name].n_categories_)
        assert table.sum() == len(x)
        assert np.all((table > 0).sum(axis=1) == 1)  # constant data: one partner each


def test_without_feedback_layers_match_standalone_networks() -> None:
    x, lengths = turn_dataset(two_channels=True)
    layers = {"angle": CobART.motion_primitives(), "velocity": CobART.observations()}
    h = HierarchicalCobART(layers=layers, channels={"angle": [0], "velocity": [1]}, w_f=0.0).fit(
        x, lengths
    )
    for name, col in (("angle", 0), ("velocity", 1)):
        alone = type(layers[name])(**layers[name].get_params()).fit(x[:, [col]], lengths)
        np.testing.assert_array_equal(h.layers_[name].labels_, alone.labels_)
        np.testing.assert_allclose(h.layers_[name].prototypes_, alone.prototypes_, atol=1e-12)
    assert layers["angle"].__dict__.keys() == CobART().__dict__.keys()  # inputs not fitted


def test_feedback_breaks_ties_toward_the_associated_category() -> None:
    layer = {"a": 1.0, "rho": 0.85, "window": 1}
    train = np.array([[0.0, -0.5]] * 5 + [[0.25, 0.5]] * 5)
    test = np.array([[0.25, 0.5], [0.125, 0.5]])  # 0.125: equally close to 0.0 and 0.25

    def fitted(w_f: float) -> HierarchicalCobART:
        return HierarchicalCobART(
            layers={"robot": CobART(**layer), "object": CobART(**layer)},
            channels={"robot": [0], "object": [1]},
            w_f=w_f,
            relation=CobART(rho=0.9),
        ).fit(train, [5, 5])

    plain = fitted(0.0).predict_all(test)
    assert plain["robot"].tolist() == [1, 0]  # tie: lowest index
    biased = fitted(0.5).predict_all(test)
    assert biased["robot"].tolist() == [1, 1]  # the relation expects robot category 1


def test_feedback_never_accepts_a_poor_match() -> None:
    x, lengths = _combos()
    plain = _net(w_f=0.0).fit(x, lengths)
    strong = _net(w_f=1.0).fit(x, lengths)
    for name in ("robot", "object"):
        assert strong.layers_[name].n_categories_ == plain.layers_[name].n_categories_


@pytest.mark.parametrize(
    "kw",
    [
        {"channels": {"robot": [0], "object": [5]}},
        {"channels": {"robot": [0], "object": []}},
        {"channels": {"robot": [0]}},
        {"weights": {"robot": -1.0, "object": 1.0}},
        {"weights": {"robot": 0.0, "object": 0.0}},
        {"weights": {"robot": 1.0}},
        {"w_f": 1.5},
        {
            "layers": {"robot": CobART(), "relation": CobART()},
            "channels": {"robot": [0], "relation": [1]},
        },
        {"layers": {"robot": CobART(), "object": "cobart"}},
        {"layers": {}},
        {"relation": "cobart"},
        {"layers": {"robot": CobART(rho=2.0), "object": CobART()}},
    ],
)
def test_bad_configuration(kw: dict[str, Any]) -> None:
    x, lengths = _combos()
    with pytest.raises(ConfigError):
        _net(**kw).fit(x, lengths)


def test_not_fitted_and_params() -> None:
    h = _net(relation=CobART(rho=0.7))
    with pytest.raises(NotFittedError):
        h.predict(np.zeros((5, 2)))
    with pytest.raises(NotFittedError):
        _ = h.n_categories_
    params = h.get_params()
    assert params["relation__rho"] == 0.7 and params["w_f"] == 0.0
    h.set_params(relation__rho=0.8)
    assert h.relation is not None and h.relation.rho == 0.8
