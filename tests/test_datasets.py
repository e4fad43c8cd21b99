"""Data sets: fixed splits, where data is looked for, and what happens when it is missing."""

from __future__ import annotations

from pathlib import Path

import pytest

from gradgps import ConfigError, DataNotFoundError
from gradgps._data.datasets import find_data_dir, load_dataset


@pytest.mark.shared
@pytest.mark.parametrize(
    ("name", "split", "rows", "tracks"),
    [
        ("driveplotr", "test", 3512, {11, 14, 31}),
        ("driveplotr", "validation", 3379, {9, 10, 12, 13, 15}),
        ("driveplotr", "train", 16296, None),
        ("tuc", "test", 8571, {"chemnitz_city"}),
        ("tuc", "validation", 3575, {"frankfurt_westend_tower"}),
        (
            "tuc",
            "train",
            13143,
            {"berlin_gendarmenmarkt", "berlin_potsdamer_platz", "frankfurt_main_tower"},
        ),
    ],
)
def test_splits_follow_the_data_readme(
    shared_data: Path, name: str, split: str, rows: int, tracks: set[object] | None
) -> None:
    table = load_dataset(name, split, data_dir=shared_data)
    assert len(table) == rows
    assert list(table.index) == list(range(rows))
    if tracks is not None:
        assert set(table["drive" if name == "driveplotr" else "trace"]) == tracks


@pytest.mark.shared
def test_data_dir_comes_from_the_environment(
    shared_data: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("GRADGPS_DATA", str(shared_data))
    assert find_data_dir() == shared_data
    monkeypatch.delenv("GRADGPS_DATA")
    monkeypatch.chdir(shared_data.parent.parent / "shared")  # ../shared/data from here is the data
    assert find_data_dir().resolve() == shared_data.resolve()


def test_missing_data_says_where_it_looked_and_what_to_do(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    with pytest.raises(DataNotFoundError, match=r"nowhere.*--data-dir.*GRADGPS_DATA"):
        load_dataset("driveplotr", "test", data_dir=tmp_path / "nowhere")
    with pytest.raises(DataNotFoundError, match=r"driveplotr_nds\.csv not found"):
        load_dataset("driveplotr", "test", data_dir=tmp_path)
    monkeypatch.delenv("GRADGPS_DATA", raising=False)
    monkeypatch.chdir(tmp_path)
    with pytest.raises(DataNotFoundError, match=r"shared/data \(default\)"):
        find_data_dir()


def test_unknown_names_are_config_errors() -> None:
    with pytest.raises(ConfigError, match="unknown dataset"):
        load_dataset("zurich", "test")
    with pytest.raises(ConfigError, match="unknown split"):
        load_dataset("tuc", "dev")
