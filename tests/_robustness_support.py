"""Tiny stand-ins for the six drive files added on 2026-11-23, for shape tests.

Same file names, track ids (so the fixed splits apply), columns and rates as
the real files (see ../shared/data/README.md); simulated positions, a few
minutes each, so the robustness suite runs on them in seconds.
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from gradgps import simulate_fleet

#: file -> (track ids, rate Hz, extra columns, has a glitch column)
TINY_FILES: dict[str, tuple[list[str], float, list[str], bool]] = {
    "nl_motorway_1hz.csv": (
        ["trip01_phone_a_00", "trip02_phone_a_00", "trip03_phone_a_00", "trip03_usb_b_00"],
        1.0,
        [],
        False,
    ),
    "nl_motorway_gopro_1hz.csv": (
        ["trip01_gopro_max_00", "trip02_gopro_max_00", "trip03_gopro_max_00"],
        1.0,
        ["speed_mps", "hdop", "fix"],
        False,
    ),
    "austin2006_logger_1hz.csv": (
        ["austin_321180_2_00", "austin_425114_1_00", "austin_425131_1_00", "austin_426309_2_00"],
        1.0,
        [],
        True,
    ),
    "garmin_nmea_nevada2005.csv": (
        ["garmin_nv2005_s1_00", "garmin_nv2005_s1_01", "garmin_nv2005_s2_00"],
        0.5,
        ["speed_mps", "heading_deg", "hdop", "sats", "fix"],
        False,
    ),
    # 2 Hz, so that both decimations change the data here.
    "ublox_f9k_mtv_1hz.csv": (
        ["ublox_f9k_mtv_s0_00"],
        2.0,
        ["speed_mps", "heading_deg", "hdop", "sats", "fix"],
        False,
    ),
    "munich_bmw_1hz.csv": (["munich_x0001_00"], 1.0, [], True),
}


def write_tiny_new_drives(folder: Path, minutes: float = 2.5) -> None:
    """Write the six files into ``folder``."""
    for i, (name, (tracks, rate, extra, glitch)) in enumerate(TINY_FILES.items()):
        fleet = simulate_fleet(len(tracks), minutes, rate, seed=40 + i, imu=False)
        ids = dict(zip(sorted(fleet["track"].unique(), key=int), tracks, strict=True))
        out = pd.DataFrame(
            {
                "track": fleet["track"].map(ids),
                "t": fleet["t"].round(3),
                "lat": fleet["lat"],
                "lon": fleet["lon"],
            }
        )
        values = {
            "speed_mps": fleet["speed"],
            "heading_deg": fleet["heading"],
            "hdop": 0.9,
            "sats": 9,
            "fix": 1,
        }
        for col in extra:
            out[col] = values[col]
        if glitch:
            # A held position in the middle of the last track, marked like the real files.
            flag = pd.Series(0, index=out.index)
            last = out.index[out["track"] == tracks[-1]]
            held = last[len(last) // 2 : len(last) // 2 + 5]
            out.loc[held, ["lat", "lon"]] = out.loc[held[0], ["lat", "lon"]].to_numpy()
            flag[held] = 1
            out["glitch"] = flag
        out.to_csv(folder / name, index=False)
