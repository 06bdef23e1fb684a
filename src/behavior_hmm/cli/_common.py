"""What the command modules share: the user-error wrapper, logging, progress bars, the
option types every command spells the same way, and the checks and loaders behind them.

Declared once here, imported by ``data``, ``learn``, ``experiment``, ``bench`` and ``demo``.
"""

from __future__ import annotations

import contextlib
import functools
import inspect
import logging
import math
import re
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Annotated, Any, TypeVar

import typer
from typer.core import TyperGroup
from typer.exceptions import TyperException

from behavior_hmm.data._channels import ARENA_MAX_DISTANCE
from behavior_hmm.errors import BehaviorHMMError, ConfigError

#: ``-h`` beside ``--help`` on every command (given to every ``typer.Typer``).
CONTEXT_SETTINGS: dict[str, Any] = {"help_option_names": ["-h", "--help"]}

F = TypeVar("F", bound=Callable[..., Any])

# ------------------------------------------------------------------------ logging

#: The command line's logger. INFO lines go to stdout (where the commands have always
#: printed them: "plot: run.png", "results: ..."), DEBUG and WARNING lines to stderr, so
#: that ``--verbose`` never mixes into results on stdout. ``--quiet`` keeps warnings only.
log = logging.getLogger("behavior_hmm.cli")


class _EchoHandler(logging.Handler):
    """Write each record as one line with ``typer.echo`` (stdout or stderr, see ``log``)."""

    def emit(self, record: logging.LogRecord) -> None:
        text = self.format(record)
        if record.levelno < logging.INFO:
            text = f"debug: {text}"
        typer.echo(text, err=record.levelno != logging.INFO)


def _install_handler() -> None:
    if not any(isinstance(h, _EchoHandler) for h in log.handlers):
        log.addHandler(_EchoHandler())
    log.propagate = False  # one line per message, whatever the root logger does
    log.setLevel(logging.INFO)


_install_handler()


def set_verbosity(verbose: bool, quiet: bool) -> None:
    """``--verbose``: DEBUG; ``--quiet``: WARNING only; neither: INFO."""
    if verbose and quiet:
        raise ConfigError("--verbose and --quiet contradict each other; give one")
    log.setLevel(logging.DEBUG if verbose else logging.WARNING if quiet else logging.INFO)


def is_quiet() -> bool:
    """True under ``--quiet``: no progress bars, no info lines."""
    return not log.isEnabledFor(logging.INFO)


# ------------------------------------------------------------------- user errors


def user_errors(func: F) -> F:
    """Turn our errors into one line on stderr and exit code 2 (no traceback)."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except BehaviorHMMError as err:
            typer.echo(f"error: {' '.join(str(err).split())}", err=True)
            raise typer.Exit(code=2) from None
        except BrokenPipeError:  # output piped into e.g. `head`, which has exited: stop quietly
            import os
            import sys

            try:  # keep Python's final flush of stdout from failing again
                os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
            except (OSError, ValueError):
                pass
            raise typer.Exit(code=141) from None
        except OSError as err:  # a path we cannot read or write: the user's to fix
            where = f"{err.filename}: " if err.filename else ""
            typer.echo(f"error: {where}{err.strerror or err}", err=True)
            raise typer.Exit(code=2) from None
        except KeyboardInterrupt as err:  # Ctrl-C, or SIGTERM (main turns it into one)
            from behavior_hmm.cli import interrupt_exit_code

            raise typer.Exit(code=interrupt_exit_code(err)) from None

    return wrapper  # type: ignore[return-value]


# ------------------------------------------------------------ the command line


class CommandLine(TyperGroup):
    """The root group of ``behavior-hmm`` (``typer.Typer(cls=CommandLine)``).

    - every usage error (a wrong-typed value, a missing argument, an unknown option or
      command) is one line ``error: ...`` on stderr with exit code 2: no usage box;
    - every command's help paragraphs are re-flowed (:func:`reflow_help`), so the
      docstrings' hard line breaks never show in ``--help``;
    - an interrupt anywhere in a command is one line (:func:`user_errors` catches those
      inside it), and the command's result counts as complete once it returns
      (:func:`behavior_hmm._atomic.finish_command`).
    """

    def __init__(self, **attrs: Any) -> None:
        super().__init__(**attrs)
        _reflow_tree(self)

    def make_context(
        self, info_name: str | None, args: list[str], parent: Any = None, **extra: Any
    ) -> Any:
        with _one_line_usage_errors():
            return super().make_context(info_name, args, parent=parent, **extra)

    def invoke(self, ctx: Any) -> Any:
        from behavior_hmm._atomic import begin_command, finish_command

        begin_command()
        try:
            with _one_line_usage_errors():
                result = super().invoke(ctx)
        except KeyboardInterrupt as err:  # outside any command's own wrapper
            from behavior_hmm.cli import interrupt_exit_code

            raise typer.Exit(code=interrupt_exit_code(err)) from None
        finish_command()
        return result


@contextlib.contextmanager
def _one_line_usage_errors() -> Iterator[None]:
    """Print a usage error (typer's ``ClickException``) as one ``error: `` line, exit 2."""
    try:
        yield
    except TyperException as err:
        if type(err).__name__ == "NoArgsIsHelpError":  # the help is already printed
            raise
        typer.echo(f"error: {usage_error_line(err)}", err=True)
        raise typer.Exit(code=getattr(err, "exit_code", 2)) from None


#: Words for pydantic's type errors: "'abc' is not a valid integer".
_EXPECTED = {
    "int_parsing": "a valid integer",
    "int_from_float": "a whole number",
    "float_parsing": "a valid number",
    "bool_parsing": "true or false",
    "path_type": "a path",
}


def usage_error_line(err: TyperException) -> str:
    """One line for a usage error, without click's capitals and full stops, e.g.
    ``--seed: 'abc' is not a valid integer`` or ``missing argument BEHAVIOR``."""
    param = getattr(err, "param", None)
    hint = _param_hint(param) if param is not None else None
    explicit = getattr(err, "param_hint", None)
    if explicit is not None:
        hint = explicit if isinstance(explicit, str) else "/".join(explicit)
    name = type(err).__name__
    if name == "NoSuchOption" and getattr(err, "possibilities", None):
        options = " or ".join(sorted(err.possibilities))  # type: ignore[attr-defined]
        return f"{_sentence(err.message)}; did you mean {options}?"
    if name == "MissingParameter":
        kind = getattr(err, "param_type", None) or getattr(param, "param_type_name", "parameter")
        return f"missing {kind} {hint}" if hint else f"missing {kind}"
    if isinstance(err, typer.BadParameter):
        cause: Any = err.__cause__  # typer's values are checked by pydantic
        details = cause.errors() if hasattr(cause, "errors") else None
        if details:
            first = details[0]
            expected = _EXPECTED.get(str(first.get("type")))
            value = first.get("input")
            what = (
                f"{value!r} is not {expected}"
                if expected is not None
                else f"{value!r}: {_sentence(str(first.get('msg', err.message)))}"
            )
        else:
            what = _sentence(err.message)
        return f"{hint}: {what}" if hint else what
    return _sentence(err.format_message())


def _param_hint(param: Any) -> str:
    """``--seed``, ``-o/--out`` or the argument's name in capitals (``BEHAVIOR``)."""
    if getattr(param, "param_type_name", "") == "argument":
        return str(param.name or "").upper()
    opts = [*getattr(param, "opts", ()), *getattr(param, "secondary_opts", ())]
    return "/".join(opts) or str(getattr(param, "name", "") or "")


def _sentence(text: str) -> str:
    """Click's message as our one-line style: one line, lower-case start, no final stop."""
    text = " ".join(text.split()).rstrip(".")
    return text[:1].lower() + text[1:] if text[1:2].islower() else text


# ----------------------------------------------------------------- help text


def reflow_help(text: str | None) -> str | None:
    """A docstring as help text: each paragraph (between blank lines) on one line, so the
    help re-wraps it to the terminal instead of keeping the source's line breaks.

    Left as written: a paragraph starting with click's ``\\b`` marker, one whose later
    lines are indented, bullets (``-``, ``*``, ``•``) or command lines
    (``behavior-hmm ...``, ``$ ...``), and anything after a form feed (``\\f``).
    """
    if not text:
        return text
    body, stop, rest = inspect.cleandoc(text).partition("\f")
    paragraphs = re.split(r"\n[ \t]*\n", body.strip("\n"))
    flowed = [p if _laid_out(p) else " ".join(p.split()) for p in paragraphs]
    return "\n\n".join(flowed) + stop + rest


_LAID_OUT_LINE = re.compile(r"(\s|[-*•] |behavior-hmm |\$ )")


def _laid_out(paragraph: str) -> bool:
    lines = paragraph.split("\n")
    return paragraph.startswith("\b") or any(_LAID_OUT_LINE.match(line) for line in lines[1:])


def _reflow_tree(command: Any) -> None:
    """Re-flow the help of ``command`` and of every command below it."""
    command.help = reflow_help(command.help)
    for sub in getattr(command, "commands", {}).values():
        _reflow_tree(sub)


# ------------------------------------------------------------------ progress bars


def progress() -> Any:
    """A rich progress bar on stdout.

    On a terminal it redraws in place; in a pipe or file it prints its final state
    once, as one plain line, when it stops. Under ``--quiet`` it prints nothing.
    """
    from rich.progress import (
        BarColumn,
        MofNCompleteColumn,
        Progress,
        TextColumn,
        TimeElapsedColumn,
        TimeRemainingColumn,
    )

    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        transient=False,
        disable=is_quiet(),
    )


@contextlib.contextmanager
def spinner(label: str) -> Iterator[None]:
    """A spinner with the elapsed time while a step with no known length runs (training).

    Only on a terminal, and gone when the step ends: in a pipe or a file, and under
    ``--quiet``, it writes nothing at all (unlike :func:`progress`, no final line).
    """
    from rich.console import Console
    from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn

    console = Console()
    shown = Progress(
        SpinnerColumn(),
        TextColumn("[bold]{task.description}"),
        TimeElapsedColumn(),
        console=console,
        transient=True,
        disable=is_quiet() or not console.is_terminal,
    )
    with shown:
        shown.add_task(label, total=None)
        yield


def with_progress(label: str, experiment: Callable[..., dict[str, Any]], **kwargs: Any) -> Any:
    """Run an experiment function under a progress bar (``kwargs`` passed on)."""
    with progress() as bar:
        task = bar.add_task(label, total=None)
        return experiment(progress=lambda d, t: bar.update(task, completed=d, total=t), **kwargs)


def collect_with_progress(
    behavior: str,
    starts: list[dict[str, float]],
    sim: str,
    seed: int,
    noise: float,
    env: Any = None,
    env_name: str | None = None,
    corrections: int = 0,
    correction_noise: float | None = None,
) -> Any:
    """Run the teacher from every start behind a progress bar (one final line when not a TTY)."""
    from behavior_hmm.teach import collect

    with progress() as bar:
        task = bar.add_task(f"collect {behavior} ({env_name or sim})", total=len(starts))

        def report(done: int, total: int) -> None:
            bar.update(task, completed=done, total=total)

        options: dict[str, Any] = {"corrections": corrections}
        if correction_noise is not None:
            options["correction_noise"] = correction_noise
        return collect(
            behavior,
            starts,
            sim=sim,
            seed=seed,
            noise=noise,
            progress=report,
            env=env,
            env_name=env_name,
            **options,
        )


# ------------------------------------------------------------------- option types

#: The simulators ``--sim`` chooses from.
SIMS: tuple[str, ...] = ("mujoco", "kinematic")

#: A folder of results (the experiments); each command gives its own default.
OutFolder = Annotated[Path, typer.Option("-o", "--out", help="Folder for results")]
#: A new Parquet dataset (collect and the imports).
ParquetOut = Annotated[Path, typer.Option("-o", "--out", help="Output Parquet file")]
SimOption = Annotated[
    str, typer.Option(help=f"Simulator backend: {', '.join(SIMS)} (kinematic: faster, no dynamics)")
]
SeedOption = Annotated[int, typer.Option(help="Seed (>= 0) of every random draw")]
NoiseOption = Annotated[
    float,
    typer.Option(
        help="Sensor noise: a standard deviation, as a fraction of each channel's "
        "normalization range (e.g. 0.01: 3.6 deg on the angle, 0.012 m on the distance)"
    ),
]
#: A robot of the user's own (the robot contract, docs/robots.md), in place of --sim.
EnvOption = Annotated[
    str | None,
    typer.Option(
        "--env",
        help="A robot of your own instead of --sim: a registered Gymnasium id, "
        "package.module:factory or path/to/file.py:factory (docs/robots.md)",
    ),
]
EnvKwargsOption = Annotated[
    str | None,
    typer.Option(
        "--env-kwargs", help="JSON object passed to the --env factory, e.g. '{\"mass\": 2}'"
    ),
]
TeacherOption = Annotated[
    str | None,
    typer.Option(
        "--teacher",
        help="Your own teacher instead of ours: path/to/file.py:factory or "
        "package.module:factory, called as factory(env, **kwargs); it offers reset(start, "
        "goal) and step(observation, info) -> (command, done) (docs/robots.md)",
    ),
]
TeacherKwargsOption = Annotated[
    str | None,
    typer.Option("--teacher-kwargs", help="JSON object passed to the --teacher factory"),
]
#: How videos are drawn (``generate --video``, ``evaluate --videos``).
VideoBackendOption = Annotated[
    str,
    typer.Option(
        "--video-backend",
        help="matplotlib (top-down, always works) or mujoco (offscreen 3-D; MUJOCO_GL=egl)",
    ),
]
#: The options that choose model parameters, shared by every command that trains.
PresetOption = Annotated[
    str | None,
    typer.Option(
        help="Model parameters: 'thesis' (the method as published) or 'default' (ours); "
        "default: the config file's 'preset', else default"
    ),
]
ConfigOption = Annotated[
    Path | None,
    typer.Option(
        "--config",
        help="TOML file of model parameters: top-level NAME = VALUE, or \\[sblm] / \\[cblm] tables",
    ),
]
SetOption = Annotated[
    list[str] | None,
    typer.Option(
        "--set",
        help="One model parameter over the preset and config, NAME=VALUE (repeatable), "
        "e.g. --set batch_size=1 --set cblm.repair=false",
    ),
]
JsonOut = Annotated[Path | None, typer.Option("--json", help="Write the results as JSON")]
#: The options that choose who runs batch work (evaluate/_executor.py).
WorkersOption = Annotated[
    int | None,
    typer.Option(
        "--workers",
        help="Local worker processes (default: $BEHAVIOR_HMM_WORKERS, else this machine's cores;"
        " 1: in-process)",
    ),
]
ExecutorOption = Annotated[
    str,
    typer.Option(
        "--executor",
        help="local (processes on this machine) or ray (pip install 'behavior-hmm\\[ray]')",
    ),
]
AddressOption = Annotated[
    str | None,
    typer.Option("--address", help="Ray cluster address for --executor ray (default: local Ray)"),
]
SeedsOption = Annotated[
    int,
    typer.Option(
        "--seeds",
        help="Train K models per row (seeds SEED..SEED+K-1) and report mean ± 95 % interval",
    ),
]


def make_run_executor(executor: str, workers: int | None, address: str | None) -> Any:
    """The executor ``--executor/--workers/--address`` ask for (checked before any work)."""
    from behavior_hmm.evaluate._executor import make_executor

    return make_executor(executor, workers=workers, address=address)


# ------------------------------------------------------------------------- checks


def check_sim(sim: str) -> str:
    """Refuse an unknown ``--sim`` with its choices."""
    if sim not in SIMS:
        raise ConfigError(f"unknown simulator '{sim}'; choose one of {', '.join(SIMS)}")
    return sim


def check_seed(seed: int, option: str = "--seed") -> int:
    """Refuse a negative seed before any work (numpy and gymnasium need seeds >= 0)."""
    if seed < 0:
        raise ConfigError(f"{option} must be an integer >= 0, got {seed}")
    return seed


def check_noise(noise: float, option: str = "--noise") -> float:
    """Refuse a sensor-noise sigma that is negative or not finite."""
    if not math.isfinite(noise) or noise < 0:
        raise ConfigError(f"{option} must be a finite number >= 0, got {noise}")
    return noise


def write_json(path: Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically; a failure is one line naming the file."""
    from behavior_hmm._atomic import atomic_write_bytes

    try:
        atomic_write_bytes(path, text.encode())
    except OSError as exc:
        raise ConfigError(f"{path}: cannot write JSON ({exc.strerror or exc})") from None


# ------------------------------------------------------------- starts and goals

#: The channels a ``--start`` may set.
START_KEYS: tuple[str, ...] = ("angle", "distance")


def parse_assignments(
    text: str, option: str, allowed: tuple[str, ...] | None = None
) -> dict[str, float]:
    """Parse ``angle=120,distance=0.5`` into ``{"angle": 120.0, "distance": 0.5}``.

    Every value must be a finite number, no key may repeat, and with ``allowed`` every
    key must be one of those; anything else raises :class:`ConfigError`.
    """
    out: dict[str, float] = {}
    for item in text.split(","):
        item = item.strip()
        if not item:
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"{option} expects CHANNEL=VALUE[,CHANNEL=VALUE], got '{text}'")
        if allowed is not None and key not in allowed:
            choices = ", ".join(allowed)
            raise ConfigError(f"{option}: unknown channel '{key}'; choose from {choices}")
        if key in out:
            raise ConfigError(f"{option} gives '{key}' twice (in '{text}')")
        try:
            number = float(value)
        except ValueError:
            raise ConfigError(f"{option}: '{value}' is not a number (in '{item}')") from None
        if number != number or number in (float("inf"), float("-inf")):
            raise ConfigError(f"{option}: '{value}' is not a finite number")
        out[key] = number
    if not out:
        raise ConfigError(f"{option} is empty; e.g. {option} angle=0")
    return out


def parse_start(text: str, arena: bool = True) -> dict[str, float]:
    """A ``--start``: angle (deg) and/or distance (m), inside our arena unless ``arena``
    is False (another robot's, ``--env``: any of its channels) (:class:`ConfigError` if
    not)."""
    from behavior_hmm.teach import check_start

    # another robot (--env) starts on any of its channels; the robot refuses the others
    start = parse_assignments(text, "--start", START_KEYS if arena else None)
    check_start(start, ARENA_MAX_DISTANCE if arena else math.inf)
    return start


# ------------------------------------------------------------- models and robots


def model_params(
    kinds: tuple[str, ...], preset: str | None, config: Path | None, sets: list[str] | None
) -> tuple[str, dict[str, dict[str, Any]]]:
    """The preset's name and the effective model parameters from ``--preset``, ``--config``
    and ``--set`` (checked); with changes over the preset, the name says them
    (``"default + generator_network='elman'"``, :func:`describe_params`)."""
    from behavior_hmm.models import CBLM, SBLM, describe_params, read_config, resolve_params
    from behavior_hmm.models._config import parse_sets

    table = read_config(config) if config is not None else None
    name, params = resolve_params(
        kinds, preset, table, parse_sets(sets or []), config_name=str(config or "config")
    )
    for kind, values in params.items():  # ranges and choices, before any work
        {"SBLM": SBLM, "CBLM": CBLM}[kind](**values).check_params()
    log.debug("preset %s; parameters %s", name, params)
    if table is not None or sets:
        # a score is never shown under a preset's name it does not have: name the changes
        named = dict.fromkeys(describe_params(kind, values) for kind, values in params.items())
        if list(named) != [name]:
            name = "; ".join(named)
    return name, params


def load_model(path: Path) -> Any:
    """Load an SBLM or CBLM file, whichever it holds."""
    from behavior_hmm.models import load

    model = load(path)
    log.debug("loaded %s: %s %s", path, model.kind, model.behavior_)
    return model


def behavior_env(model: Any, env: str | None) -> str | None:
    """``--env``, else the robot the model's behavior needs (grasp: the gripper robot)."""
    if env is not None:
        return env
    from behavior_hmm.teach import BEHAVIORS

    spec = BEHAVIORS.get(str(getattr(model, "behavior_", "")))
    return None if spec is None else spec.env


def open_env(sim: str, env: str | None, env_kwargs: str | None) -> tuple[Any, str]:
    """The env to run on and its name: ``--env`` (with ``--env-kwargs``) or ``--sim``."""
    from behavior_hmm.runtime import Robot, make_robot_env, parse_env_kwargs

    if env is None:
        if env_kwargs:
            raise ConfigError("--env-kwargs needs --env (the factory it is passed to)")
        from behavior_hmm.sim import make_env

        return make_env(check_sim(sim)), sim
    made = make_robot_env(env, parse_env_kwargs(env_kwargs))
    robot = Robot(made)  # the contract is checked now, before anything runs
    log.debug("env %s: control period %g ms", env, robot.control_period * 1000)
    return made, env


def warn_provenance(model: Any, env: Any, env_name: str) -> None:
    """Warn (stderr) when ``env`` is not the robot, or not the control period, of training."""
    from behavior_hmm.runtime import Robot

    trained = getattr(model, "provenance_", None) or {}
    was = trained.get("env")
    if was and was != env_name:
        log.warning("warning: the model was trained on %s, running on %s", was, env_name)
    period = trained.get("control_period")
    now = Robot(env).control_period
    if period and abs(float(period) - now) > 1e-9:
        log.warning(
            "warning: the model was trained at a %g ms control period, %s runs at %g ms",
            float(period) * 1000,
            env_name,
            now * 1000,
        )


def check_video(path: Path, backend: str) -> None:
    """Refuse a video file or backend we cannot write, before anything runs."""
    from behavior_hmm.viz._mujoco_video import VIDEO_BACKENDS
    from behavior_hmm.viz._video import _video_format

    if backend not in VIDEO_BACKENDS:
        raise ConfigError(
            f"unknown --video-backend '{backend}'; choose one of {', '.join(VIDEO_BACKENDS)}"
        )
    _video_format(path)


def write_video(
    trace: Any, path: Path, backend: str, robot: Any, title: str = "", teacher: Any = None
) -> None:
    """Render one run's video with ``backend`` (see :func:`check_video`); ``teacher``: the
    teacher's path (n, 3) from the same start, drawn faint by the top-down backend."""
    if backend == "mujoco":
        from behavior_hmm.viz._mujoco_video import render_trace_mujoco

        render_trace_mujoco(trace, path, robot=robot)
    else:
        from behavior_hmm.viz import render_trace

        render_trace(trace, path, robot=robot, title=title, teacher_pose=teacher)
