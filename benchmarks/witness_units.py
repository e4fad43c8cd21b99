"""A reported speed or heading in the wrong unit or convention: what the detector flags, and
whether ``gradgps detect`` says so.

Why: most logs carry speed, if at all, under a plain name (``speed``), and the readers take
such a column as m/s; phone apps, GPX exports and OBD loggers often write km/h, mph or
knots, and some write the course in radians or counter-clockwise from east. The model
reads a reported speed and heading as independent witnesses of the motion, so one that
contradicts the positions looks like a fault on every clean fix. This takes one clean real
drive with a Doppler speed and course (the Nevada Garmin's training drive, 0.5 Hz; a
training split, never a test one), writes it as a user's CSV file (t, lat, lon, speed,
heading) once as it is and once per mix-up, runs ``gradgps detect`` on each with the
shipped model (or ``--model``), in batch and with ``--follow``, and prints the share of
fixes flagged by each and batch's warning line, if any. Run:

    python benchmarks/witness_units.py [--model DIR] [--data-dir DIR]

``benchmarks/results/witness_units_before_follow_fix.txt`` is this script run on the
sources of commit 437ec95 (``git worktree add ../old 437ec95`` and
``PYTHONPATH=../old/src``), before ``--follow`` read a ``speed_kmh`` column in km/h.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import tempfile
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._data.datasets import load_dataset

TRACK = "garmin_nv2005_s1_00"

#: Each variant: a name, what it does to the (speed m/s, heading degrees) columns, and
#: whether the file keeps its heading.
VARIANTS: tuple[tuple[str, Callable[[pd.DataFrame], pd.DataFrame], bool], ...] = (
    ("as recorded (m/s, degrees from north)", lambda d: d, True),
    ("speed in km/h", lambda d: d.assign(speed=d["speed"] * 3.6), True),
    ("speed in mph", lambda d: d.assign(speed=d["speed"] / 0.44704), True),
    ("speed in knots", lambda d: d.assign(speed=d["speed"] / 0.514444), True),
    ("speed in km/h, no heading column", lambda d: d.assign(speed=d["speed"] * 3.6), False),
    (
        "speed in km/h in a column named speed_kmh",
        lambda d: d.assign(speed=d["speed"] * 3.6).rename(columns={"speed": "speed_kmh"}),
        True,
    ),
    ("heading in radians", lambda d: d.assign(heading=np.radians(d["heading"])), True),
    (
        "heading counter-clockwise from east",
        lambda d: d.assign(heading=(90.0 - d["heading"]) % 360.0),
        True,
    ),
)


def user_file(data_dir: str | None) -> pd.DataFrame:
    """The drive as a user's file: t, lat, lon, speed (m/s), heading (degrees)."""
    table = load_dataset("nevada", "train", data_dir=data_dir)
    drive = table[table["track"] == TRACK]
    return pd.DataFrame(
        {
            "t": drive["t"].to_numpy(),
            "lat": drive["lat"].to_numpy(),
            "lon": drive["lon"].to_numpy(),
            "speed": drive["speed_mps"].to_numpy(),
            "heading": drive["heading_deg"].to_numpy(),
        }
    )


def detect(
    path: Path, out: Path, model: str | None, *, follow: bool = False
) -> tuple[float, list[str]]:
    """Share of rows flagged by ``gradgps detect`` (``--follow``: reading ``path`` as a
    stream), and its warning lines."""
    cmd = [sys.executable, "-m", "gradgps", "detect", str(path), "-o", str(out)]
    if follow:
        cmd.append("--follow")
    if model is not None:
        cmd += ["--model", model]
    run = subprocess.run(cmd, capture_output=True, text=True, check=True)
    flagged = float(pd.read_csv(out)["anomaly"].mean())
    return flagged, [line for line in run.stderr.splitlines() if line.startswith("warning: ")]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", default=None, help="model directory (default: shipped)")
    parser.add_argument("--data-dir", default=None)
    args = parser.parse_args()
    base = user_file(args.data_dir)
    print(f"nevada train drive {TRACK}: {len(base):,} fixes, 0.5 Hz, written as a user's CSV")
    print("| the file's speed and heading | fixes flagged | with --follow | warning |")
    print("|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for name, change, keep_heading in VARIANTS:
            data = change(base)
            if not keep_heading:
                data = data.drop(columns=["heading"])
            src, out = Path(tmp) / "in.csv", Path(tmp) / "out.csv"
            data.to_csv(src, index=False)
            flagged, warnings = detect(src, out, args.model)
            streamed, _ = detect(src, out, args.model, follow=True)
            said = "; ".join(w.removeprefix("warning: ") for w in warnings) or "none"
            print(f"| {name} | {100 * flagged:.1f} % | {100 * streamed:.1f} % | {said} |")


if __name__ == "__main__":
    main()
