"""Command-line commands that bring robot data in and take datasets out.

Registered on the main app by :func:`register` (``behavior_hmm.cli``)::

    behavior-hmm import-csv log.csv --map angle=bearing --unit angle=rad \\
        --derive linear_velocity,angular_velocity --resample -o mine.parquet
    behavior-hmm import-bag run1.bag run2.bag --map angle=/object_bearing:data \\
        --map distance=/object_distance --twist /cmd_vel \\
        --derive linear_velocity,angular_velocity -o mine.parquet
    behavior-hmm import-lerobot lerobot/turn -o mine.parquet
    behavior-hmm export-lerobot data/turn.parquet lerobot/turn
"""

from __future__ import annotations

import warnings
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Annotated, Any

import typer

from behavior_hmm.errors import ConfigError

MapOption = Annotated[
    list[str] | None,
    typer.Option("--map", help="OURS=THEIRS mapping (repeatable); see each command"),
]
MapFileOption = Annotated[
    Path | None,
    typer.Option(
        "--map-file",
        help="TOML mapping file: [map] and [unit] tables and options (the command line wins)",
    ),
]
UnitOption = Annotated[
    list[str] | None,
    typer.Option(help="CHANNEL=UNIT of your data, e.g. angle=rad, distance=mm (repeatable)"),
]
DeriveOption = Annotated[
    str | None,
    typer.Option(
        help="Velocities to compute from positions by finite differences: "
        "linear_velocity (= -d distance/dt), angular_velocity (= -d angle/dt)"
    ),
]
ResampleOption = Annotated[
    bool,
    typer.Option(
        "--resample", help="Interpolate each episode linearly onto the 16 ms control period"
    ),
]
BehaviorOption = Annotated[str | None, typer.Option(help="Behavior name stored in metadata")]
ChannelOption = Annotated[
    list[str] | None,
    typer.Option(
        "--channel",
        help="NAME:UNIT:LO:HI, a robot's own sensor column of your file (e.g. ir0:m:0:0.1 "
        "for an infrared proximity reading in m, normalized from [0, 0.1]); imported in "
        "that unit and declared in the dataset's metadata (repeatable)",
    ),
]
OutOption = Annotated[Path, typer.Option("-o", "--out", help="Output Parquet file")]


def pairs(items: list[str], option: str) -> dict[str, str]:
    """``["angle=bearing", ...]`` -> ``{"angle": "bearing"}``; one-line errors."""
    out: dict[str, str] = {}
    for item in items:
        key, sep, value = item.partition("=")
        if not sep or not key.strip() or not value.strip():
            raise ConfigError(f"{option} expects KEY=VALUE, got '{item}'")
        if key.strip() in out:
            raise ConfigError(f"{option} gives '{key.strip()}' twice")
        out[key.strip()] = value.strip()
    return out


@contextmanager
def _reported_warnings() -> Iterator[None]:
    """Print each import warning as one ``warning: ...`` line on stderr."""
    from behavior_hmm.data._transform import DataImportWarning

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always", DataImportWarning)
        try:
            yield
        finally:
            ours = [w for w in caught if issubclass(w.category, DataImportWarning)]
            others = [w for w in caught if not issubclass(w.category, DataImportWarning)]
    for w in ours:
        typer.echo(f"warning: {' '.join(str(w.message).split())}", err=True)
    for w in others:  # not ours: let Python report it as usual
        warnings.warn_explicit(w.message, w.category, w.filename, w.lineno)


def _merged(
    map_: list[str] | None, unit: list[str] | None, map_file: Path | None, kind: str
) -> tuple[dict[str, str], dict[str, str], dict[str, Any]]:
    """Mapping, units and options: the mapping file's, overridden key by key by the options."""
    from behavior_hmm.data._mapfile import MapFile, read_map_file

    loaded = read_map_file(map_file, kind) if map_file is not None else MapFile()
    mapping = {**loaded.map, **pairs(map_ or [], "--map")}
    units = {**loaded.unit, **pairs(unit or [], "--unit")}
    return mapping, units, loaded.options


def _derive(option: str | None, options: dict[str, Any]) -> tuple[str, ...]:
    from behavior_hmm.data._transform import parse_derive

    return parse_derive(option if option is not None else options.get("derive"))


def _metadata(behavior: str | None, options: dict[str, Any]) -> dict[str, Any]:
    """The imported dataset's behavior, and the goal channels of a registered behavior.

    The goal travels in the metadata (``goal``), so a model learns where a registered
    behavior's demonstrations aim without knowing its name (docs/robots.md).
    """
    from behavior_hmm.teach import BEHAVIORS

    name = behavior if behavior is not None else options.get("behavior")
    if name is None:
        return {}
    spec = BEHAVIORS.get(str(name))
    return {"behavior": name} if spec is None else {"behavior": name, "goal": dict(spec.goal)}


def channel_options(items: list[str]) -> list[dict[str, Any]]:
    """``["ir0:m:0:0.1", ...]`` -> channel declarations ``{"name", "unit", "range"}``."""
    out: list[dict[str, Any]] = []
    for item in items:
        parts = [part.strip() for part in item.split(":")]
        if len(parts) != 4 or not all(parts):
            raise ConfigError(f"--channel expects NAME:UNIT:LO:HI (e.g. ir0:m:0:0.1), got '{item}'")
        name, unit, lo, hi = parts
        try:
            bounds = [float(lo), float(hi)]
        except ValueError:
            raise ConfigError(
                f"--channel {item}: LO and HI must be numbers (e.g. ir0:m:0:0.1)"
            ) from None
        out.append({"name": name, "unit": unit, "range": bounds})
    return out


def _wrote(out: Path, dataset: Any) -> None:
    typer.echo(f"wrote {out}: {len(dataset)} episodes, {dataset.n_samples} rows")


def register(app: typer.Typer, wrap: Callable[[Any], Any]) -> None:
    """Add import-csv / import-bag / import-lerobot / export-lerobot to ``app``."""

    @app.command("import-csv")
    @wrap
    def import_csv(
        csv_file: Annotated[Path, typer.Argument(help="Your CSV log")],
        out: OutOption,
        map_: Annotated[
            list[str] | None,
            typer.Option(
                "--map", help="OURS=THEIRS column mapping, e.g. angle=heading (repeatable)"
            ),
        ] = None,
        unit: UnitOption = None,
        drop: Annotated[
            list[str] | None,
            typer.Option(help="A column of your file to ignore (repeatable)"),
        ] = None,
        split_on_time_reset: Annotated[
            bool,
            typer.Option(
                "--split-on-time-reset",
                help="Without an episode column: start a new episode wherever time drops",
            ),
        ] = False,
        delimiter: Annotated[
            str | None, typer.Option(help="Cell separator, e.g. ';' or 'tab' (default ',')")
        ] = None,
        derive: DeriveOption = None,
        resample: ResampleOption = False,
        map_file: MapFileOption = None,
        behavior: BehaviorOption = None,
        channel: ChannelOption = None,
    ) -> None:
        """Convert a CSV log into a validated dataset (same checks as Parquet).

        Episode ids may be integers or names (run-a, run-b: numbered in order of
        appearance, the names kept in the metadata). Every column that is not ours is
        named in one error; --drop ignores one, --map renames one, --channel declares
        one as a robot's own sensor channel. A log sampled at another rate than 16 ms
        gets a warning unless --resample.
        Example: behavior-hmm import-csv log.csv --map angle=bearing --unit angle=rad
        --unit t=ms --derive linear_velocity,angular_velocity --resample -o mine.parquet
        """
        from behavior_hmm import data
        from behavior_hmm._paths import check_outputs

        mapping, units, options = _merged(map_, unit, map_file, "csv")
        derived = _derive(derive, options)
        channels = channel_options(channel or [])
        text = delimiter if delimiter is not None else str(options.get("delimiter", ","))
        sep = "\t" if text in ("tab", "\\t") else text
        if len(sep) != 1:
            raise ConfigError(f"--delimiter must be one character or 'tab', got '{text}'")
        check_outputs({"CSV_FILE": csv_file, "--map-file": map_file}, {"-o": out})
        with _reported_warnings():
            dataset = data.import_csv(
                csv_file,
                mapping=mapping,
                units=units,
                drop=(drop or []) + [str(d) for d in options.get("drop", [])],
                metadata=_metadata(behavior, options),
                split_on_time_reset=split_on_time_reset or bool(options.get("split_on_time_reset")),
                delimiter=sep,
                derive=derived,
                resample=resample or bool(options.get("resample")),
                channels=channels,
            )
        data.write(dataset, out)
        _wrote(out, dataset)

    @app.command("import-bag")
    @wrap
    def import_bag(
        bags: Annotated[
            list[Path],
            typer.Argument(help="ROS 1 .bag files and/or ROS 2 bag folders (one episode each)"),
        ],
        out: OutOption,
        map_: Annotated[
            list[str] | None,
            typer.Option(
                "--map",
                help="CHANNEL=TOPIC:FIELD, e.g. angle=/object_bearing:data or "
                "linear_velocity=/odom:twist.twist.linear.x (repeatable)",
            ),
        ] = None,
        unit: UnitOption = None,
        twist: Annotated[
            str | None,
            typer.Option(
                help="A geometry_msgs/Twist topic (v, omega) giving the wheel speeds, e.g. /cmd_vel"
            ),
        ] = None,
        wheel_radius: Annotated[
            float | None,
            typer.Option(help="Wheel radius (m) for --twist; default the simulated robot's"),
        ] = None,
        track_width: Annotated[
            float | None,
            typer.Option(
                help="Distance between the wheels (m) for --twist; default the simulated robot's"
            ),
        ] = None,
        split_gap: Annotated[
            float | None,
            typer.Option(help="Start a new episode after this many seconds without messages"),
        ] = None,
        episode_topic: Annotated[
            str | None,
            typer.Option(help="Counter topic (TOPIC[:FIELD]): a new episode where it changes"),
        ] = None,
        derive: DeriveOption = None,
        map_file: MapFileOption = None,
        behavior: BehaviorOption = None,
    ) -> None:
        """Convert ROS 1 / ROS 2 bags into a validated dataset (needs the 'bags' extra).

        Every channel comes from one field of one topic; the topics are aligned onto the
        16 ms control period by their time stamps in the bag (from the first instant
        every mapped topic has a message, each holding its latest message). Each bag is
        one episode unless --split-gap or --episode-topic splits it.
        Example: behavior-hmm import-bag run.bag --map angle=/object_bearing:data
        --unit angle=rad --map distance=/object_distance:data --twist /cmd_vel
        --derive linear_velocity,angular_velocity -o mine.parquet
        """
        from behavior_hmm import data
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.data._bags import import_bags
        from behavior_hmm.sim import RobotParams

        mapping, units, options = _merged(map_, unit, map_file, "bag")
        derived = _derive(derive, options)
        spec = RobotParams()
        twist_topic = twist if twist is not None else options.get("twist")
        radius = _number(wheel_radius, options.get("wheel_radius"), spec.wheel_radius)
        track = _number(track_width, options.get("track_width"), spec.axle_track)
        gap = split_gap if split_gap is not None else options.get("split_gap")
        counter = episode_topic if episode_topic is not None else options.get("episode_topic")
        check_outputs({"BAG": bags, "--map-file": map_file}, {"-o": out})
        with _reported_warnings():
            dataset = import_bags(
                bags,
                mapping=mapping,
                units=units,
                twist=twist_topic,
                wheel_radius=radius,
                track_width=track,
                split_gap=None if gap is None else float(gap),
                episode_topic=counter,
                derive=derived,
                metadata=_metadata(behavior, options),
            )
        data.write(dataset, out)
        _wrote(out, dataset)

    @app.command("import-lerobot")
    @wrap
    def import_lerobot(
        folder: Annotated[Path, typer.Argument(help="A LeRobot dataset folder (meta/info.json)")],
        out: OutOption,
        map_: Annotated[
            list[str] | None,
            typer.Option(
                "--map",
                help="CHANNEL=FEATURE[:ELEMENT], e.g. angle=observation.state:bearing or "
                "left=action:0 (repeatable); default: elements named like our channels",
            ),
        ] = None,
        unit: UnitOption = None,
        derive: DeriveOption = None,
        resample: ResampleOption = False,
        map_file: MapFileOption = None,
        behavior: BehaviorOption = None,
    ) -> None:
        """Convert a LeRobot dataset (v3.0 layout, local files only) into a dataset.

        A folder written by export-lerobot needs no mapping. Frames are read from
        data/**/*.parquet; time is 'timestamp', episodes 'episode_index'.
        Example: behavior-hmm import-lerobot their_robot --map angle=observation.state:bearing
        --map distance=observation.state:range --map left=action:0 --map right=action:1
        --unit angle=rad --derive linear_velocity,angular_velocity --resample -o mine.parquet
        """
        from behavior_hmm import data
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.data._lerobot import import_lerobot as read_lerobot

        mapping, units, options = _merged(map_, unit, map_file, "lerobot")
        derived = _derive(derive, options)
        check_outputs({"FOLDER": folder, "--map-file": map_file}, {"-o": out})
        with _reported_warnings():
            dataset = read_lerobot(
                folder,
                mapping=mapping,
                units=units,
                derive=derived,
                resample=resample or bool(options.get("resample")),
                metadata=_metadata(behavior, options),
            )
        data.write(dataset, out)
        _wrote(out, dataset)

    @app.command("export-lerobot")
    @wrap
    def export_lerobot(
        inputs: Annotated[
            list[Path],
            typer.Argument(
                help="Datasets (Parquet) and/or traces written by 'generate -o'",
                metavar="DATA...",
            ),
        ],
        folder: Annotated[
            Path, typer.Argument(help="New folder for the LeRobot dataset", metavar="FOLDER")
        ],
        task: Annotated[
            str | None,
            typer.Option(help="Task text of every frame (default: the dataset's behavior)"),
        ] = None,
        robot_type: Annotated[
            str, typer.Option(help="robot_type in meta/info.json")
        ] = "differential_drive",
    ) -> None:
        """Write datasets or generated traces as a LeRobot dataset (v3.0 layout).

        observation.state holds distance, linear_velocity, angle, angular_velocity
        (m, m/s, deg, deg/s), action the wheel speeds left, right (rad/s); complex
        demonstrations name each frame's sub-behavior as its task. A trace
        (generate -o) is one episode of the readings the controller saw and its commands; several
        inputs are numbered one after another. FOLDER must be new or empty; nothing is
        left behind on failure.
        Example: behavior-hmm export-lerobot data/turn.parquet lerobot/turn
        """
        from behavior_hmm._paths import check_outputs
        from behavior_hmm.data._lerobot import export_lerobot as write_lerobot

        check_outputs({"DATA": inputs}, {}, folders={"FOLDER": folder})
        dataset = _read_inputs(inputs)
        written = write_lerobot(dataset, folder, task=task, robot_type=robot_type)
        typer.echo(
            f"wrote {written}: LeRobot dataset v3.0, {len(dataset)} episodes, "
            f"{dataset.n_samples} frames"
        )


#: Schema metadata key of a trace file (``Trace.write``).
TRACE_KEY = b"behavior_hmm_trace"


def _read_trace(path: Path) -> Any:
    """A trace file (``generate -o``) as a one-episode dataset: readings and commands."""
    import json

    import numpy as np
    import pyarrow.parquet as pq

    from behavior_hmm.data import COMMAND_CHANNELS, SENSOR_CHANNELS, Dataset
    from behavior_hmm.errors import DatasetError

    table = pq.read_table(path)
    needed = ["t", *SENSOR_CHANNELS, *COMMAND_CHANNELS]
    missing = [c for c in needed if c not in table.column_names]
    if missing:
        raise DatasetError(f"trace without column(s) {', '.join(missing)}", file=str(path))
    columns = {c: table.column(c).to_numpy() for c in needed}
    columns["episode"] = np.zeros(table.num_rows, dtype=np.int64)
    summary = json.loads((table.schema.metadata or {}).get(TRACE_KEY, b"{}"))
    try:
        return Dataset(columns, {"trace": summary, "source": {"trace": path.name}})
    except DatasetError as err:
        raise DatasetError(
            err.reason, file=str(path), episode=None, row=err.row, field=err.field
        ) from None


def _without_behavior(ds: Any) -> Any:
    from behavior_hmm.data import Dataset

    cols = ds.to_columns()
    cols.pop("behavior", None)
    return Dataset(cols, ds.metadata)


def _read_inputs(paths: list[Path]) -> Any:
    """Datasets and traces, their episodes numbered one after another."""
    import pyarrow.parquet as pq

    from behavior_hmm import data

    datasets = []
    for path in paths:
        is_trace = False
        if path.is_file():
            try:
                is_trace = TRACE_KEY in (pq.read_schema(path).metadata or {})
            except Exception:  # not Parquet: data.read says what is wrong
                is_trace = False
        datasets.append(_read_trace(path) if is_trace else data.read(path))
    with_names = [ds.has_behavior for ds in datasets]
    if any(with_names) and not all(with_names) and all(len(ds.behaviors) <= 1 for ds in datasets):
        datasets = [_without_behavior(ds) for ds in datasets]  # one behavior: the task says it
    combined = datasets[0]
    for other in datasets[1:]:
        combined = combined.concat(other, renumber=True)
    if len(datasets) > 1:
        combined = combined.with_metadata(sources=[p.name for p in paths])
    return combined


def _number(option: float | None, from_file: Any, default: float) -> float:
    if option is not None:
        return float(option)
    if from_file is not None:
        return float(from_file)
    return float(default)
