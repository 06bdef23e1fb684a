"""A robot's own sensor channels, declared in the dataset's metadata (issue 9, item 2).

Eight infrared proximity readings ``ir0 .. ir7`` (m, range [0, 0.1]) ride along the
four channels of the data contract: through ``Dataset``, Parquet, validation and
``import-csv`` (Python API and command line).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from typer.testing import CliRunner

from behavior_hmm.cli import app
from behavior_hmm.data import (
    CHANNELS,
    CONTROL_PERIOD,
    METADATA_KEY,
    REQUIRED_COLUMNS,
    SENSOR_CHANNELS,
    ChannelSpec,
    Dataset,
    SamplingWarning,
    import_csv,
    read,
    summarize,
    write,
)
from behavior_hmm.errors import ConfigError, DatasetError

IR = tuple(f"ir{k}" for k in range(8))
IR_DECLARED = [{"name": name, "unit": "m", "range": [0, 0.1]} for name in IR]
CSV_COLUMNS = ("episode", "t", *SENSOR_CHANNELS, "left", "right")


def _ir_episode(i: int, n: int) -> dict[str, Any]:
    """A slow turn in place (episode ``i``, ``n`` rows) with eight proximity readings."""
    t = np.arange(n) * CONTROL_PERIOD
    omega = -20.0 - 5.0 * i
    ep: dict[str, Any] = {
        "t": t,
        "distance": np.full(n, 0.3 + 0.1 * i),
        "linear_velocity": np.zeros(n),
        "angle": 90.0 - 40.0 * i - omega * t,
        "angular_velocity": np.full(n, omega),
        "left": np.full(n, 0.5 + 0.1 * i),
        "right": np.full(n, -0.5 - 0.1 * i),
    }
    rng = np.random.default_rng(i)
    for name in IR:
        ep[name] = rng.uniform(0.0, 0.1, n)
    return ep


@pytest.fixture
def ir_ds() -> Dataset:
    """Three episodes with eight proximity channels each."""
    eps = [_ir_episode(i, 30 + 5 * i) for i in range(3)]
    return Dataset.from_episodes(eps, {"behavior": "turn", "channels": IR_DECLARED})


def _raw_parquet(path: Path, columns: dict[str, Any], metadata: dict[str, Any]) -> Path:
    table = pa.table({name: pa.array(values) for name, values in columns.items()})
    meta = {METADATA_KEY: json.dumps(metadata).encode()}
    pq.write_table(table.replace_schema_metadata(meta), path)
    return path


# --- the dataset ------------------------------------------------------------------------


def test_declared_channels_become_sensor_columns(ir_ds: Dataset) -> None:
    assert ir_ds.sensor_channels == (*SENSOR_CHANNELS, *IR)
    assert ir_ds.sensors.shape == (ir_ds.n_samples, 12)
    specs = ir_ds.channel_specs
    assert [s.name for s in specs] == list(ir_ds.sensor_channels)
    assert specs[:4] == [CHANNELS[name] for name in SENSOR_CHANNELS]
    assert specs[4] == ChannelSpec("ir0", "m", (0.0, 0.1))
    assert ir_ds.metadata["channels"] == [
        {"name": name, "unit": "m", "range": [0.0, 0.1]} for name in IR
    ]
    assert ir_ds.numeric_channels == ("t", *SENSOR_CHANNELS, *IR, "left", "right")


def test_episode_channel_and_columns(ir_ds: Dataset) -> None:
    source = _ir_episode(1, 35)
    ep = ir_ds.episode(1)
    assert ep.sensors.shape == (35, 12)
    assert ep.sensor_channels == ir_ds.sensor_channels
    np.testing.assert_array_equal(ep.channel("ir3"), source["ir3"])
    np.testing.assert_array_equal(ep.columns(["angle", "ir7"])[:, 1], source["ir7"])
    both = ir_ds.columns(["angle", "ir0"])  # what training reads
    assert both.shape == (ir_ds.n_samples, 2)
    np.testing.assert_array_equal(both[:, 0], ir_ds.column("angle"))
    np.testing.assert_array_equal(both[:, 1], ir_ds.sensors[:, 4])
    assert ep.to_dict()["ir3"].tolist() == source["ir3"].tolist()
    with pytest.raises(ConfigError, match=r"unknown channel 'ir8'.*did you mean"):
        ir_ds.column("ir8")


def test_new_datasets_keep_the_declared_channels(ir_ds: Dataset) -> None:
    sub = ir_ds.subset([2, 0])
    assert sub.sensor_channels == ir_ds.sensor_channels
    np.testing.assert_array_equal(sub.episode(1).channel("ir5"), ir_ds.episode(0).channel("ir5"))
    both = ir_ds.concat(ir_ds, renumber=True)
    assert len(both) == 6 and both.sensors.shape == (2 * ir_ds.n_samples, 12)
    assert ir_ds.with_metadata(seed=3).sensor_channels == ir_ds.sensor_channels
    assert Dataset.from_episodes(ir_ds.episodes(), ir_ds.metadata) == ir_ds
    assert Dataset(ir_ds.to_columns(), ir_ds.metadata) == ir_ds
    assert list(ir_ds.to_columns()) == ["episode", "t", *SENSOR_CHANNELS, *IR, "left", "right"]
    assert "ir0" in repr(ir_ds)


def test_concat_refuses_other_channels(ir_ds: Dataset, small_ds: Dataset) -> None:
    with pytest.raises(DatasetError, match="different declared channels"):
        ir_ds.concat(small_ds, renumber=True)


def test_channel_spec_objects_are_accepted_as_declarations() -> None:
    ep = _ir_episode(0, 20)
    specs = [ChannelSpec(name, "m", (0.0, 0.1)) for name in IR]
    ds = Dataset.from_episodes([ep], {"channels": specs})
    assert ds == Dataset.from_episodes([ep], {"channels": IR_DECLARED})


def test_a_standard_dataset_is_unchanged(small_ds: Dataset) -> None:
    assert small_ds.sensor_channels == SENSOR_CHANNELS
    assert small_ds.sensors.shape == (small_ds.n_samples, 4)
    assert "channels" not in small_ds.metadata
    assert list(small_ds.to_columns()) == list(REQUIRED_COLUMNS)
    assert small_ds.episode(0).sensor_channels == SENSOR_CHANNELS


def test_summary_lists_the_declared_channels(ir_ds: Dataset) -> None:
    channels = summarize(ir_ds)["channels"]
    assert list(channels) == [*SENSOR_CHANNELS, *IR, "left", "right"]
    assert channels["ir2"]["unit"] == "m"
    assert 0.0 <= channels["ir2"]["min"] <= channels["ir2"]["max"] <= 0.1


# --- Parquet ----------------------------------------------------------------------------


def test_parquet_round_trip_is_identical(tmp_path: Path, ir_ds: Dataset) -> None:
    path = write(ir_ds, tmp_path / "ir.parquet")
    back = read(path)
    assert back == ir_ds
    assert back.metadata == ir_ds.metadata
    assert back.sensor_channels == ir_ds.sensor_channels
    np.testing.assert_array_equal(back.sensors, ir_ds.sensors)
    np.testing.assert_array_equal(back.commands, ir_ds.commands)
    np.testing.assert_array_equal(back.episode(2).channel("ir3"), ir_ds.episode(2).channel("ir3"))
    schema = pq.read_schema(path)
    assert schema.names == ["episode", "t", *SENSOR_CHANNELS, *IR, "left", "right"]
    assert all(schema.field(name).type == pa.float64() for name in IR)
    md = json.loads(schema.metadata[METADATA_KEY])
    assert [c["name"] for c in md["channels"]] == list(IR)


def test_parquet_refuses_an_undeclared_column(tmp_path: Path, ir_ds: Dataset) -> None:
    path = _raw_parquet(tmp_path / "f.parquet", ir_ds.to_columns(), {"behavior": "turn"})
    with pytest.raises(DatasetError) as info:
        read(path)
    err = info.value
    assert err.file == str(path) and err.field == "ir0"
    assert "unexpected column" in str(err)
    assert 'declare it in the metadata\'s "channels" with unit and range' in str(err)
    assert "\n" not in str(err)


def test_parquet_refuses_a_declared_channel_without_column(tmp_path: Path, ir_ds: Dataset) -> None:
    cols = ir_ds.to_columns()
    del cols["ir6"]
    path = _raw_parquet(tmp_path / "f.parquet", cols, ir_ds.metadata)
    with pytest.raises(DatasetError, match="missing column of a declared channel") as info:
        read(path)
    assert info.value.file == str(path) and info.value.field == "ir6"


@pytest.mark.parametrize(
    ("channels", "needle"),
    [
        ([{"name": "ir0", "unit": "m"}], "needs 'range'"),
        ([{"name": "ir0", "unit": "m", "range": [0.1, 0]}], "lo < hi"),
        ([{"name": "ir0", "unit": "m", "range": [0, 0.1], "color": "red"}], "unknown key"),
        ([{"name": "IR 0", "unit": "m", "range": [0, 0.1]}], "lowercase identifier"),
        ([{"name": "angle", "unit": "m", "range": [0, 1]}], "built-in column"),
        ([{"name": "behavior", "unit": "m", "range": [0, 1]}], "reserved column"),
        ([{"name": "ir0", "unit": "m", "range": [0, 1], "kind": "command"}], "only sensor"),
        ([*IR_DECLARED, IR_DECLARED[0]], "declared twice"),
        ({"ir0": "m"}, "must be a list"),
        (["ir0"], "must be a mapping"),
    ],
)
def test_malformed_declarations_name_the_file(
    tmp_path: Path, ir_ds: Dataset, channels: Any, needle: str
) -> None:
    path = _raw_parquet(tmp_path / "f.parquet", ir_ds.to_columns(), {"channels": channels})
    with pytest.raises(DatasetError) as info:
        read(path)
    err = info.value
    assert needle in str(err), str(err)
    assert err.file == str(path) and err.field == "channels"
    assert "\n" not in str(err)
    with pytest.raises(DatasetError, match="channel"):
        Dataset(ir_ds.to_columns(), {"channels": channels})


# --- validation of the values -----------------------------------------------------------


def test_nan_in_a_declared_channel_names_episode_row_and_column(
    tmp_path: Path, ir_ds: Dataset
) -> None:
    cols = ir_ds.to_columns()
    cols["ir5"][int(ir_ds.offsets[1]) + 7] = np.nan
    with pytest.raises(DatasetError, match="NaN value") as info:
        Dataset(cols, ir_ds.metadata)
    err = info.value
    assert (err.episode, err.row, err.field) == (1, 7, "ir5")
    assert "episode 1, row 7, field 'ir5'" in str(err)
    path = _raw_parquet(tmp_path / "f.parquet", cols, ir_ds.metadata)
    with pytest.raises(DatasetError, match="NaN value") as info:
        read(path)
    assert (info.value.file, info.value.episode, info.value.row) == (str(path), 1, 7)
    assert info.value.field == "ir5"


def test_values_outside_the_declared_bounds_are_refused(ir_ds: Dataset) -> None:
    cols = ir_ds.to_columns()
    cols["ir2"][3] = 7.5  # mm read as m; the spec's bounds are [-0.45, 0.55] m
    with pytest.raises(DatasetError, match=r"absurd value 7.5 m.*\[-0.45, 0.55\] m") as info:
        Dataset(cols, ir_ds.metadata)
    assert (info.value.episode, info.value.row, info.value.field) == (0, 3, "ir2")


def test_undeclared_and_missing_columns_from_episodes() -> None:
    ep = _ir_episode(0, 20)
    with pytest.raises(DatasetError, match="unexpected column") as info:
        Dataset.from_episodes([ep])
    assert info.value.field == "ir0"
    assert '"channels" with unit and range' in str(info.value)
    del ep["ir4"]
    with pytest.raises(DatasetError, match="missing column of a declared channel") as info:
        Dataset.from_episodes([ep], {"channels": IR_DECLARED})
    assert info.value.field == "ir4"


# --- import-csv -------------------------------------------------------------------------


def _ir_log(path: Path, period: float = 0.016, header: tuple[str, ...] = IR) -> Path:
    lines = [",".join([*CSV_COLUMNS, *header])]
    for ep in range(2):
        for i in range(10):
            angle = 60.0 - 5.0 * i - 3.0 * ep
            ir = [f"{0.01 * ((i + k) % 10):.3f}" for k in range(len(header))]
            cells = [str(ep), f"{i * period:.3f}", "0.5", "0.0", f"{angle:g}", "-10.0"]
            lines.append(",".join([*cells, "-0.2", "0.2", *ir]))
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return path


def test_import_csv_takes_declared_channels(tmp_path: Path) -> None:
    log = _ir_log(tmp_path / "log.csv")
    ds = import_csv(log, channels=IR_DECLARED, metadata={"behavior": "turn"})
    assert ds.sensor_channels == (*SENSOR_CHANNELS, *IR)
    assert ds.metadata["channels"] == [
        {"name": name, "unit": "m", "range": [0.0, 0.1]} for name in IR
    ]
    np.testing.assert_allclose(ds.episode(1).channel("ir3")[:3], [0.03, 0.04, 0.05])
    assert read(write(ds, tmp_path / "d.parquet")) == ds
    with pytest.raises(DatasetError) as info:  # without the declaration
        import_csv(log)
    assert "unexpected columns 'ir0'" in str(info.value)
    assert "--channel NAME:UNIT:LO:HI" in str(info.value)


def test_import_csv_channels_mapping_units_and_resampling(tmp_path: Path) -> None:
    log = _ir_log(tmp_path / "log.csv", period=0.02, header=("prox",))
    spec = ChannelSpec("ir0", "m", (0.0, 0.1))
    with pytest.warns(SamplingWarning, match="20 ms"):
        ds = import_csv(log, channels=[spec], mapping={"ir0": "prox"}, units={"ir0": "m"})
    assert ds.sensor_channels == (*SENSOR_CHANNELS, "ir0")
    assert ds.metadata["source"]["mapping"] == {"ir0": "prox"}
    fine = import_csv(log, channels=[spec], mapping={"ir0": "prox"}, resample=True)
    assert np.allclose(np.diff(fine.episode(0).t), 0.016)
    np.testing.assert_allclose(fine.episode(0).channel("ir0")[:3], [0.0, 0.008, 0.016])
    assert fine.metadata["channels"] == [spec.to_metadata()]
    assert fine.metadata["source"]["resampled"]["to_period_s"] == 0.016
    with pytest.raises(ConfigError, match="declared unit"):
        import_csv(log, channels=[spec], mapping={"ir0": "prox"}, units={"ir0": "mm"})
    with pytest.raises(DatasetError, match="missing column of a declared channel"):
        import_csv(log, channels=[spec], drop=["prox"])
    with pytest.raises(ConfigError, match="built-in column"):
        import_csv(log, channels=[{"name": "distance", "unit": "m", "range": [0, 1]}])
    with pytest.raises(ConfigError, match="channel declaration"):
        import_csv(log, channels=[{"name": "ir0", "unit": "m", "range": ["near", "far"]}])


def test_import_csv_names_the_line_of_a_bad_declared_value(tmp_path: Path) -> None:
    log = _ir_log(tmp_path / "log.csv")
    text = log.read_text().splitlines()
    cells = text[13].split(",")
    cells[len(CSV_COLUMNS) + 5] = "nan"  # ir5 of episode 1, row 2
    text[13] = ",".join(cells)
    log.write_text("\n".join(text) + "\n")
    with pytest.raises(DatasetError, match=r"NaN value \(CSV line 14\)") as info:
        import_csv(log, channels=IR_DECLARED)
    assert (info.value.episode, info.value.row, info.value.field) == (1, 2, "ir5")


def test_cli_import_csv_with_channels(tmp_path: Path) -> None:
    log = _ir_log(tmp_path / "log.csv")
    out = tmp_path / "mine.parquet"
    args = ["import-csv", str(log), "-o", str(out)]
    for name in IR:
        args += ["--channel", f"{name}:m:0:0.1"]
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 0, result.output
    ds = read(out)
    assert ds.sensor_channels == (*SENSOR_CHANNELS, *IR)
    assert ds.channel_specs[-1] == ChannelSpec("ir7", "m", (0.0, 0.1))
    np.testing.assert_allclose(ds.episode(0).channel("ir3")[:2], [0.03, 0.04])


@pytest.mark.parametrize(
    ("option", "needle"),
    [
        ("ir0:m:0", "--channel expects NAME:UNIT:LO:HI"),
        ("ir0:m:zero:0.1", "must be numbers"),
        ("ir0:m:0.1:0", "lo < hi"),
        ("Ir0:m:0:0.1", "lowercase identifier"),
    ],
)
def test_cli_refuses_a_bad_channel_option(tmp_path: Path, option: str, needle: str) -> None:
    log = _ir_log(tmp_path / "log.csv", header=("ir0",))
    out = tmp_path / "mine.parquet"
    result = CliRunner().invoke(app, ["import-csv", str(log), "--channel", option, "-o", str(out)])
    assert result.exit_code == 2, result.output
    lines = result.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: ") and needle in lines[0], lines
    assert not out.exists()
