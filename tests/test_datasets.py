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


# The drives added on 2026-11-23 (shared/data/README.md, "More real drives"):
# (data set, file, rows per split). Test-only sets have no train/validation rows.
NEW_SPLITS = [
    ("nl_motorway", "nl_motorway_1hz.csv", {"train": 6313, "validation": 6594, "test": 6490}),
    (
        "nl_motorway_gopro",
        "nl_motorway_gopro_1hz.csv",
        {"train": 2114, "validation": 2201, "test": 2169},
    ),
    ("austin2006", "austin2006_logger_1hz.csv", {"train": 7085, "validation": 1652, "test": 4649}),
    ("nevada", "garmin_nmea_nevada2005.csv", {"train": 1245, "validation": 1182, "test": 2042}),
    ("ublox_f9k", "ublox_f9k_mtv_1hz.csv", {"test": 1653}),
    ("munich", "munich_bmw_1hz.csv", {"test": 1194}),
]


@pytest.mark.shared
@pytest.mark.parametrize(("name", "file", "rows"), NEW_SPLITS, ids=[s[0] for s in NEW_SPLITS])
def test_new_drives_split_disjoint_and_cover_the_file(
    shared_data: Path, name: str, file: str, rows: dict[str, int]
) -> None:
    import pandas as pd

    whole = pd.read_csv(shared_data / file)
    seen: dict[str, set[str]] = {}
    parts = []
    for split, n in rows.items():
        table = load_dataset(name, split, data_dir=shared_data)
        assert len(table) == n, split
        assert list(table.index) == list(range(n))
        assert list(table.columns) == list(whole.columns)  # the file's columns, glitch kept
        seen[split] = set(table["track"])
        parts.append(table)
    splits = list(seen)
    for i, a in enumerate(splits):
        for b in splits[i + 1 :]:
            assert not seen[a] & seen[b], (a, b)
    # Together the splits are the file: every row once, nothing changed.
    together = pd.concat(parts).sort_values(["track", "t"]).reset_index(drop=True)
    expected = whole.sort_values(["track", "t"]).reset_index(drop=True)
    pd.testing.assert_frame_equal(together, expected)


@pytest.mark.shared
@pytest.mark.parametrize("name", ["nl_motorway", "nl_motorway_gopro"])
def test_nl_splits_are_by_trip_never_by_receiver(shared_data: Path, name: str) -> None:
    receivers: dict[str, set[str]] = {}
    for split, trip in (("train", "trip01"), ("validation", "trip02"), ("test", "trip03")):
        tracks = set(load_dataset(name, split, data_dir=shared_data)["track"])
        assert {t.split("_")[0] for t in tracks} == {trip}
        receivers[split] = {t.split("_", 1)[1].rsplit("_", 1)[0] for t in tracks}
    # The same receivers (same car) in every split: the split is by trip.
    assert receivers["train"] == receivers["validation"] == receivers["test"]


@pytest.mark.shared
@pytest.mark.parametrize("name", ["ublox_f9k", "munich"])
@pytest.mark.parametrize("split", ["train", "validation"])
def test_test_only_sets_refuse_other_splits(shared_data: Path, name: str, split: str) -> None:
    with pytest.raises(ConfigError, match=rf"{name}.*test split only.*use split 'test'"):
        load_dataset(name, split, data_dir=shared_data)


@pytest.mark.shared
@pytest.mark.parametrize(
    ("name", "optional"),
    [
        ("nl_motorway", set()),
        ("nl_motorway_gopro", {"speed", "hdop"}),
        ("austin2006", set()),
        ("nevada", {"speed", "heading", "hdop"}),
        ("ublox_f9k", {"speed", "heading", "hdop"}),
        ("munich", set()),
    ],
)
def test_new_drives_columns_are_detected(shared_data: Path, name: str, optional: set[str]) -> None:
    from gradgps import to_fixes

    fixes = to_fixes(load_dataset(name, "test", data_dir=shared_data))
    cmap = fixes.attrs["columns"]
    assert (cmap.track, cmap.time, cmap.lat, cmap.lon) == ("track", "t", "lat", "lon")
    found = {c for c in ("speed", "heading", "alt", "hdop") if c in fixes.columns}
    assert found == optional
    spelled = {"speed": "speed_mps", "heading": "heading_deg", "hdop": "hdop"}
    assert {getattr(cmap, c) for c in optional} == {spelled[c] for c in optional}
    # fix and sats are the receiver's own fix quality and satellite count (read as such
    # where present: a no-fix epoch is flagged); glitch is a label, never an input.
    roles = {k: v for k, v in cmap.as_dict().items() if v}
    assert roles.get("fix_quality") in (None, "fix")
    assert roles.get("satellites") in (None, "sats")
    assert "glitch" not in roles.values()
