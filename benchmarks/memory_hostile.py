"""Peak memory of ``gradgps detect`` (and ``detect-fleet``) on hostile inputs, every mode.

    python benchmarks/memory_hostile.py [--json benchmarks/results/memory_hostile.json]
        [--scale 1.0] [--only NAME]

The cases of issue 18, built in a temporary folder (never the repository):

* ``tiny-step``: 40,000 fixes 10 s apart with one 1.1 ms step after the first
  (an 830 KB CSV; on main batch asked for 32.5 GiB), run chunked (default),
  ``--chunk-size 0``, as Parquet, GPX and NMEA input, with ``--report``, and
  through ``detect-fleet``;
* ``tracks-tiny-step``: 3,000 tracks of 3 fixes, each with a 1.1 ms first step
  (on main 2.85 GB in chunked mode);
* ``long-line-gz`` / ``long-line``: a CSV whose third line is 256 MiB long
  (gzip, and plain; the issue's were 4 GiB and 1 GB: scaled down so a case runs
  in seconds, the reader stops at 1 MiB either way);
* ``wide-header``: a header of 1,000,000 columns (14 MB).

Each command runs in a child Python process that calls the CLI and reports its
own peak resident set size (``getrusage(RUSAGE_SELF).ru_maxrss``, the kernel's
high-water mark; for ``detect-fleet`` the larger of that and its worker
processes' ``RUSAGE_CHILDREN``) and exit code. About 290 MB of it is the
interpreter with pandas, numba and the compiled kernels loaded, before any
input is read. ``--scale`` multiplies the fix counts.
"""

from __future__ import annotations

import argparse
import datetime
import gzip
import json
import os
import platform
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from gradgps._io.nmea import nmea_checksum

# A child running the CLI with the given arguments, then printing its peak and exit code.
_RUN_CLI = """
import resource, sys
from gradgps._cli import main
code = 0
try:
    main.main(args=sys.argv[1:], standalone_mode=False)
except SystemExit as exc:
    code = exc.code or 0
except Exception as exc:
    print(f"{type(exc).__name__}: {exc}", file=sys.stderr)
    code = 1
"""
_PRINT_PEAK = """
print("MAXRSS_KB", peak, "EXIT", code)
"""
_CHILD = (
    _RUN_CLI
    + """
peak = max(
    resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,
    resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss,  # detect-fleet's workers
)
"""
    + _PRINT_PEAK
)
# A child reporting its own peak: VmHWM of /proc/self/status, the high-water mark of this
# process's memory map. Not getrusage's ru_maxrss: Linux carries that over from the parent
# across fork + exec, so a parent holding a big input would set a floor under the figure
# (_CHILD above keeps ru_maxrss for detect-fleet's workers, which VmHWM does not see).
VMHWM_CHILD = (
    _RUN_CLI
    + """
with open("/proc/self/status") as status:
    peak = next(int(line.split()[1]) for line in status if line.startswith("VmHWM:"))
"""
    + _PRINT_PEAK
)


def _tiny_step_fixes(n: int) -> pd.DataFrame:
    t = 1.7e9 + 10.0 * np.arange(n, dtype=float)
    t[1] = t[0] + 0.0011
    t[2:] = t[0] + 10.0 * np.arange(1, n - 1)
    rng = np.random.default_rng(0)
    return pd.DataFrame(
        {
            "time": t,
            "lat": 48.1 + np.arange(n) * 1e-5 + rng.normal(0, 1e-5, n),
            "lon": 11.5 + rng.normal(0, 1e-5, n),
        }
    )


def _gpx(fixes: pd.DataFrame, path: Path) -> None:
    with path.open("w") as out:
        out.write('<?xml version="1.0"?>\n<gpx version="1.1" creator="bench"><trk><trkseg>\n')
        for r in fixes.itertuples():
            stamp = pd.Timestamp(r.time, unit="s", tz="UTC").strftime("%Y-%m-%dT%H:%M:%S.%fZ")
            out.write(f'<trkpt lat="{r.lat:.8f}" lon="{r.lon:.8f}"><time>{stamp}</time></trkpt>\n')
        out.write("</trkseg></trk></gpx>\n")


def _nmea(fixes: pd.DataFrame, path: Path) -> None:
    def ddmm(value: float, width: int) -> str:
        deg = int(abs(value))
        return f"{deg:0{width}d}{(abs(value) - deg) * 60:07.4f}"

    with path.open("w") as out:
        for r in fixes.itertuples():
            ts = pd.Timestamp(r.time, unit="s", tz="UTC")
            body = (
                f"GPRMC,{ts.strftime('%H%M%S')}.{ts.microsecond // 1000:03d},A,"
                f"{ddmm(r.lat, 2)},N,{ddmm(r.lon, 3)},E,0.0,0.0,{ts.strftime('%d%m%y')},,,A"
            )
            out.write(f"${body}*{nmea_checksum(body):02X}\n")


def _cases(folder: Path, scale: float) -> list[tuple[str, list[str]]]:
    n = max(20, int(40_000 * scale))
    fixes = _tiny_step_fixes(n)
    csv = folder / "tiny_step.csv"
    fixes.to_csv(csv, index=False)
    fixes.to_parquet(folder / "tiny_step.parquet")
    _gpx(fixes, folder / "tiny_step.gpx")
    _nmea(fixes, folder / "tiny_step.nmea")
    fleet_in = folder / "fleet_in"
    fleet_in.mkdir()
    fixes.to_csv(fleet_in / "v1.csv", index=False)

    n_tracks = max(10, int(3_000 * scale))
    base = 1.7e9 + np.arange(n_tracks, dtype=float)
    tracks = pd.DataFrame(
        {
            "track": np.repeat(np.arange(n_tracks), 3),
            "time": np.column_stack([base, base + 0.0011, base + 1.0]).ravel(),
            "lat": 48.1,
            "lon": 11.5 + np.tile([0.0, 0.0, 1e-4], n_tracks),
        }
    )
    tracks_csv = folder / "tracks_tiny_step.csv"
    tracks.to_csv(tracks_csv, index=False)

    line = b"9" * 2**20
    with gzip.open(folder / "long_line.csv.gz", "wb", compresslevel=1) as out:
        out.write(b"time,lat,lon\n1,48,11\n")
        for _ in range(256):
            out.write(line)
        out.write(b"\n")
    with (folder / "long_line.csv").open("wb") as out:
        out.write(b"time,lat,lon\n1,48,11\n")
        for _ in range(256):
            out.write(line)
        out.write(b"\n")
    (folder / "wide.csv").write_text(",".join(f"c{i}" for i in range(10**6)) + "\n1\n")

    out = str(folder / "out.csv")
    return [
        ("tiny-step csv chunked", ["detect", str(csv), "-o", out]),
        ("tiny-step csv --chunk-size 0", ["detect", str(csv), "-o", out, "--chunk-size", "0"]),
        ("tiny-step parquet", ["detect", str(folder / "tiny_step.parquet"), "-o", out]),
        ("tiny-step gpx", ["detect", str(folder / "tiny_step.gpx"), "-o", out]),
        ("tiny-step nmea", ["detect", str(folder / "tiny_step.nmea"), "-o", out]),
        (
            "tiny-step csv --report",
            ["detect", str(csv), "-o", out, "--report", str(folder / "r.html")],
        ),
        (
            "tiny-step detect-fleet",
            ["detect-fleet", str(fleet_in), "-o", str(folder / "fleet_out"), "--workers", "1"],
        ),
        ("tracks-tiny-step csv chunked", ["detect", str(tracks_csv), "-o", out]),
        (
            "tracks-tiny-step csv --chunk-size 0",
            ["detect", str(tracks_csv), "-o", out, "--chunk-size", "0"],
        ),
        ("long-line-gz (256 MiB line)", ["detect", str(folder / "long_line.csv.gz"), "-o", out]),
        ("long-line (256 MiB line)", ["detect", str(folder / "long_line.csv"), "-o", out]),
        ("wide-header (10^6 columns)", ["detect", str(folder / "wide.csv"), "-o", out]),
    ]


def run_child(args: list[str], child: str = _CHILD) -> dict[str, object]:
    """Run ``gradgps`` with ``args`` in a child process that prints its peak memory
    (``child``: the script measuring it; this file's reads ``ru_maxrss``); its peak,
    exit code, last error line and wall time. One thread for numba and BLAS."""
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    start = time.perf_counter()
    proc = subprocess.run(
        [sys.executable, "-c", child, *args], capture_output=True, text=True, env=env, check=False
    )
    wall = time.perf_counter() - start
    last = [ln for ln in proc.stdout.splitlines() if ln.startswith("MAXRSS_KB")]
    if not last:
        return {"error": (proc.stderr or proc.stdout)[-500:], "wall_s": round(wall, 2)}
    _, kb, _, code = last[-1].split()
    errors = [ln for ln in proc.stderr.splitlines() if ln.strip()][-1:]
    return {
        "peak_rss_mb": round(int(kb) / 1024, 1),
        "exit_code": int(code),
        "error_line": errors[-1][:160] if errors and int(code) else "",
        "wall_s": round(wall, 2),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--json", type=Path)
    parser.add_argument("--scale", type=float, default=1.0)
    parser.add_argument("--only", default="")
    opts = parser.parse_args()
    results = []
    load_before = os.getloadavg()[0]
    with tempfile.TemporaryDirectory() as tmp:
        for name, args in _cases(Path(tmp), opts.scale):
            if opts.only and opts.only not in name:
                continue
            for leftover in ("out.csv", "r.html"):
                (Path(tmp) / leftover).unlink(missing_ok=True)
            row = {"case": name, **run_child(args)}
            if name.endswith("detect-fleet"):
                import shutil

                shutil.rmtree(Path(tmp) / "fleet_out", ignore_errors=True)
            results.append(row)
            print(json.dumps(row), flush=True)
    report = {
        "command": " ".join(["python", *sys.argv]),
        "date": datetime.datetime.now(datetime.UTC).isoformat(timespec="seconds"),
        "machine": f"{platform.machine()} {os.cpu_count()} CPUs, {platform.platform()}",
        "load_1min_before_after": [load_before, os.getloadavg()[0]],
        "results": results,
    }
    if opts.json:
        opts.json.write_text(json.dumps(report, indent=2) + "\n")


if __name__ == "__main__":
    main()
