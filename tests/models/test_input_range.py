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
from behavior_hmm.teach import collect


def _record_windows(
    model: SBLM, patch: pytest.MonkeyPatch, whole: bool = False
) -> list[tuple[int, np.ndarray]]:
    """Record (primitive, sensor windows) of every generator step from now on (policies
    made after this call); ``whole``: the whole row the network reads (its clock last)."""
    n = None if whole else len(model.inputs_) * int(model.generators_.window)
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


@pytest.fixture(scope="module")
def near_approach() -> SBLM:
    """An approach whose nearest demonstrated start is 0.1 m off the object (kinematic)."""
    starts = [{"distance": d, "angle": 0.0} for d in (0.1, 0.2, 0.3, 0.5)]
    data = collect("approach", starts, sim="kinematic", seed=0)
    return SBLM(inputs=("distance", "angle"), epochs=30, random_state=0).fit(data)


def _start_reads(
    model: SBLM, env: Any, distance: float, monkeypatch: pytest.MonkeyPatch
) -> tuple[Any, list[tuple[int, np.ndarray]]]:
    """A run from rest at ``distance`` and the (primitive, row) its networks read."""
    with monkeypatch.context() as patch:
        seen = _record_windows(model, patch, whole=True)
        run = model.generate(env, start={"distance": distance, "angle": 0.0}, seed=0)
    return run, seen


def _without_start_ranges(model: SBLM) -> SBLM:
    """``model`` as a file written before ``start_range_`` was learned (the rule off)."""
    off = copy.copy(model)
    off.start_range_ = None
    return off


def _held_and_not(
    model: SBLM, readings: list[dict[str, float]], prepare: Callable[[Any], Any] | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """The commands of a fresh policy fed ``readings``, with ``start_range_`` and without;
    ``prepare`` is called on each policy first."""
    runs = []
    for m in (model, _without_start_ranges(model)):
        policy = m.policy({"distance": 0.0, "angle": 0.0})
        if prepare is not None:
            prepare(policy)
        runs.append(np.asarray([policy.step(r).command.copy() for r in readings]))
    return runs[0], runs[1]


def _beyond_start_ups(model: SBLM, reads: list[tuple[int, np.ndarray]]) -> int:
    """Reads of the clock's first cycles whose distance windows lie outside what their
    primitive's rows held by the clock read (``start_range_``)."""
    starts = model.start_range_
    assert starts is not None
    cycles = starts.shape[2] - 1
    window = int(model.generators_.window)
    count = 0
    for p, row in reads:
        k = int(np.rint(row[-1] * cycles))
        lo, hi = starts[p, 0, k]
        if k < cycles and lo <= hi:
            d = row[:window]
            count += bool(np.any((d < lo - 1e-12) | (d > hi + 1e-12)))
    return count


def test_start_ranges_are_learned_per_onset_clock_cycle(near_approach: SBLM) -> None:
    starts = near_approach.start_range_
    assert starts is not None
    assert starts.shape == (near_approach.primitives_.n_categories_, 2, 97, 2)
    # what the rows held by a cycle only widens with the clock
    lo, hi = starts[..., 0], starts[..., 1]
    seen = ~np.isnan(lo)
    assert np.all(np.diff(np.where(seen, lo, 9.0), axis=2) <= 0)
    assert np.all(np.diff(np.where(seen, hi, -9.0), axis=2) >= 0)
    # at cycle 0 the distance of the demonstrated starts only: 0.1 to 0.5 m (normalized
    # over 0..1.2 m to [-1, 1]), with the clock's end everything down to the object
    union = np.nanmin(lo[:, 0, 0]), np.nanmax(hi[:, 0, 0])
    np.testing.assert_allclose(union, [0.1 / 0.6 - 1, 0.5 / 0.6 - 1], atol=1e-3)
    assert np.nanmin(lo[:, 0, -1]) < -0.99


def test_a_start_closer_than_every_demonstrated_start_reads_as_the_nearest(
    near_approach: SBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    """From 2 cm, closer to the object than any demonstration started, the networks read at
    clock 0 a distance none of their rows held so early, and back the robot away first;
    held to the start-ups the rows did hold, the robot backs away less and arrives sooner."""
    off = _without_start_ranges(near_approach)
    plain, plain_reads = _start_reads(off, kinematic_env, 0.02, monkeypatch)
    held, held_reads = _start_reads(near_approach, kinematic_env, 0.02, monkeypatch)
    assert _beyond_start_ups(near_approach, plain_reads) > 20
    assert _beyond_start_ups(near_approach, held_reads) == 0
    assert held.goal_reached and plain.goal_reached
    backed = [float(run.channel("distance")[:200].max()) - 0.02 for run in (plain, held)]
    assert backed[1] < 0.5 * backed[0]
    assert len(held) < len(plain)


def test_a_start_among_the_demonstrated_ones_is_read_as_it_is(
    near_approach: SBLM, kinematic_env: Any
) -> None:
    off = _without_start_ranges(near_approach)
    for distance in (0.15, 0.4, 0.095):  # 0.095: within the 1 cm goal tolerance of 0.1
        start = {"distance": distance, "angle": 0.0}
        a = near_approach.generate(kinematic_env, start=start, seed=0)
        b = off.generate(kinematic_env, start=start, seed=0)
        np.testing.assert_array_equal(np.asarray(a.commands), np.asarray(b.commands))


def test_a_run_carried_on_at_speed_is_read_as_it_is(near_approach: SBLM) -> None:
    reading = {"distance": 0.02, "angle": 0.0, "linear_velocity": 0.0, "angular_velocity": 0.0}
    from_rest, from_rest_off = _held_and_not(near_approach, [reading] * 30)
    # a complex behavior hands over at speed
    at_speed, at_speed_off = _held_and_not(
        near_approach, [reading] * 30, lambda policy: policy.carry(np.array([2.0, 2.0]))
    )
    assert not np.array_equal(from_rest, from_rest_off)
    np.testing.assert_array_equal(at_speed, at_speed_off)


def test_a_resumed_onset_clock_is_read_as_it_is(near_approach: SBLM) -> None:
    """A component a complex behavior resumes where a run of it stopped (2 cm short after
    moving there) goes on as it was: only a run whose clock starts at 0 is held."""
    reading = {"distance": 0.02, "angle": 0.0, "linear_velocity": 0.0, "angular_velocity": 0.0}

    def resumed(policy: Any) -> None:
        policy.reset()
        policy.resume_onset(5)  # early in the clock, where a fresh start would be held

    np.testing.assert_array_equal(*_held_and_not(near_approach, [reading] * 30, resumed))


def test_start_ranges_are_saved_and_grown(
    half_and_grown: tuple[SBLM, SBLM],
    saved_and_grown: Callable[[str], tuple[np.ndarray, np.ndarray]],
) -> None:
    before, after = saved_and_grown("start_range_")
    grown = half_and_grown[1]
    assert after.shape[0] == grown.primitives_.n_categories_
    # an old primitive's network only gains rows: at every clock its range can only widen
    kept = before.shape[0]
    had = ~np.isnan(before[..., 0])
    assert np.all(~np.isnan(after[:kept, ..., 0])[had])
    assert np.all(after[:kept, ..., 0][had] <= before[..., 0][had])
    assert np.all(after[:kept, ..., 1][had] >= before[..., 1][had])


def test_only_a_start_beyond_the_start_ups_is_held(near_approach: SBLM) -> None:
    """A run that started among the demonstrated starts reads what follows as it is, even
    a reading none of the start-ups held by that clock (pushed to 2 cm in its first
    cycles): only where the run began decides."""
    moved = {"distance": 0.3, "angle": 0.0, "linear_velocity": 0.0, "angular_velocity": 0.0}
    pushed = dict(moved, distance=0.02)
    np.testing.assert_array_equal(*_held_and_not(near_approach, [moved] * 3 + [pushed] * 40))
