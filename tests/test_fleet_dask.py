"""detect-fleet on a 2-worker local Dask cluster: the same rows as ``gradgps detect``."""

from __future__ import annotations

import itertools
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pandas as pd
import pytest
from click.testing import CliRunner

from gradgps import ConfigError, InputError
from gradgps._cli import main
from gradgps._data.simulator import simulate_fleet
from gradgps._result import RESULT_COLUMNS as _RESULT_COLUMNS
from gradgps._run.chunked import detect_partition
from gradgps._run.fleet_dask import dask_client, detect_fleet, find_partitions

pytest.importorskip("distributed")

RESULT_COLUMNS = list(_RESULT_COLUMNS)


@pytest.fixture(scope="module")
def client() -> Iterator[Any]:
    with dask_client(workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def fleet() -> pd.DataFrame:
    frame = simulate_fleet(5, 3.0, 1.0, seed=11)
    frame.loc[17, "lat"] = float("nan")  # one unusable fix, so invalid rows are compared too
    return frame


def _write_fleet(fleet: pd.DataFrame, root: Path) -> None:
    """Both layouts at once: flat CSV and Parquet files, and hive folders (one split in two parts)."""
    root.mkdir()
    for vehicle, rows in fleet.groupby("track"):
        rows = rows.drop(columns="track")
        match int(vehicle):
            case 0:
                rows.to_csv(root / f"{vehicle}.csv", index=False)
            case 1:
                rows.to_parquet(root / f"{vehicle}.parquet", index=False)
            case 2:
                part = root / f"vehicle={vehicle}"
                part.mkdir()
                half = len(rows) // 2
                rows.iloc[:half].to_parquet(part / "part-0.parquet", index=False)
                rows.iloc[half:].to_parquet(part / "part-1.parquet", index=False)
            case _:
                part = root / f"vehicle=car%20{vehicle}"  # URL-encoded, as pyarrow writes it
                part.mkdir()
                rows.to_parquet(part / "part-0.parquet", index=False)
    (root / "_SUCCESS").write_text("")


def _read(path: Path) -> pd.DataFrame:
    return pd.read_csv(path) if path.suffix == ".csv" else pd.read_parquet(path)


def test_detect_fleet_equals_detect_row_for_row(
    client: Any, fleet: pd.DataFrame, tmp_path: Path
) -> None:
    source, target = tmp_path / "in", tmp_path / "out"
    _write_fleet(fleet, source)
    runner = CliRunner()
    done = runner.invoke(
        main,
        ["detect-fleet", str(source), "-o", str(target), "--scheduler", client.scheduler.address],
    )
    assert done.exit_code == 0, done.output
    assert "5 vehicles" in done.output
    inputs = sorted(
        p.relative_to(source)
        for p in source.rglob("*")
        if p.is_file() and not p.name.startswith("_")
    )
    outputs = sorted(p.relative_to(target) for p in target.rglob("*") if p.is_file())
    assert outputs == inputs

    # Per file: exactly what `gradgps detect` writes for that file alone (a one-part vehicle).
    for relative in (Path("0.csv"), Path("1.parquet"), Path("vehicle=car%204/part-0.parquet")):
        alone = tmp_path / f"alone{relative.suffix}"
        single = runner.invoke(main, ["detect", str(source / relative), "-o", str(alone)])
        assert single.exit_code == 0, single.output
        pd.testing.assert_frame_equal(_read(target / relative), _read(alone))

    # Whole fleet: `gradgps detect` on one file with every vehicle gives the same results.
    whole = tmp_path / "whole.parquet"
    fleet.to_parquet(whole, index=False)
    everything = tmp_path / "whole-out.parquet"
    assert runner.invoke(main, ["detect", str(whole), "-o", str(everything)]).exit_code == 0
    expected = pd.read_parquet(everything)
    for part in find_partitions(source):
        got = pd.concat([_read(target / r) for r in part.outputs], ignore_index=True)
        vehicle = part.vehicle.removeprefix("car ")
        want = expected[expected["track"] == vehicle].reset_index(drop=True)
        # A CSV output reads back anomaly/alert as int64 and an empty invalid_reason as NaN.
        got["invalid_reason"] = got["invalid_reason"].fillna("")
        pd.testing.assert_frame_equal(
            got[["t", *RESULT_COLUMNS]], want[["t", *RESULT_COLUMNS]], check_dtype=False
        )
    assert (expected["invalid_reason"] != "").sum() == 1


def test_find_partitions_reads_both_layouts(fleet: pd.DataFrame, tmp_path: Path) -> None:
    _write_fleet(fleet, tmp_path / "in")
    parts = find_partitions(tmp_path / "in")
    assert [p.vehicle for p in parts] == ["0", "1", "2", "car 3", "car 4"]
    assert parts[2].outputs == ("vehicle=2/part-0.parquet", "vehicle=2/part-1.parquet")


@pytest.mark.parametrize(
    ("layout", "message"),
    [
        ({}, "no vehicle files"),
        ({"a.csv": "t,lat,lon\n", "a.parquet": ""}, "appears twice"),
        ({"notes.json": "{}"}, "not a CSV or Parquet file"),
        ({"trips/a.csv": "t,lat,lon\n"}, "not a key=value partition"),
        ({"vehicle=1/readme.md": ""}, "not a CSV or Parquet file"),
    ],
)
def test_find_partitions_rejects_what_is_not_a_fleet(
    tmp_path: Path, layout: dict[str, str], message: str
) -> None:
    for name, text in layout.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    with pytest.raises(InputError, match=message):
        find_partitions(tmp_path)


def test_a_bad_vehicle_file_fails_the_run_naming_the_file(client: Any, tmp_path: Path) -> None:
    source = tmp_path / "in"
    source.mkdir()
    (source / "ok.csv").write_text("t,lat,lon\n0,45,7\n1,45.0001,7\n")
    (source / "bad.csv").write_text("t,lat,lon\n0,45,7\n1,north,7\n")
    with pytest.raises(InputError, match=r"bad\.csv.*lat"):
        detect_fleet(source, tmp_path / "out", client, task=detect_partition)


def test_output_directory_must_be_new_or_empty(
    client: Any, fleet: pd.DataFrame, tmp_path: Path
) -> None:
    source, target = tmp_path / "in", tmp_path / "out"
    _write_fleet(fleet, source)
    target.mkdir()
    (target / "old.csv").write_text("x\n")
    with pytest.raises(ConfigError, match="not empty"):
        detect_fleet(source, target, client, task=detect_partition)
    with pytest.raises(ConfigError, match="input directory"):
        detect_fleet(source, source, client, task=detect_partition)


def test_a_partition_runs_serially_without_touching_numba_threads(
    fleet: pd.DataFrame, tmp_path: Path
) -> None:
    """Detect runs the serial kernel: no process-wide lock, numba's thread count left alone."""
    import threading

    import numba

    from gradgps._run import fleet_dask

    _write_fleet(fleet, tmp_path / "in")
    parts = find_partitions(tmp_path / "in")
    (tmp_path / "out").mkdir()
    before = numba.get_num_threads()
    assert not any(isinstance(v, type(threading.Lock())) for v in vars(fleet_dask).values())
    summary = detect_partition(parts[0], str(tmp_path / "out"))
    assert numba.get_num_threads() == before
    assert summary is not None


@pytest.mark.parametrize("chunk_size", [1, 7, 10_000])
def test_a_partition_in_chunks_equals_batch_detection_of_its_files_joined(
    fleet: pd.DataFrame, tmp_path: Path, chunk_size: int
) -> None:
    """Issue 18: a task reads its vehicle's files in chunks (memory of one chunk), with the
    detectors carried over chunk and file boundaries: the results of the files joined and
    detected whole, as tasks did before, row for row."""
    from gradgps import Detector
    from gradgps._io.read import load_table
    from gradgps._tracks.track import to_fixes

    _write_fleet(fleet, tmp_path / "in")
    split = next(p for p in find_partitions(tmp_path / "in") if len(p.files) == 2)
    (tmp_path / "out").mkdir()
    summary = detect_partition(split, str(tmp_path / "out"), chunk_size=chunk_size)
    fixes = pd.concat([to_fixes(load_table(f)) for f in split.files], ignore_index=True)
    want = Detector().detect(fixes).reset_index(drop=True)
    got = pd.concat(
        [pd.read_parquet(tmp_path / "out" / r) for r in split.outputs], ignore_index=True
    )
    assert summary.rows == len(want) == len(got)
    pd.testing.assert_frame_equal(got[RESULT_COLUMNS], want[RESULT_COLUMNS], check_dtype=False)


@pytest.mark.parametrize("chunk_size", [1, 7])
def test_a_settling_vehicle_is_settled_across_its_files(
    fleet: pd.DataFrame, tmp_path: Path, chunk_size: int
) -> None:
    """A model whose verdicts settle one fix late: a file's last fix is settled by the next
    file's first, so a vehicle split in many files gets batch detection's rows of the
    files joined (the split is where a verdict at once and the settled one differ)."""
    from _gru_support import random_detector_model
    from gradgps import Detector
    from gradgps._run.settings import RunSettings
    from gradgps._tracks.track import to_fixes

    model = random_detector_model(tmp_path / "confirm", confirm_head=True)
    rows = fleet[fleet["track"] == fleet["track"].iloc[0]].drop(columns="track")
    fixes = to_fixes(rows.reset_index(drop=True))
    want = Detector(model).detect(fixes).reset_index(drop=True)
    stream = Detector(model)
    at_once = [stream.update(f.t, f.lat, f.lon, f.speed, f.heading) for f in fixes.itertuples()]
    ends = [k for k in range(len(fixes) - 1) if at_once[k].anomaly != want["anomaly"][k]]
    assert len(ends) >= 3  # else the test could not tell
    part = tmp_path / "in" / "vehicle=v"
    part.mkdir(parents=True)
    cuts = [0, *(k + 1 for k in ends), len(rows)]  # each part ends on such a fix
    for j, (a, b) in enumerate(itertools.pairwise(cuts)):
        rows.iloc[a:b].to_parquet(part / f"part-{j:03d}.parquet", index=False)
    (tmp_path / "out").mkdir()
    (split,) = find_partitions(tmp_path / "in")
    detect_partition(split, str(tmp_path / "out"), RunSettings(model=model), chunk_size)
    got = pd.concat([pd.read_parquet(tmp_path / "out" / r) for r in split.outputs])
    pd.testing.assert_frame_equal(
        got[RESULT_COLUMNS].reset_index(drop=True), want[RESULT_COLUMNS], check_dtype=False
    )


def test_detect_fleet_chunk_size_0_asks_for_the_largest_bounded_chunks(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--chunk-size 0`` means one thing in ``detect`` and ``detect-fleet``: the largest
    chunks the memory bound allows (issue 18; ``detect-fleet`` refused 0). The cluster is
    left out: what matters is the chunk size each vehicle's task gets."""
    import contextlib

    from gradgps._io.read import MAX_CHUNK_ROWS
    from gradgps._run import fleet_dask

    asked: list[int] = []

    def run(*_: object, chunk_size: int, **__: object) -> fleet_dask.FleetSummary:
        asked.append(chunk_size)
        return fleet_dask.FleetSummary(0, 0, 0, 0, 0, 1.0)

    monkeypatch.setattr(fleet_dask, "dask_client", lambda *_: contextlib.nullcontext())
    monkeypatch.setattr(fleet_dask, "detect_fleet", run)
    for given, rows in (("0", MAX_CHUNK_ROWS), ("1234", 1234)):
        args = ["detect-fleet", str(tmp_path), "-o", str(tmp_path / "out"), "--chunk-size", given]
        done = CliRunner().invoke(main, args)
        assert done.exit_code == 0, done.output
        assert asked.pop() == rows


def test_detect_fleet_says_what_detect_says_of_each_file(client: Any, tmp_path: Path) -> None:
    """A fleet run is as honest as a one-file run: a vehicle logged at one fix every 5 s
    (below the slowest validated rate) gets `detect`'s warning, led by its file's path, on
    standard error; a vehicle at 1 Hz gets none."""
    frame = simulate_fleet(2, 6.0, 1.0, seed=5)
    source = tmp_path / "in"
    source.mkdir()
    for vehicle, rows in frame.groupby("track"):
        rows = rows.drop(columns="track")
        if int(vehicle) == 1:
            rows = rows.iloc[::5]
        rows.to_csv(source / f"car{vehicle}.csv", index=False)
    alone = CliRunner().invoke(
        main, ["detect", str(source / "car1.csv"), "-o", str(tmp_path / "alone.csv")]
    )
    assert alone.exit_code == 0, alone.output
    said = [line for line in alone.stderr.splitlines() if line.startswith("warning: ")]
    assert any("slower than the slowest rate" in line for line in said), alone.stderr

    args = ["detect-fleet", str(source), "-o", str(tmp_path / "out")]
    done = CliRunner().invoke(main, [*args, "--scheduler", client.scheduler.address])
    assert done.exit_code == 0, done.output
    fleet_said = [line for line in done.stderr.splitlines() if line.startswith("warning: ")]
    assert fleet_said == [line.replace("warning: ", "warning: car1.csv: ", 1) for line in said]


def test_detect_fleet_cuts_a_long_warning_list_and_says_by_how_much(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import contextlib

    from gradgps._cli.detect_fleet import MAX_WARNINGS_SHOWN
    from gradgps._run import fleet_dask

    many = tuple(f"car{i}.csv: median time step 5 s" for i in range(MAX_WARNINGS_SHOWN + 7))

    def run(*_: object, **__: object) -> fleet_dask.FleetSummary:
        return fleet_dask.FleetSummary(27, 0, 0, 0, 0, 1.0, many)

    monkeypatch.setattr(fleet_dask, "dask_client", lambda *_: contextlib.nullcontext())
    monkeypatch.setattr(fleet_dask, "detect_fleet", run)
    done = CliRunner().invoke(main, ["detect-fleet", str(tmp_path), "-o", str(tmp_path / "o")])
    assert done.exit_code == 0, done.output
    lines = [line for line in done.stderr.splitlines() if line.startswith("warning: ")]
    assert lines[:-1] == [f"warning: {w}" for w in many[:MAX_WARNINGS_SHOWN]]
    assert lines[-1].startswith("warning: ... and 7 more input warnings")
