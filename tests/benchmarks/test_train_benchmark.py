"""``bench train``'s option times: every option fitted with its parameters, ratios in the
same run."""

from __future__ import annotations

from typing import Any

import pytest

from behavior_hmm.benchmarks import train
from behavior_hmm.teach import collect


def test_option_times_fit_each_option_and_divide_by_the_default(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    from behavior_hmm import models

    fitted: list[dict[str, Any]] = []

    class Spy(models.SBLM):
        def fit(self, *args: Any, **kwargs: Any) -> Any:
            params = self.get_params()
            fitted.append({"mirror": params["mirror"], "init": params["generator_init"]})
            return super().fit(*args, **kwargs)

    monkeypatch.setattr(models, "SBLM", Spy)
    data = collect("turn", [{"angle": 60.0}, {"angle": -90.0}], sim="kinematic", seed=0)
    out = train.option_times({"turn": (data, ("angle",))}, repeats=1)
    assert fitted == [
        {"mirror": False, "init": "random"},
        {"mirror": True, "init": "random"},
        {"mirror": False, "init": "shared"},
        {"mirror": True, "init": "shared"},
    ]
    row = out["turn"]
    assert set(row) == {f"{name}_s" for name in train.OPTIONS} | {
        f"{name}_over_default" for name in train.OPTIONS if name != "default"
    }
    for name in ("mirror", "shared", "mirror+shared"):
        assert row[f"{name}_over_default"] == row[f"{name}_s"] / row["default_s"]
