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

__all__ = ["DATASETS", "SIMULATED_SPLITS", "SPLITS", "find_data_dir", "load_dataset"]

DATASETS = (
    "driveplotr",
    "tuc",
    "nl_motorway",
    "nl_motorway_gopro",
    "austin2006",
    "nevada",
    "ublox_f9k",
    "munich",
    "simulated",
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
_TRACK_COLUMN = {"driveplotr": "drive", "tuc": "trace"}  # the newer files use `track`
# The newer files split by trip or household: track ids starting with these
# prefixes (shared/data/README.md); "train" is every other track. ``None``:
# the file is a test set only.
_HELD_OUT_PREFIX: dict[str, dict[str, str] | None] = {
    "nl_motorway": {"test": "trip03", "validation": "trip02"},
    "nl_motorway_gopro": {"test": "trip03", "validation": "trip02"},
    "austin2006": {"test": "austin_426309", "validation": "austin_425131"},
    "nevada": {"test": "garmin_nv2005_s2_00", "validation": "garmin_nv2005_s1_01"},
    "ublox_f9k": None,
    "munich": None,
}
# Held-out tracks; "train" is every other track in the file.
_HELD_OUT: dict[str, dict[str, tuple[object, ...]]] = {
    "driveplotr": {"test": (11, 14, 31), "validation": (9, 10, 12, 13, 15)},
    "tuc": {"test": ("chemnitz_city",), "validation": ("frankfurt_westend_tower",)},
}

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


def load_dataset(
    name: str, split: str = "test", *, data_dir: str | Path | None = None
) -> pd.DataFrame:
    """Rows of data set ``name`` (``driveplotr``, ``tuc`` or ``simulated``) in ``split``.

    Real data keeps the file's columns and row order (index 0..n-1).
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
    if name in _HELD_OUT_PREFIX:
        prefixes = _HELD_OUT_PREFIX[name]
        if prefixes is None:
            if split != "test":
                raise ConfigError(f"data set {name!r} is a test set only (no {split} split)")
            keep = pd.Series(True, index=table.index)
        else:
            ids = track.astype(str)
            if split == "train":
                keep = ~ids.str.startswith(tuple(prefixes.values()))
            else:
                keep = ids.str.startswith(prefixes[split])
    else:
        held = _HELD_OUT[name]
        if split == "train":
            keep = ~track.isin([v for ids in held.values() for v in ids])
        else:
            keep = track.isin(list(held[split]))
    out = table[keep.to_numpy()].reset_index(drop=True)
    out.attrs["source"] = f"{path} [{split}]"
    return out
