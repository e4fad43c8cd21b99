"""Peak memory of ``gradgps detect`` against input size, in every mode (issue 18).

    python benchmarks/memory_modes.py --json benchmarks/results/memory_modes.json
        [--sizes-mb 10 50 100] [--only MODE ...]
    python benchmarks/memory_modes.py --refit benchmarks/results/memory_modes.json

For each size a fleet log of about that many megabytes of CSV is built from
simulated drives (``gradgps.simulate_fleet``: 100 drives at 1 Hz, repeated
under new track ids and shifted in time, as in ``benchmarks/memory_10m.py``)
in a temporary folder (never the repository), and written again as Parquet
(one file), GPX (one ``<trk>`` per track) and NMEA (one receiver: the tracks
one after another, RMC sentences). Then ``gradgps detect`` runs on it in each
mode:

* ``csv chunked``: the default (``--chunk-size 200000``);
* ``csv --chunk-size 0``: the largest chunks the memory bound allows (it read the
  whole file at once before issue 18's round three);
* ``parquet``, ``gpx``, ``nmea``: those inputs (same fixes; the files'
  sizes differ, each is recorded);
* ``csv --report``: chunked detection plus the HTML report;
* ``geoparquet``: the fixes as GeoParquet (WKB points, ``geo`` metadata);
* ``rosbag``: the fixes as a ROS 1 bag (``sensor_msgs/NavSatFix`` on one
  topic per 100 tracks, so several receivers interleave);
* ``csv --geojson --gpx``: chunked detection writing both exports;
* ``detect-fleet``: the CSV as one vehicle's file of a fleet directory,
  ``detect-fleet --workers 1`` (peak: the larger of the process and its Dask
  worker processes, ``ru_maxrss`` of the children, which needs the processes
  ended; for this mode only, since ``VmHWM`` does not see the workers);
* ``geojson``: the fixes as GeoJSON Point features (read in chunks since
  issue 18, two streaming passes with ijson; about twice a CSV's size, and
  slow: a few MB/s of GeoJSON per pass on the 2-core machine).

Each command runs in a child Python process that calls the CLI and reports its
own peak resident set size (``VmHWM`` in ``/proc/self/status``: the kernel's
high-water mark of the process's memory, nothing sampled; not ``ru_maxrss``,
which Linux carries over from the parent across fork and exec, so that the
parent's size, holding the input it built, would be a floor under every figure). The baseline (interpreter, pandas, numba,
the compiled kernels) is measured by the same child on a 10-row file. For each
mode a least-squares line through (input MB, peak MB) gives the growth per MB
of input, and its extrapolation to a 1 GB input of that format (an
extrapolation: 2-core shared machine, nothing above a few hundred MB is run
here); so does the line through the two largest sizes alone, which is the
one that tells for a bounded mode (its peak stops growing once a chunk, 200,000
rows by default, is full, so a line through a smaller size overstates it). Machine, load and command go into the JSON.
"""

from __future__ import annotations

import argparse
import datetime
import json
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd
from memory_hostile import _CHILD, VMHWM_CHILD, run_child

from gradgps import simulate_fleet
from gradgps._io.nmea import nmea_checksum

_BLOCK = 100  # tracks simulated once and repeated
_BYTES_PER_ROW = 64.0  # of the CSV below, measured: sizes are approximate

MODES = (
    "csv chunked",
    "csv --chunk-size 0",
    "parquet",
    "gpx",
    "nmea",
    "csv --report",
    "geoparquet",
    "rosbag",
    "csv --geojson --gpx",
    "detect-fleet",
    "geojson",
)


def _fleet(rows: int) -> pd.DataFrame:
    """About ``rows`` fixes: blocks of 100 simulated 1 Hz drives, interleaved by time."""
    per_track = max(10, rows // (4 * _BLOCK))  # 4 blocks at least: several hundred tracks
    base = simulate_fleet(_BLOCK, per_track / 60.0, 1.0, seed=7, imu=False)
    base = base.groupby("track", sort=False).head(per_track)
    base = base.sort_values("t", kind="stable").reset_index(drop=True)
    number = base["track"].astype(int).to_numpy()
    blocks = []
    for block in range(max(1, rows // len(base))):
        copy = base.copy()
        copy["track"] = (number + block * _BLOCK).astype(str)
        copy["t"] = copy["t"] + 3600.0 * block
        copy["lat"] = copy["lat"] + 0.01 * block
        blocks.append(copy)
    return pd.concat(blocks, ignore_index=True)


def _gpx(fixes: pd.DataFrame, path: Path) -> None:
    with path.open("w") as out:
        out.write('<?xml version="1.0"?>\n<gpx version="1.1" creator="bench">\n')
        for track, rows in fixes.groupby("track", sort=False):
            stamps = pd.to_datetime(rows["t"].to_numpy(), unit="s", utc=True).strftime(
                "%Y-%m-%dT%H:%M:%S.%fZ"
            )
            out.write(f"<trk><name>{track}</name><trkseg>\n")
            out.writelines(
                f'<trkpt lat="{lat:.8f}" lon="{lon:.8f}"><time>{s}</time>'
                f"<speed>{v:.2f}</speed></trkpt>\n"
                for lat, lon, s, v in zip(
                    rows["lat"], rows["lon"], stamps, rows["speed"], strict=True
                )
            )
            out.write("</trkseg></trk>\n")
        out.write("</gpx>\n")


def _nmea(fixes: pd.DataFrame, path: Path) -> None:
    """One receiver: the tracks one after another (each shifted to start after the last)."""
    parts, end = [], 0.0
    for _, rows in fixes.groupby("track", sort=False):
        t = rows["t"].to_numpy() - rows["t"].iloc[0] + end
        end = t[-1] + 1.0
        parts.append(rows.assign(t=t))
    one = pd.concat(parts, ignore_index=True)
    stamps = pd.to_datetime(1.7e9 + one["t"].to_numpy(), unit="s", utc=True)
    hms = stamps.strftime("%H%M%S.%f").str[:-3]
    dmy = stamps.strftime("%d%m%y")

    def ddmm(values: np.ndarray, width: int) -> list[str]:
        deg = np.floor(np.abs(values)).astype(int)
        minutes = (np.abs(values) - deg) * 60
        return [f"{d:0{width}d}{m:07.4f}" for d, m in zip(deg, minutes, strict=True)]

    lat, lon = ddmm(one["lat"].to_numpy(), 2), ddmm(one["lon"].to_numpy(), 3)
    ns = np.where(one["lat"].to_numpy() >= 0, "N", "S")
    ew = np.where(one["lon"].to_numpy() >= 0, "E", "W")
    knots = one["speed"].to_numpy() / 0.514444
    with path.open("w") as out:
        for i in range(len(one)):
            body = (
                f"GPRMC,{hms[i]},A,{lat[i]},{ns[i]},{lon[i]},{ew[i]},{knots[i]:.1f},"
                f"{one['heading'].iat[i]:.1f},{dmy[i]},,,A"
            )
            out.write(f"${body}*{nmea_checksum(body):02X}\n")


def _geoparquet(fixes: pd.DataFrame, path: Path) -> None:
    """GeoParquet 1.0 with WKB points (little-endian, type 1) and no CRS (OGC:CRS84)."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    n = len(fixes)
    wkb = np.zeros(n, np.dtype([("order", "u1"), ("kind", "<u4"), ("x", "<f8"), ("y", "<f8")]))
    wkb["order"], wkb["kind"] = 1, 1
    wkb["x"], wkb["y"] = fixes["lon"].to_numpy(), fixes["lat"].to_numpy()
    points = pa.Array.from_buffers(pa.binary(21), n, [None, pa.py_buffer(wkb.tobytes())])
    table = pa.Table.from_pandas(fixes.drop(columns=["lat", "lon"]), preserve_index=False)
    table = table.append_column("geometry", points.cast(pa.binary()))
    geo = {
        "version": "1.0.0",
        "primary_column": "geometry",
        "columns": {"geometry": {"encoding": "WKB", "geometry_types": ["Point"]}},
    }
    metadata = {**(table.schema.metadata or {}), b"geo": json.dumps(geo).encode()}
    pq.write_table(table.replace_schema_metadata(metadata), path)


def _rosbag(fixes: pd.DataFrame, path: Path) -> None:
    """A ROS 1 bag: a NavSatFix per fix, on topic ``/gps<k>/fix`` for tracks ``k*100..``."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    types = store.types
    fix_type = "sensor_msgs/msg/NavSatFix"
    status = types["sensor_msgs/msg/NavSatStatus"](status=0, service=1)
    covariance = np.zeros(9)
    group = fixes["track"].astype(int).to_numpy() // 100
    with Writer(path) as writer:
        connections = {
            int(k): writer.add_connection(f"/gps{k}/fix", fix_type, typestore=store)
            for k in np.unique(group)
        }
        for k, t, lat, lon in zip(
            group.tolist(),
            fixes["t"].tolist(),
            fixes["lat"].tolist(),
            fixes["lon"].tolist(),
            strict=True,
        ):
            stamp = t  # unix seconds
            sec = int(stamp)
            header = types["std_msgs/msg/Header"](
                seq=0,
                stamp=types["builtin_interfaces/msg/Time"](
                    sec=sec, nanosec=round((stamp - sec) * 1e9)
                ),
                frame_id="gps",
            )
            message = types[fix_type](
                header=header,
                status=status,
                latitude=lat,
                longitude=lon,
                altitude=500.0,
                position_covariance=covariance,
                position_covariance_type=0,
            )
            writer.write(connections[k], int(stamp * 1e9), store.serialize_ros1(message, fix_type))


def _geojson(fixes: pd.DataFrame, path: Path) -> None:
    with path.open("w") as out:
        out.write('{"type":"FeatureCollection","features":[')
        for i, (track, t, lat, lon) in enumerate(
            zip(fixes["track"], fixes["t"], fixes["lat"], fixes["lon"], strict=True)
        ):
            out.write(
                ("," if i else "")
                + '{"type":"Feature","geometry":{"type":"Point","coordinates":'
                + f'[{lon!r},{lat!r}]}},"properties":{{"track":"{track}","t":{t!r}}}}}'
            )
        out.write("]}")


def _inputs(folder: Path, size_mb: float, formats: set[str]) -> dict[str, Path]:
    """The fixes of a ``size_mb`` CSV, written in each of ``formats`` (Parquet always: the
    fix count is read from it)."""
    fixes = _fleet(int(size_mb * 1e6 / _BYTES_PER_ROW))
    writers = {
        "csv": lambda path: fixes.to_csv(path, index=False),
        "parquet": lambda path: fixes.to_parquet(path, index=False),
        "gpx": lambda path: _gpx(fixes, path),
        "nmea": lambda path: _nmea(fixes, path),
        "geoparquet": lambda path: _geoparquet(fixes, path),
        "rosbag": lambda path: _rosbag(fixes, path),
        "geojson": lambda path: _geojson(fixes, path),
    }
    paths = {}
    for kind, write in writers.items():
        if kind in formats or kind == "parquet":
            suffix = {"geoparquet": "parquet", "rosbag": "bag"}.get(kind, kind)
            paths[kind] = folder / f"fleet_{size_mb:g}_{kind}.{suffix}"
            write(paths[kind])
    if "detect-fleet" in formats:  # the CSV as one vehicle's file
        vehicles = folder / f"fleet_{size_mb:g}_dir"
        vehicles.mkdir()
        os.link(paths["csv"], vehicles / "vehicle.csv")
        paths["detect-fleet"] = vehicles
    return paths


def _command(mode: str, paths: dict[str, Path], out: Path) -> list[str]:
    if mode == "csv chunked":
        return ["detect", str(paths["csv"]), "-o", str(out)]
    if mode == "csv --chunk-size 0":
        return ["detect", str(paths["csv"]), "-o", str(out), "--chunk-size", "0"]
    if mode == "csv --report":
        report = out.with_name("report.html")
        return ["detect", str(paths["csv"]), "-o", str(out), "--report", str(report)]
    if mode == "csv --geojson --gpx":
        geo, gpx = out.with_name("out.geojson"), out.with_name("out.gpx")
        return [
            "detect",
            str(paths["csv"]),
            "-o",
            str(out),
            "--geojson",
            str(geo),
            "--gpx",
            str(gpx),
        ]
    if mode == "detect-fleet":
        return [
            "detect-fleet",
            str(paths[mode]),
            "-o",
            str(out.with_name("fleet_out")),
            "--workers",
            "1",
        ]
    return ["detect", str(paths[mode]), "-o", str(out)]


def _input_of(mode: str) -> str:
    return "csv" if mode == "detect-fleet" else mode.split()[0]


# Runs children for this process, started before any input is built (see _Launcher).
_LAUNCHER = """
import json, sys
from memory_hostile import run_child
for line in sys.stdin:
    args, child = json.loads(line)
    print(json.dumps(run_child(args, child)), flush=True)
"""


class _Launcher:
    """A small process, started before any input is built, that starts the measured children.

    detect-fleet's peak is read as ``ru_maxrss`` of the children (its Dask worker
    processes, which ``VmHWM`` of the CLI's process does not see), and Linux carries a
    process's ``ru_maxrss`` over into the children it forks and execs: started from this
    process, holding the inputs it built (a gigabyte at 100 MB of CSV), the figure would
    be this process's peak (it was: 1,039 MB at 1.56 M fixes, where the worker peaked
    at 473 MB at 781,200 fixes, sampled). The launcher's own peak is the floor instead.
    """

    def __init__(self) -> None:
        self._proc = subprocess.Popen(
            [sys.executable, "-c", _LAUNCHER],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
            cwd=Path(__file__).parent,
        )

    def run(self, args: list[str], child: str) -> dict[str, object]:
        assert self._proc.stdin is not None
        assert self._proc.stdout is not None
        self._proc.stdin.write(json.dumps([args, child]) + "\n")
        self._proc.stdin.flush()
        done: dict[str, object] = json.loads(self._proc.stdout.readline())
        return done


_launcher: _Launcher | None = None


def _run(args: list[str]) -> dict[str, object]:
    # The child's own peak (VmHWM), not ru_maxrss, which carries the parent's size; for
    # detect-fleet, whose work is done in Dask worker processes, ru_maxrss of the children,
    # started from the launcher.
    if args[0] != "detect-fleet":
        return run_child(args, VMHWM_CHILD)
    assert _launcher is not None
    return _launcher.run(args, _CHILD)


def _fit(rows: list[dict[str, object]]) -> dict[str, float] | None:
    """Least-squares growth of the peak with input size (MB) and with fixes (millions)."""
    done = [r for r in rows if "peak_rss_mb" in r]
    if len(done) < 2:
        return None
    mb = np.array([float(str(r["input_mb"])) for r in done])
    fixes = np.array([float(str(r["fixes"])) for r in done])
    peak = np.array([float(str(r["peak_rss_mb"])) for r in done])
    slope, intercept = np.polyfit(mb, peak, 1)
    per_fix = np.polyfit(fixes / 1e6, peak, 1)[0]
    # A bounded mode's peak stops growing once a chunk is full: a line through all sizes
    # (the smallest below one chunk) overstates its growth; the two largest sizes tell.
    order = np.argsort(mb)
    a, b = order[-2], order[-1]
    tail = (peak[b] - peak[a]) / (mb[b] - mb[a]) if mb[b] > mb[a] else float("nan")
    return {
        "mb_per_input_mb": round(float(slope), 3),
        "mb_per_million_fixes": round(float(per_fix), 1),
        "intercept_mb": round(float(intercept), 1),
        "extrapolated_peak_mb_at_1000_mb_input": round(float(intercept + 1000 * slope)),
        "mb_per_input_mb_between_two_largest": round(float(tail), 3),
        "extrapolated_peak_mb_at_1000_mb_input_from_two_largest": round(
            float(peak[b] + (1000 - mb[b]) * tail)
        ),
    }


def _source() -> str:
    """Which gradgps ran: its package folder and, in a git checkout, the commit."""
    import gradgps

    folder = Path(gradgps.__file__).resolve().parent
    try:
        commit = subprocess.run(
            ["git", "-C", str(folder), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
            check=True,
        ).stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        commit = "not a git checkout"
    return f"{folder} ({commit})"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--sizes-mb", type=float, nargs="+", default=[10.0, 50.0, 100.0])
    parser.add_argument("--only", nargs="*", default=[], help="modes to run (default: all)")
    parser.add_argument("--note", default="", help="stored in the JSON (e.g. which code ran)")
    parser.add_argument(
        "--refit", type=Path, help="recompute the growth lines of a results JSON, in place"
    )
    opts = parser.parse_args()
    if opts.refit is not None:
        done = json.loads(opts.refit.read_text())
        found = {str(r["mode"]) for r in done["results"]}
        done["growth"] = {
            m: _fit([r for r in done["results"] if r["mode"] == m]) for m in MODES if m in found
        }
        opts.refit.write_text(json.dumps(done, indent=2) + "\n")
        print(json.dumps(done["growth"], indent=2))
        return
    modes = [m for m in MODES if not opts.only or m in opts.only]
    global _launcher
    _launcher = _Launcher()
    rows: list[dict[str, object]] = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory(prefix="gradgps-memmodes-") as tmp:
        folder = Path(tmp)
        tiny = folder / "tiny.csv"
        tiny.write_text("t,lat,lon\n" + "".join(f"{i},48.1,{11.5 + i * 1e-4}\n" for i in range(10)))
        baseline = _run(["detect", str(tiny), "-o", str(folder / "tiny_out.csv")])
        print(json.dumps({"baseline": baseline}), flush=True)
        for size in opts.sizes_mb:
            started = time.perf_counter()
            paths = _inputs(folder, size, {_input_of(m) for m in modes} | set(modes))
            sizes = {k: p.stat().st_size for k, p in paths.items()}
            n_fixes = len(pd.read_parquet(paths["parquet"], columns=["t"]))
            print(
                f"built {size:g} MB inputs in {time.perf_counter() - started:.0f} s",
                file=sys.stderr,
            )
            for mode in modes:
                out = folder / "out.csv"
                row = {
                    "mode": mode,
                    "fixes": n_fixes,
                    "input_mb": round(sizes[_input_of(mode)] / 1e6, 2),
                    **_run(_command(mode, paths, out)),
                }
                for leftover in ("report.html", "out.geojson", "out.gpx"):
                    (folder / leftover).unlink(missing_ok=True)
                out.unlink(missing_ok=True)
                shutil.rmtree(folder / "fleet_out", ignore_errors=True)
                rows.append(row)
                print(json.dumps(row), flush=True)
            for p in paths.values():
                shutil.rmtree(p) if p.is_dir() else p.unlink()
    fits = {mode: _fit([r for r in rows if r["mode"] == mode]) for mode in modes}
    report = {
        "command": " ".join(["python", *sys.argv]),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()} {os.cpu_count()} CPUs, {platform.platform()}",
        "gradgps": _source(),
        "note": opts.note,
        "load_1min_before_after": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "baseline_10_rows": baseline,
        "results": rows,
        "growth": fits,
    }
    print(json.dumps(report["growth"], indent=2))
    if opts.json:
        opts.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
