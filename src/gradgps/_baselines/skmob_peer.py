"""The ``skmob-filter`` peer: scikit-mobility in its own virtual environment, run as a subprocess.

scikit-mobility 1.3.1 (its latest release) pins ``pandas<2``, ``geopandas<0.11``
and ``statsmodels<0.14``, so it cannot be installed next to gradgps (which needs
pandas 2 and numpy 2). On first use a virtual environment is created at
``$GRADGPS_SKMOB_VENV`` (default ``.venv-skmob`` in the current directory) with
``python -m venv`` and ``pip install scikit-mobility==1.3.1 "numpy<2" "shapely<2"``
(its python-igraph 0.9 has no wheel for Python 3.11 and is compiled: minutes); every call then
writes the fixes to a CSV file, runs :data:`RUNNER` there with that
environment's Python, and reads back which rows ``filtering.filter`` kept.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pandas as pd

from .._exceptions import ConfigError

__all__ = ["RUNNER", "SKMOB_REQUIREMENTS", "skmob_kept", "skmob_python"]

#: Its last release, and the pins its own metadata lacks: built against numpy 1 (pandas 1.5)
#: and importing ``shapely.ops.cascaded_union`` (gone in shapely 2).
SKMOB_REQUIREMENTS = ("scikit-mobility==1.3.1", "numpy<2", "shapely<2")

#: Runs inside the scikit-mobility environment: argv = input CSV, speeds JSON, output JSON.
RUNNER = r"""
import json, sys, time, warnings
warnings.simplefilter("ignore")
import pandas as pd
import skmob
from skmob.preprocessing import filtering

df = pd.read_csv(sys.argv[1])
df["datetime"] = pd.to_datetime(df["t"], unit="s")
tdf = skmob.TrajDataFrame(df, latitude="lat", longitude="lng", datetime="datetime", user_id="uid")
out = []
for v in json.loads(sys.argv[2]):
    began = time.perf_counter()
    kept = filtering.filter(tdf, max_speed_kmh=float(v))
    out.append({"kept": [int(r) for r in kept["row"]], "seconds": time.perf_counter() - began})
json.dump(out, open(sys.argv[3], "w"))
"""


def _venv() -> Path:
    return Path(os.environ.get("GRADGPS_SKMOB_VENV") or Path.cwd() / ".venv-skmob")


def skmob_python() -> Path:
    """The Python of the scikit-mobility environment; created first (minutes) if missing."""
    venv = _venv()
    python = venv / "bin" / "python"
    stamp = venv / ".stamp-skmob"
    if stamp.is_file():
        return python
    wanted = " ".join(SKMOB_REQUIREMENTS)
    print(f"[skmob-filter] creating {venv} ({wanted}; minutes)", file=sys.stderr)
    try:
        subprocess.run([sys.executable, "-m", "venv", "--clear", str(venv)], check=True)
        subprocess.run(
            [str(python), "-m", "pip", "install", "-q", *SKMOB_REQUIREMENTS],
            check=True,
            capture_output=True,
            text=True,
        )
    except subprocess.CalledProcessError as exc:
        tail = (exc.stderr or "").strip().splitlines()[-1:] or [""]
        raise ConfigError(
            f"detector 'skmob-filter': could not install {wanted} into {venv}: {tail[0]}"
        ) from exc
    stamp.write_text(wanted + "\n")
    return python


def skmob_kept(
    tracks: Sequence[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]],
    speeds_kmh: Sequence[float],
) -> tuple[list[np.ndarray], list[float]]:
    """Rows ``filtering.filter(tdf, max_speed_kmh=v)`` keeps, for each ``v``; and seconds each took.

    ``tracks``: per track ``(rows, t, lat, lon)`` in time order (one user each).
    """
    python = skmob_python()
    frame = pd.concat(
        [
            pd.DataFrame({"row": rows, "uid": k, "t": t, "lat": lat, "lng": lon})
            for k, (rows, t, lat, lon) in enumerate(tracks)
        ],
        ignore_index=True,
    )
    with tempfile.TemporaryDirectory() as tmp:
        src, out, script = Path(tmp, "fixes.csv"), Path(tmp, "kept.json"), Path(tmp, "run.py")
        frame.to_csv(src, index=False, float_format="%.9f")
        script.write_text(RUNNER)
        done = subprocess.run(
            [str(python), str(script), str(src), json.dumps(list(speeds_kmh)), str(out)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            last = done.stderr.strip().splitlines()[-1:] or [""]
            raise ConfigError(f"detector 'skmob-filter' failed in {python}: {last[0]}")
        result = json.loads(out.read_text())
    return (
        [np.asarray(r["kept"], dtype=np.int64) for r in result],
        [float(r["seconds"]) for r in result],
    )
