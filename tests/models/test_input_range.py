"""``SBLM(input_range=True)``: each primitive's network reads its sensor windows clipped
to the range its own training rows held."""

from __future__ import annotations

import copy
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest

from behavior_hmm.generators import _motion
from behavior_hmm.models import SBLM


def _record_windows(model: SBLM, patch: pytest.MonkeyPatch) -> list[tuple[int, np.ndarray]]:
    """Record (primitive, sensor windows) of every generator step from now on (policies
    made after this call)."""
    n = len(model.inputs_) * int(model.generators_.window)
    seen: list[tuple[int, np.ndarray]] = []
    original = _motion.MotionGenerators.predict_one

    def recording(self: Any, x: np.ndarray, primitive: int) -> np.ndarray:
        seen.append((int(primitive), np.array(x[:n])))
        return original(self, x, primitive)

    patch.setattr(_motion.MotionGenerators, "predict_one", recording)
    return seen


def _windows_read(
    model: SBLM, env: Any, starts: list[dict[str, float]], monkeypatch: pytest.MonkeyPatch
) -> list[tuple[int, np.ndarray]]:
    """(primitive, sensor windows) of every generator step of runs from ``starts``."""
    with monkeypatch.context() as patch:
        seen = _record_windows(model, patch)
        for start in starts:
            model.generate(env, start=start, seed=0)
    return seen


def _outside(ranges: np.ndarray, reads: list[tuple[int, np.ndarray]]) -> int:
    """How many reads hold a window value outside their primitive's range."""
    return sum(
        bool(np.any((x < ranges[p, 0] - 1e-12) | (x > ranges[p, 1] + 1e-12))) for p, x in reads
    )


def test_ranges_are_learned_from_the_training_rows(turn_model: SBLM) -> None:
    ranges = turn_model.input_range_
    assert ranges is not None
    columns = len(turn_model.inputs_) * int(turn_model.generators_.window)
    assert ranges.shape == (turn_model.primitives_.n_categories_, 2, columns)
    assert np.all(ranges[:, 0] <= ranges[:, 1])
    # each primitive holds a part of the turn: narrower than all the rows together
    overall = ranges[:, 1].max(axis=0) - ranges[:, 0].min(axis=0)
    assert np.all(ranges[:, 1] - ranges[:, 0] <= overall + 1e-12)
    assert np.median(ranges[:, 1, 0] - ranges[:, 0, 0]) < 0.5 * overall[0]


def test_a_start_beyond_every_row_reads_as_its_primitive_was_shown(
    turn_model: SBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    ranges = turn_model.input_range_
    assert ranges is not None
    start = {"angle": 179.0, "distance": 0.5}
    assert 179.0 / 180.0 > ranges[:, 1].max()  # beyond every row (angles normalized /180)
    off = copy.copy(turn_model)
    off.input_range = False
    plain = _windows_read(off, kinematic_env, [start], monkeypatch)
    # the readings as they are: the first network reads a bearing none of its rows held
    assert _outside(ranges, plain[:1]) == 1
    view = copy.copy(turn_model)
    view.input_range = True
    held = _windows_read(view, kinematic_env, [start], monkeypatch)
    assert _outside(ranges, held[:1]) == 0
    assert view.generate(kinematic_env, start=start, seed=0).goal_reached


def test_a_deviation_after_the_start_stays_visible(
    turn_model: SBLM, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Once the readings have been inside the rows' range the windows are not clipped: a
    bearing that drifts beyond what any row held reaches the network that corrects it."""
    ranges = turn_model.input_range_
    assert ranges is not None
    view = copy.copy(turn_model)
    view.input_range = True
    seen = _record_windows(view, monkeypatch)
    policy = view.policy({"angle": 0.0})
    for angle in [40.0] * 20 + [179.0] * 80:  # inside, then pushed beyond every row
        out = policy.step(
            {"angle": angle, "angular_velocity": 0.0, "distance": 0.5, "linear_velocity": 0.0}
        )
        assert not out.done
    late = [(p, x) for p, x in seen[20:] if x[-1] > ranges[:, 1].max()]
    assert late and _outside(ranges, late) == len(late)


def test_ranges_are_saved_and_grown(
    half_and_grown: tuple[SBLM, SBLM],
    saved_and_grown: Callable[[str], tuple[np.ndarray, np.ndarray]],
) -> None:
    before, after = saved_and_grown("input_range_")
    grown = half_and_grown[1]
    assert after.shape[0] == grown.primitives_.n_categories_
    # an old primitive's network only gains rows: its range can only widen
    kept = before.shape[0]
    assert np.all(after[:kept, 0] <= before[:, 0]) and np.all(after[:kept, 1] >= before[:, 1])
    assert np.all(after[:, 0] <= after[:, 1])


def test_a_model_without_ranges_stays_without_them_when_grown(turn_data: Any) -> None:
    """A model file written before ``input_range_`` was learned: its old primitives' rows
    are gone, so an update cannot know their ranges and learns none."""
    n = len(turn_data)
    model = SBLM(inputs=("angle",), epochs=2, random_state=0).fit(
        turn_data.subset(np.arange(n // 2))
    )
    model.input_range_ = None
    grown = model.partial_fit(turn_data.subset(np.arange(n // 2, n)))
    assert grown.input_range_ is None
