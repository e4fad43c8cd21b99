"""The benchmark data sets and their fixed splits.

Numbers are only comparable when every run uses the same drives for the same
purpose, so the splits live here, once (they follow
``../shared/data/README.md``). Tables come back with their original columns;
:func:`gradgps.to_fixes` finds track, time and position in them.
"""

from __future__ import annotations

import os
from pathlib import Path

import pandas as pd

from .._exceptions import ConfigError, DataNotFoundError

__all__ = [
    "DATASETS",
    "SIMULATED_SPLITS",
    "SPLITS",
    "TEST_ONLY",
    "find_data_dir",
    "load_dataset",
]

DATASETS = (
    "driveplotr",
    "tuc",
    "simulated",
    "nl_motorway",
    "nl_motorway_gopro",
    "austin2006",
    "nevada",
    "ublox_f9k",
    "munich",
)
SPLITS = ("train", "validation", "test")

_FILES = {
    "driveplotr": "driveplotr_nds.csv",
    "tuc": "tuc_urban_gt.csv",
    "nl_motorway": "nl_motorway_1hz.csv",
    "nl_motorway_gopro": "nl_motorway_gopro_1hz.csv",
    "austin2006": "austin2006_logger_1hz.csv",
    "nevada": "garmin_nmea_nevada2005.csv",
    "ublox_f9k": "ublox_f9k_mtv_1hz.csv",
    "munich": "munich_bmw_1hz.csv",
}
_TRACK_COLUMN = {"driveplotr": "drive", "tuc": "trace"}  # the others: "track"
# Held-out tracks; "train" is every other track in the file.
_HELD_OUT: dict[str, dict[str, tuple[object, ...]]] = {
    "driveplotr": {"test": (11, 14, 31), "validation": (9, 10, 12, 13, 15)},
    "tuc": {"test": ("chemnitz_city",), "validation": ("frankfurt_westend_tower",)},
}
# The drives added on 2026-11-23: each split is the tracks whose id starts with one of
# these prefixes (by trip or household, never by receiver: the NL receivers rode in
# one car together).
_NL: dict[str, tuple[str, ...]] = {
    "train": ("trip01",),
    "validation": ("trip02",),
    "test": ("trip03",),
}
_BY_PREFIX: dict[str, dict[str, tuple[str, ...]]] = {
    "nl_motorway": _NL,
    "nl_motorway_gopro": _NL,
    "austin2006": {
        "train": ("austin_321180", "austin_425114"),
        "validation": ("austin_425131",),
        "test": ("austin_426309",),
    },
    "nevada": {
        "train": ("garmin_nv2005_s1_00",),
        "validation": ("garmin_nv2005_s1_01",),
        "test": ("garmin_nv2005_s2_00",),
    },
}
#: Data sets with a test split only (every row is test): too small or too unlike the
#: others to train on, kept for measuring.
TEST_ONLY = ("ublox_f9k", "munich")

#: (n_tracks, minutes, rate_hz, seed) of the simulated fleet for each split; distinct
#: seeds so no simulated drive appears in two splits.
SIMULATED_SPLITS: dict[str, tuple[int, float, float, int]] = {
    "train": (40, 10.0, 1.0, 20_250_001),
    "validation": (10, 10.0, 1.0, 20_250_002),
    "test": (10, 10.0, 1.0, 20_250_003),
}


def find_data_dir(data_dir: str | Path | None = None) -> Path:
    """The folder holding the shared drives: ``data_dir``, else ``$GRADGPS_DATA``, else ``../shared/data``.

    The last one is relative to the current directory (a checkout next to
    ``shared/``). Raises :class:`DataNotFoundError` naming where it looked.
    """
    if data_dir is not None:
        candidates = [("--data-dir", Path(data_dir))]
    elif os.environ.get("GRADGPS_DATA"):
        candidates = [("$GRADGPS_DATA", Path(os.environ["GRADGPS_DATA"]))]
    else:
        candidates = [("default", Path.cwd().parent / "shared" / "data")]
    how, path = candidates[0]
    if not path.is_dir():
        raise DataNotFoundError(
            f"data folder not found: {path} ({how}); pass --data-dir DIR or set GRADGPS_DATA "
            f"to the folder holding {', '.join(_FILES.values())}"
        )
    return path


def _check(name: str, split: str) -> None:
    if name not in DATASETS:
        raise ConfigError(f"unknown dataset {name!r}; choose one of {', '.join(DATASETS)}")
    if split not in SPLITS:
        raise ConfigError(f"unknown split {split!r}; choose one of {', '.join(SPLITS)}")
    if name in TEST_ONLY and split != "test":
        raise ConfigError(
            f"data set {name!r} has a test split only (see shared/data/README.md): "
            f"it is for measuring, not for {split}; use split 'test' or another data set"
        )


def load_dataset(
    name: str, split: str = "test", *, data_dir: str | Path | None = None
) -> pd.DataFrame:
    """Rows of data set ``name`` (one of :data:`DATASETS`) in ``split``.

    Real data keeps the file's columns (``glitch`` included, where a file has
    it) and row order (index 0..n-1). The drives added on 2026-11-23 have
    their track id in ``track`` and time in ``t``; ``ublox_f9k`` and
    ``munich`` have a test split only (:data:`TEST_ONLY`): other splits are a
    :class:`ConfigError`.
    ``simulated`` calls the fleet simulator with the split's fixed settings
    (:data:`SIMULATED_SPLITS`) and names its sensor channels as in the
    DrivePlotR file (``accel_x`` -> ``accel_x_mps2``, ``yaw_rate`` ->
    ``gyro_z_dps``) so both sensor protocols run on it unchanged.
    """
    _check(name, split)
    if name == "simulated":
        # Written alongside this module; the ignore covers checkouts that lack it.
        from .simulator import simulate_fleet  # type: ignore[import-not-found,unused-ignore]

        n_tracks, minutes, rate_hz, seed = SIMULATED_SPLITS[split]
        fleet: pd.DataFrame = simulate_fleet(n_tracks, minutes, rate_hz, seed)
        renamed: pd.DataFrame = fleet.rename(
            columns={"accel_x": "accel_x_mps2", "yaw_rate": "gyro_z_dps"}
        )
        return renamed
    path = find_data_dir(data_dir) / _FILES[name]
    if not path.is_file():
        raise DataNotFoundError(
            f"{path} not found; the data folder must hold {_FILES[name]} "
            "(see shared/data/README.md), pass --data-dir DIR or set GRADGPS_DATA"
        )
    table = pd.read_csv(path)
    track = table[_TRACK_COLUMN.get(name, "track")]
    if name in TEST_ONLY:
        keep = pd.Series(True, index=table.index)
    elif name in _BY_PREFIX:
        ids = track.astype(str)
        keep = ids.str.startswith(_BY_PREFIX[name][split])
    elif split == "train":
        keep = ~track.isin([v for ids in _HELD_OUT[name].values() for v in ids])
    else:
        keep = track.isin(list(_HELD_OUT[name][split]))
    out = table[keep.to_numpy()].reset_index(drop=True)
    out.attrs["source"] = f"{path} [{split}]"
    return out
