from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from behavior_hmm.data import Dataset
from behavior_hmm.errors import ConfigError, DatasetError, ModelFileError
from behavior_hmm.models import CBLM, SBLM
from behavior_hmm.teach import collect

ANGLES = [float(a) for a in range(-160, 181, 40)]
DISTANCES = [0.2, 0.5, 0.8]


@pytest.fixture(scope="module")
def components(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    d = tmp_path_factory.mktemp("components")
    turn = SBLM(inputs=("angle",), epochs=60).fit(
        collect("turn", [{"angle": a} for a in range(-170, 181, 20)], sim="kinematic")
    )
    approach = SBLM(inputs=("distance", "angle"), epochs=60).fit(
        collect("approach", [{"distance": x} for x in np.arange(0.1, 1.01, 0.1)], sim="kinematic")
    )
    turn.save(d / "turn.bhmm")
    approach.save(d / "approach.bhmm")
    return {
        "dir": d,
        "turn": SBLM.load(d / "turn.bhmm"),
        "approach": SBLM.load(d / "approach.bhmm"),
    }


@pytest.fixture(scope="module")
def complex_data() -> Dataset:
    starts = [{"angle": a, "distance": x} for a in ANGLES for x in DISTANCES]
    starts += [{"angle": 0.0, "distance": x} for x in DISTANCES]
    starts += [{"angle": a, "distance": 0.0} for a in ANGLES]
    return collect("turn-approach", starts, sim="kinematic")


@pytest.fixture(scope="module")
def cblm(components: dict[str, Any], complex_data: Dataset) -> CBLM:
    return CBLM([components["turn"], components["approach"]]).fit(complex_data)


def test_fit_learns_between_components(cblm: CBLM) -> None:
    assert cblm.names_ == ["turn", "approach"]
    assert cblm.hmm_.n_states_ == 2
    assert cblm.observations_.n_categories_ > 2
    # in the demonstrations turn is followed by approach, never the reverse
    a = np.exp(cblm.hmm_.log_A_)
    assert a[0, 1] > 0 and a[1, 0] == 0


def test_components_are_not_modified(
    components: dict[str, Any], cblm: CBLM, tmp_path: Path, kinematic_env: Any
) -> None:
    folder = components["dir"]
    before = {n: (folder / f"{n}.bhmm").read_bytes() for n in ("turn", "approach")}
    cblm.generate(kinematic_env, start={"angle": 70.0, "distance": 0.4}, seed=0, max_steps=300)
    cblm.save(tmp_path / "ta.bhmm")
    loaded = CBLM.load(tmp_path / "ta.bhmm")
    for name, model in zip(("turn", "approach"), cblm.components_, strict=True):
        model.save(tmp_path / f"{name}.again.bhmm")
        assert (tmp_path / f"{name}.again.bhmm").read_bytes() == before[name]
        assert (folder / f"{name}.bhmm").read_bytes() == before[name]
    for name, model in zip(("turn", "approach"), loaded.components_, strict=True):
        model.save(tmp_path / f"{name}.loaded.bhmm")
        assert (tmp_path / f"{name}.loaded.bhmm").read_bytes() == before[name]


def test_save_load_gives_identical_trace(cblm: CBLM, tmp_path: Path, kinematic_env: Any) -> None:
    cblm.save(tmp_path / "ta.bhmm")
    loaded = CBLM.load(tmp_path / "ta.bhmm")
    start = {"angle": -60.0, "distance": 0.5}
    a = cblm.generate(kinematic_env, start=start, seed=2, max_steps=400)
    b = loaded.generate(kinematic_env, start=start, seed=2, max_steps=400)
    np.testing.assert_array_equal(a.command_array, b.command_array)
    assert a.component == b.component


def test_angle_zero_runs_approach_only(cblm: CBLM, kinematic_env: Any) -> None:
    trace = cblm.generate(kinematic_env, start={"angle": 0.0, "distance": 0.6}, seed=0)
    assert trace.goal_reached
    # turn is skipped: approach runs from the first step until the object is reached
    # (a short corrective turn may follow if the approach drifted off the bearing)
    distance = trace.reading_array[:, 0]
    first_turn = trace.component.index("turn") if "turn" in trace.component else len(trace)
    assert set(trace.component[:first_turn]) == {"approach"}
    assert distance[first_turn - 1] <= 0.02


def test_distance_zero_runs_turn_only(cblm: CBLM, kinematic_env: Any) -> None:
    trace = cblm.generate(kinematic_env, start={"angle": 120.0, "distance": 0.0}, seed=0)
    assert set(trace.component[:-1]) == {"turn"}


@pytest.fixture(scope="module")
def nested(cblm: CBLM, complex_data: Dataset) -> CBLM:
    """A higher CBLM whose only component is the turn-approach CBLM (tagged accordingly)."""
    tagged = Dataset.from_episodes(
        [{**ep.to_dict(), "behavior": "turn-approach"} for ep in complex_data.episodes()],
        metadata={"behavior": "reach"},
    )
    return CBLM([cblm]).fit(tagged)


def test_a_nested_complex_component_without_a_plan_is_skipped_not_restarted_elsewhere(
    nested: CBLM, cblm: CBLM
) -> None:
    """Run alone, a CBLM whose start category has no plan to its goal starts from the
    best-matching category that has one; run as a component it raises instead, so that
    its parent skips it and its own plan picks the next component (a runner-up start
    describes another place: nested position from 0 m started 0.2 m away and never
    retreated)."""
    from types import SimpleNamespace

    from behavior_hmm.errors import UnreachableGoalError

    goal = {"distance": 0.4, "angle": 0.0}
    alone = cblm.policy(goal)
    alone.reset()
    child = nested.policy(None)._children[0]
    child.renew(goal, 1.0)
    child.reset()
    plannable = cblm.hmm_.plannable_from(alone.goal_candidates)
    dead, live = np.flatnonzero(~plannable), np.flatnonzero(plannable)
    mismatch = np.ones(cblm.hmm_.n_observations_)
    mismatch[dead[0]], mismatch[live[0]] = 0.01, 0.02
    alone._live = child._live = SimpleNamespace(mismatch=mismatch)
    assert alone._plannable(int(dead[0])) == live[0]
    with pytest.raises(UnreachableGoalError):
        child._plannable(int(dead[0]))


def test_nested_cblm_generates(nested: CBLM, kinematic_env: Any) -> None:
    trace = nested.generate(kinematic_env, start={"angle": 80.0, "distance": 0.5}, seed=0)
    assert set(trace.component[:-1]) <= {"turn", "approach"}
    assert "turn" in trace.component
    assert abs(trace.final_observation[2]) < 80.0


def test_bad_inputs(components: dict[str, Any], complex_data: Dataset) -> None:
    with pytest.raises(ConfigError, match="at least one component"):
        CBLM([]).fit(complex_data)
    with pytest.raises(ConfigError, match="distinct"):
        CBLM([components["turn"], components["turn"]]).fit(complex_data)
    with pytest.raises(DatasetError, match="not a component"):
        CBLM([components["turn"]]).fit(complex_data)
    untagged = Dataset.from_episodes(
        [
            {k: v for k, v in ep.to_dict().items() if k != "behavior"}
            for ep in complex_data.episodes()
        ]
    )
    with pytest.raises(DatasetError, match="behavior"):
        CBLM([components["turn"], components["approach"]]).fit(untagged)


def test_sblm_file_is_not_a_cblm(components: dict[str, Any]) -> None:
    with pytest.raises(ModelFileError, match="not a CBLM"):
        CBLM.load(components["dir"] / "turn.bhmm")


def test_push_during_approach_brings_turn_back(cblm: CBLM, kinematic_env: Any) -> None:
    start = {"angle": 60.0, "distance": 0.7}
    plain = cblm.generate(kinematic_env, start=start, seed=0)
    first_approach = plain.component.index("approach")
    push_step = first_approach + 60  # well into the approach
    pushed = cblm.generate(
        kinematic_env, start=start, seed=0, pushes=[{"step": push_step, "angle": 50.0}]
    )
    after = pushed.component[push_step + 1 :]
    # the complex level re-plans: the bearing is off again, so turn runs again
    assert "turn" in after
    assert pushed.goal_reached
    assert abs(pushed.final_observation[2]) <= 3.0


def test_cli_trains_and_runs_a_complex_model(
    components: dict[str, Any], complex_data: Dataset, tmp_path: Path
) -> None:
    from typer.testing import CliRunner

    from behavior_hmm import data
    from behavior_hmm.cli import app

    data.write(complex_data, tmp_path / "ta.parquet")
    runner = CliRunner()
    folder = components["dir"]
    before = {n: (folder / f"{n}.bhmm").read_bytes() for n in ("turn", "approach")}
    res = runner.invoke(
        app,
        ["train", "complex", str(tmp_path / "ta.parquet"), "--component", str(folder / "turn.bhmm"),
         "--component", str(folder / "approach.bhmm"), "--inputs", "distance,angle",
         "-o", str(tmp_path / "ta.bhmm")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    res = runner.invoke(
        app,
        ["generate", str(tmp_path / "ta.bhmm"), "--start", "angle=70,distance=0.4",
         "--sim", "kinematic", "-o", str(tmp_path / "run.parquet")],
    )  # fmt: skip
    assert res.exit_code in (0, 1), res.output
    assert (tmp_path / "run.parquet").exists()
    starts = tmp_path / "starts.csv"
    starts.write_text("angle,distance,goal_distance\n50,0.6,0.0\n")
    res = runner.invoke(
        app,
        ["evaluate", str(tmp_path / "ta.bhmm"), "--starts", str(starts), "--sim", "kinematic",
         "--json", str(tmp_path / "eval.json")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    for name in ("turn", "approach"):
        assert (folder / f"{name}.bhmm").read_bytes() == before[name]


@pytest.mark.parametrize("angle", [8.0, -10.0, 14.0])
def test_a_start_off_the_bearing_turns_before_approaching(
    cblm: CBLM, kinematic_env: Any, angle: float
) -> None:
    # a still window a few degrees off can look like an aligned start to the categories;
    # the turn must still come first, since nothing in the demonstrations turns after
    # approaching
    trace = cblm.generate(kinematic_env, start={"angle": angle, "distance": 0.3}, seed=0)
    assert trace.component[0] == "turn"
    assert trace.goal_reached


def _count_calls(monkeypatch: pytest.MonkeyPatch, name: str) -> list[int]:
    """Count calls of ComplexController.<name> (still running the original)."""
    from behavior_hmm.models._complex_policy import ComplexPolicy as ComplexController

    calls = [0]
    original = getattr(ComplexController, name)

    def spy(self: Any, *args: Any, **kwargs: Any) -> Any:
        calls[0] += 1
        return original(self, *args, **kwargs)

    monkeypatch.setattr(ComplexController, name, spy)
    return calls


def test_preemption_is_switched_by_its_parameter(
    cblm: CBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    calls = _count_calls(monkeypatch, "_uncovered")
    start = {"angle": 8.0, "distance": 0.3}
    on = cblm.generate(kinematic_env, start=start, seed=0)
    assert calls[0] > 0 and on.component[0] == "turn"
    calls[0] = 0
    # a runtime parameter: read when the controller is made, the fitted tables stay
    monkeypatch.setattr(cblm, "preempt_uncovered", False)
    cblm.generate(kinematic_env, start=start, seed=0)
    assert calls[0] == 0


def test_a_preempting_component_that_cannot_start_leaves_the_gap_to_the_plan(
    cblm: CBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    # From 8 deg off, turn pre-empts the planned approach (the test above). A component
    # that cannot start (its own plan unreachable, as a nested turn & approach asked to
    # back away) used to be tried again every cycle while the robot stood still until
    # the step limit; now the plan runs instead.
    from behavior_hmm.errors import UnreachableGoalError
    from behavior_hmm.models._policy import SimplePolicy

    turn = cblm.components_[0]
    original = SimplePolicy.step

    def step(self: Any, reading: Any) -> Any:
        if self.model is turn:
            raise UnreachableGoalError("turn: no plan from here")
        return original(self, reading)

    monkeypatch.setattr(SimplePolicy, "step", step)
    trace = cblm.generate(kinematic_env, start={"angle": 8.0, "distance": 0.3}, seed=0)
    assert "approach" in trace.component
    assert trace.channel("distance")[-1] < 0.1  # it drove to the object


def test_thesis_cblm_switches_at_once_and_never_repairs(
    cblm: CBLM, complex_data: Dataset, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    thesis = CBLM.from_preset("thesis", components=cblm.components_).fit(complex_data)
    assert thesis.observation_vigilance == 0.95 and thesis.hmm_.counting == "changes"
    repairs = _count_calls(monkeypatch, "_repair")
    uncovered = _count_calls(monkeypatch, "_uncovered")
    for angle, distance in ((60.0, 0.7), (8.0, 0.3), (-120.0, 0.5)):
        trace = thesis.generate(kinematic_env, start={"angle": angle, "distance": distance})
        assert trace.component[0] in ("turn", "approach")
    assert repairs[0] == 0 and uncovered[0] == 0


def test_cli_trains_the_thesis_cblm(
    components: dict[str, Any], complex_data: Dataset, tmp_path: Path
) -> None:
    from typer.testing import CliRunner

    from behavior_hmm import data
    from behavior_hmm.cli import app

    data.write(complex_data, tmp_path / "ta.parquet")
    folder = components["dir"]
    runner = CliRunner()
    res = runner.invoke(
        app,
        ["train", "complex", str(tmp_path / "ta.parquet"), "--component", str(folder / "turn.bhmm"),
         "--component", str(folder / "approach.bhmm"), "--preset", "thesis",
         "--set", "switch_cycles=3", "-o", str(tmp_path / "ta.bhmm")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert "preset thesis + switch_cycles=3" in res.output
    model = CBLM.load(tmp_path / "ta.bhmm")
    assert (model.repair, model.preempt_uncovered, model.start_alternatives) == (False, False, 0)
    assert model.switch_cycles == 3 and model.hmm_.counting == "changes"
    res = runner.invoke(app, ["inspect", str(tmp_path / "ta.bhmm")])
    assert res.exit_code == 0, res.output
    assert "preset: thesis + switch_cycles=3" in res.output
    assert "components: turn, approach" in res.output


def test_components_leave_the_start_check_to_the_complex_behavior(cblm: CBLM) -> None:
    # a component starts once the complex level has found its goal missed: it does not
    # hold still to confirm a goal at its first reading (tests/models/test_start_confirmation.py)
    policy = cblm.policy({"angle": 0.0, "distance": 0.0})
    children = list(policy._children.values())
    assert children and all(child.start_confirm_cycles == 0 for child in children)
    assert cblm.components_[0].policy({"angle": 0.0}).start_confirm_cycles > 0


def test_an_approach_the_plan_leaves_out_runs_after_the_turn(
    cblm: CBLM, kinematic_env: Any
) -> None:
    # 110 deg off and 3 cm behind the goal's distance, the plan holds only "turn"; the
    # approach it leaves out used to pre-empt it, and from 110 deg off it circled until
    # the step limit. In the demonstrations approach follows turn: it runs after it.
    goal = {"angle": 0.0, "distance": 0.47}
    trace = cblm.generate(kinematic_env, start={"angle": -110.0, "distance": 0.5}, goal=goal)
    assert trace.component[0] == "turn"
    assert trace.goal_reached


def test_a_nested_cblm_stops_as_softly_as_its_components(
    components: dict[str, Any], nested: CBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    # the outer level let its component (itself complex) brake into the goal only when
    # that component was simple: a nested run stopped from cruise speed in one cycle
    goal = {"angle": 0.0, "distance": 0.3}
    # the limit is on the commands the behavior asks for: the wheel calibration divides
    # them by gains that move (by well under 1 %) as they are measured
    monkeypatch.setattr(nested, "wheel_calibration", False)
    trace = nested.generate(kinematic_env, start={"angle": 0.0, "distance": 0.8}, goal=goal)
    commands = np.asarray(trace.commands)
    approach = components["approach"]
    rate = approach.command_rate_limit * approach.delta_scale_ * approach.command_scale_
    assert trace.goal_reached
    assert np.abs(np.diff(commands, axis=0)).max() <= rate * 1.001


def test_an_intermediate_goal_never_sends_the_robot_away_from_the_goal(
    cblm: CBLM, monkeypatch: pytest.MonkeyPatch
) -> None:
    from behavior_hmm.models._policy import make_policy

    policy = make_policy(cblm, {"angle": 0.0, "distance": 0.63})
    here = {"angle": 30.0, "distance": 0.49}
    # a prototype 0.39 m (behind the robot, seen from the goal) keeps the current 0.49 m
    assert policy._on_the_way({"angle": 0.0, "distance": 0.39}, here)["distance"] == 0.49
    # one on the way stays; the angle is never snapped (its sign is no direction)
    assert policy._on_the_way({"angle": 5.0, "distance": 0.55}, here) == {
        "angle": 5.0,
        "distance": 0.55,
    }
    # thesis (forward_goals off): the prototype as it is
    monkeypatch.setattr(cblm, "forward_goals", False)
    policy = make_policy(cblm, {"angle": 0.0, "distance": 0.63})
    assert policy._on_the_way({"angle": 0.0, "distance": 0.39}, here)["distance"] == 0.39


def test_a_cycle_without_a_component_slows_down_instead_of_stopping_dead(
    components: dict[str, Any], cblm: CBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    # a component that cannot go on in one cycle (its plan unreachable) used to leave
    # the wheels at zero for that cycle, from cruise speed
    from behavior_hmm.errors import UnreachableGoalError
    from behavior_hmm.models._policy import SimplePolicy

    approach = components["approach"]
    original = SimplePolicy.step
    calls = [0]

    def step(self: Any, reading: Any) -> Any:
        if self.model is approach:
            calls[0] += 1
            if calls[0] == 40:
                raise UnreachableGoalError("approach: no plan from here")
        return original(self, reading)

    monkeypatch.setattr(SimplePolicy, "step", step)
    monkeypatch.setattr(cblm, "wheel_calibration", False)  # the commands asked (above)
    trace = cblm.generate(kinematic_env, start={"angle": 0.0, "distance": 0.8}, seed=0)
    assert calls[0] > 40
    rates = [
        approach.command_rate_limit * approach.delta_scale_ * approach.command_scale_,
        cblm.command_rate_limit * cblm.delta_scale_,
    ]
    assert np.abs(np.diff(np.asarray(trace.commands), axis=0)).max() <= max(rates) * 1.001


def test_the_handover_pause_is_the_teachers_rest_around_a_switch() -> None:
    from behavior_hmm.models._cblm import _handover_cycles

    moving, still = [1.0, -1.0], [0.001, 0.0]
    # episode 1: 2 slow rows before its switch, 1 after; episode 2: 4 before, 2 after
    first = [moving] * 3 + [still] * 2 + [still] + [moving] * 2
    second = [moving] + [still] * 4 + [still] * 2 + [moving]
    commands = np.array(first + second)
    states = np.array([0] * 5 + [1] * 3 + [0] * 5 + [1] * 3)
    lengths = np.array([8, 8])
    assert _handover_cycles(commands, states, lengths, scale=1.0) == 4  # median of 3 and 6
    # no switch in the demonstrations: no pause; a switch between episodes is none
    assert _handover_cycles(commands, np.array([0] * 8 + [1] * 8), lengths, scale=1.0) == 0


def test_a_component_that_ends_at_rest_hands_over_after_the_teachers_pause(
    cblm: CBLM, kinematic_env: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert cblm.handover_cycles_ > 0  # the kinematic teacher settles each component too

    def rest_before_approach() -> int:
        trace = cblm.generate(kinematic_env, start={"angle": 90.0, "distance": 0.5}, seed=0)
        first = trace.component.index("approach")
        still = ~np.any(np.asarray(trace.commands[:first]), axis=1)
        return int(np.argmin(still[::-1])) if not still.all() else first

    assert rest_before_approach() >= cblm.handover_cycles_
    monkeypatch.setattr(cblm, "handover_pause", False)  # thesis: the next one at once
    assert rest_before_approach() < cblm.handover_cycles_


def test_a_saved_cblm_keeps_its_handover_pause(cblm: CBLM, tmp_path: Path) -> None:
    cblm.save(tmp_path / "ta.bhmm")
    assert CBLM.load(tmp_path / "ta.bhmm").handover_cycles_ == cblm.handover_cycles_


def test_a_push_after_a_component_finished_runs_it_afresh(cblm: CBLM, kinematic_env: Any) -> None:
    # pushed during the pause after the turn, the turn's goal no longer holds; the turn
    # used to be resumed on its stopped controller, which stopped again every cycle and
    # left the robot standing until the step limit
    start = {"angle": 90.0, "distance": 0.5}  # its turn ends at rest: a pause follows
    plain = cblm.generate(kinematic_env, start=start, seed=0)
    push_step = plain.component.index("approach") - cblm.handover_cycles_ // 2
    pushed = cblm.generate(
        kinematic_env, start=start, seed=0, pushes=[{"step": push_step, "angle": 30.0}]
    )
    assert pushed.reason == "goal" and pushed.goal_reached
    assert "approach" in pushed.component[push_step:]


def test_sblm_and_cblm_share_one_fit_sequence() -> None:
    """One fit (models._base): the kinds supply its steps, not copies of the sequence."""
    from behavior_hmm.models import SBLM
    from behavior_hmm.models._base import LearnedBehavior

    assert SBLM.fit is LearnedBehavior.fit and CBLM.fit is LearnedBehavior.fit
    for kind in (SBLM, CBLM):
        for step in ("_fit_setup", "_fit_rows", "_fit_learn", "_fit_finish"):
            assert getattr(kind, step) is not getattr(LearnedBehavior, step), (kind, step)


def _plan_insists_on(policy: Any, monkeypatch: pytest.MonkeyPatch, component: int) -> None:
    """Make every cycle's plan ask for ``component`` first, toward the complex goal."""
    from types import SimpleNamespace

    exit_category = next(iter(policy._goal_set))
    segment = SimpleNamespace(state=component, exit_observation=exit_category)
    monkeypatch.setattr(policy, "_open_segments", lambda category: [segment])


@pytest.mark.parametrize("skip", [True, False])
def test_a_running_component_is_not_replaced_by_one_whose_goal_already_holds(
    cblm: CBLM, monkeypatch: pytest.MonkeyPatch, skip: bool
) -> None:
    # Under sensor noise the plan can ask for turn while an approach on its bearing runs
    # (the categories flicker where the demonstrations switched). With skip_reached the
    # approach goes on while turn's goal (angle 0 +- 3 deg) holds, and turn replaces it
    # once the bearing is off; without it (the thesis) turn replaces it after the debounce.
    monkeypatch.setattr(cblm, "skip_reached", skip)
    turn, approach = cblm.names_.index("turn"), cblm.names_.index("approach")
    policy = cblm.policy(None)
    reading = {"distance": 0.6, "angle": 1.0, "linear_velocity": 0.0, "angular_velocity": 0.0}
    for _ in range(5):
        policy.step(reading)
    assert policy._active == approach
    _plan_insists_on(policy, monkeypatch, turn)
    for _ in range(4 * cblm.switch_cycles):
        policy.step(reading)
    assert policy._active == (approach if skip else turn)
    if skip:
        off = {**reading, "angle": 10.0}  # turn's goal no longer holds: it replaces approach
        for _ in range(60):
            policy.step(off)
        assert policy._active == turn


def test_the_thesis_preset_replaces_a_running_component_whatever_the_goal() -> None:
    from behavior_hmm.models._presets import preset_params

    assert preset_params("thesis", "CBLM")["skip_reached"] is False
    assert preset_params("default", "CBLM")["skip_reached"] is True


def test_a_component_reopened_after_it_finished_starts_afresh(
    cblm: CBLM, monkeypatch: pytest.MonkeyPatch
) -> None:
    # A turn that hands back where the complex level still reads its goal missed (its
    # own stop rule judges its own readings: 3.08 deg off after a push, MuJoCo) is
    # reopened at once. Its controller has ended; carried on as it was, it reported its
    # goal again every cycle and the robot stood 3.25 deg off until the step limit. It
    # must start afresh (a renewed controller), whether or not the plan names it.
    turn = cblm.names_.index("turn")
    policy = cblm.policy(None)
    _plan_insists_on(policy, monkeypatch, turn)
    off = {"distance": 0.3, "angle": 10.0, "linear_velocity": 0.0, "angular_velocity": 0.0}
    policy.step(off)
    assert policy._active == turn
    child = policy._children[turn]
    real_step = child.step
    monkeypatch.setattr(child, "step", lambda reading: real_step(reading)._replace(done=True))
    monkeypatch.setattr(policy, "_open_segments", lambda category: [])  # nothing planned
    policy.step(off)
    assert turn in policy._finished  # it handed back
    monkeypatch.undo()  # its own step again, and no plan
    monkeypatch.setattr(policy, "_open_segments", lambda category: [])
    renewed: list[dict[str, float]] = []
    real_renew = child.renew
    monkeypatch.setattr(
        child, "renew", lambda goal, tol=1.0: (renewed.append(goal), real_renew(goal, tol))
    )
    for _ in range(cblm.handover_cycles_ + 2):  # the handover pause, then the reopening
        policy.step(off)
    assert renewed == [{"angle": 0.0}]
    assert policy._active == turn and turn not in policy._finished
    assert policy.phase.name == "RUNNING"


def _ends_after(policy: Any, readings: list[dict[str, float]]) -> int | None:
    """The cycle a run fed ``readings`` ends (None: it does not)."""
    policy.reset()
    for i, reading in enumerate(readings):
        if policy.step(reading).done:
            return i
    return None


def test_a_noisy_complex_run_ends_where_the_mean_of_its_readings_puts_it(
    cblm: CBLM, monkeypatch: pytest.MonkeyPatch
) -> None:
    # Noise 0.02 (7.2 deg, 0.024 m a reading) on a robot at rest 5 deg off the bearing at
    # the goal's distance: the filtered bearing falls inside 3 deg about one cycle in five,
    # and a component that finishes there used to end the run. The CBLM confirms its goal
    # on the mean of the raw readings at rest (its components do not: it does, once).
    from behavior_hmm.models import _confirm

    policy = cblm.policy(None)
    assert not any(child.confirm_goal for child in policy._children.values())
    rng = np.random.default_rng(5)
    ended = {True: 0, False: 0}
    for _ in range(10):
        readings = [
            {
                "distance": 0.004 + float(rng.normal(0.0, 0.024)),
                "angle": 5.0 + float(rng.normal(0.0, 7.2)),
                "linear_velocity": 0.0,
                "angular_velocity": 0.0,
            }
            for _ in range(150)
        ]
        for confirm in (True, False):
            quiet = _confirm.QUIET if confirm else np.inf
            with monkeypatch.context() as patch:
                patch.setattr(_confirm, "QUIET", quiet)
                ended[confirm] += _ends_after(cblm.policy(None), readings) is not None
    assert ended[False] >= 6  # 7 of 10 with these draws
    assert ended[True] <= 2  # 1


def test_a_complex_run_confirms_its_goal_only_if_its_components_stop_at_rest(
    cblm: CBLM, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert cblm.policy(None)._confirms
    for component in cblm.components_:  # the thesis preset's components
        monkeypatch.setattr(component, "stop_at_rest", False)
    assert not cblm.policy(None)._confirms


def test_a_nested_complex_component_leaves_confirming_to_its_parent(nested: CBLM) -> None:
    policy = nested.policy(None)
    assert policy._confirms and policy.confirm_goal
    assert all(not child.confirm_goal for child in policy._children.values())


def test_the_component_run_again_resumes_its_onset_clock(ta_model: CBLM) -> None:
    """A component the complex behavior runs again right after it (a repair toward a
    tighter goal) goes on with its generators' onset clock: the robot is where that run
    left it, not at a start. Another component starts its clock at 0."""
    policy = ta_model.policy(None)
    policy.reset()
    # on the bearing, 0.4 m off: the approach runs (open loop: the readings stay)
    reading = {"angle": 0.0, "distance": 0.4, "angular_velocity": 0.0, "linear_velocity": 0.0}
    for _ in range(40):
        out = policy.step(reading)
    assert out.component == "approach"
    active = policy._active
    ran = policy._child.onset_cycles
    assert ran > 20
    goal = dict(policy._child.goal)
    policy._start(active, goal, reading, out.observation, False, renew=True, tolerance=0.5)
    assert policy._child.onset_cycles == ran + 1  # one more cycle, from where it was
    other = next(k for k in policy._children if k != active)
    other_goal = dict(ta_model.components_[other].default_goal_)
    policy._start(other, other_goal, reading, out.observation, False, renew=True)
    assert policy._child.onset_cycles <= 1  # a start


def test_no_pause_after_a_component_that_ran_on_the_noise(ta_model: CBLM) -> None:
    """On noisy readings a component whose commands moved none of its goal channels by
    their tolerance hands over without the teacher's pause; one that moved pauses, and
    on clean readings every component does."""
    reading = {"angle": -60.0, "distance": 0.4, "angular_velocity": 0.0, "linear_velocity": 0.0}

    def pause_after(cycles: int, noisy: bool) -> int:
        policy = ta_model.policy(None)
        policy.reset()
        for _ in range(cycles):
            out = policy.step(reading)  # open loop: the turn runs
        assert out.component == "turn"
        policy._noisy = lambda: noisy  # type: ignore[method-assign]
        policy._hand_back(at_rest=True)
        return int(policy._pause_left)

    handover = int(ta_model.policy(None)._handover)
    assert handover > 0
    assert pause_after(1, noisy=False) == handover
    assert pause_after(1, noisy=True) == 0  # it has not moved the bearing yet
    assert pause_after(80, noisy=True) == handover  # it turned: the teacher's pause


def test_mirror_counts_every_demonstration_and_its_image(ta_model: CBLM) -> None:
    starts = [{"distance": 0.4, "angle": a} for a in (-60.0, 100.0)]
    data = collect("turn-approach", starts, sim="kinematic", seed=0)
    plain = CBLM(list(ta_model.components_), inputs=("distance", "angle")).fit(data)
    both = CBLM(list(ta_model.components_), inputs=("distance", "angle"), mirror=True).fit(data)
    assert plain.hmm_.to_arrays()["start_counts"].sum() == len(data)
    assert both.hmm_.to_arrays()["start_counts"].sum() == 2 * len(data)
    # the image of the turn from -60 deg starts where a turn from +60 deg would
    assert both.observations_.n_categories_ > plain.observations_.n_categories_


def test_an_unplannable_start_takes_the_best_matching_category_a_plan_starts_from(
    ta_model: CBLM,
) -> None:
    """A start window whose best matches (here the first seven) have no plan to the goal
    starts from the best-matching category that has one, however far down the ranking:
    the runner-ups without a plan do not count against ``start_alternatives``."""
    from types import SimpleNamespace

    from behavior_hmm.errors import UnreachableGoalError

    goal = {"distance": 0.4, "angle": 0.0}  # an approach cannot go back from 0.3 m
    policy = ta_model.policy(goal)
    policy.reset()
    plannable = ta_model.hmm_.plannable_from(policy.goal_candidates)
    dead, live = np.flatnonzero(~plannable), np.flatnonzero(plannable)
    assert dead.size >= 7 and live.size >= 2
    mismatch = np.ones(ta_model.hmm_.n_observations_)
    mismatch[dead[:7]] = np.linspace(0.01, 0.07, 7)  # the seven best matches: no plan
    mismatch[live[1]] = 0.08  # then one with a plan, then the rest
    policy._live = SimpleNamespace(mismatch=mismatch)
    assert ta_model.start_alternatives == 5
    assert policy._plannable(int(dead[0])) == live[1]
    policy._alternatives = 0  # the thesis: the goal is unreachable
    with pytest.raises(UnreachableGoalError, match="no observation path"):
        policy._plannable(int(dead[0]))
