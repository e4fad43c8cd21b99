"""Offline fleet logs on a Dask cluster: one task per vehicle, no shuffle.

A fleet's log is a directory partitioned by vehicle, in one of two layouts
(both may be mixed in one directory):

* one file per vehicle: ``INPUT_DIR/<vehicle>.parquet`` (or ``.csv``,
  ``.csv.gz``...), the vehicle id being the file name without extensions;
* a hive-partitioned dataset: ``INPUT_DIR/<key>=<vehicle>/<part files>``,
  as written by pyarrow, Spark or ``dask.dataframe.to_parquet(partition_on=
  ...)``; the vehicle id is the (URL-decoded) value, the part files are read
  in name order and their rows joined.

Why one task per vehicle and not a Dask DataFrame: GRAD is a sequential
filter over each vehicle's fixes in time order, so a vehicle must be
processed whole, by one task. The data is already partitioned that way, so
a ``groupby`` (a full shuffle of terabytes) would only move rows to where
they already are. Each task reads its own files one after the other, in
chunks, with streaming detectors that carry over from chunk to chunk and file
to file (memory of one chunk, whatever the vehicle's size), and writes its
own output files; the only
thing that travels back to the client is a row count. The output mirrors
the input: the same relative paths, each output file holding its input
file's rows (every input column kept, in the same order) followed by the
detector's columns, exactly what ``gradgps detect`` writes for that file.

Output files are written under a hidden temporary name and renamed into
place, so a crashed or cancelled run never leaves a truncated file under a
real name (and :func:`find_partitions` skips hidden names when the output is
read back as a fleet).

Threads: a task (:func:`gradgps._run.chunked.detect_partition`) runs
streaming detectors, whose compiled step is serial (never the parallel batch kernel, see
:mod:`gradgps._grad.pipeline`), so it needs no lock and leaves numba's
thread setting alone; tasks in threads of one worker run
side by side. Parallelism comes from Dask *processes* (``LocalCluster`` with
one thread per worker, or ``dask worker --nthreads 1`` on a real cluster).
"""

from __future__ import annotations

import os
from collections.abc import Callable, Iterable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING
from urllib.parse import unquote

from .._exceptions import ConfigError, InputError
from .settings import DEFAULT_SETTINGS, RunSettings

if TYPE_CHECKING:
    from distributed import Client

__all__ = [
    "FleetSummary",
    "PartitionSummary",
    "VehiclePartition",
    "dask_client",
    "detect_fleet",
    "find_partitions",
]

# Track-file suffixes a fleet directory may hold (the tabular formats the
# readers know; GPX/NMEA logs are per-trip files, not fleet partitions).
_DATA_SUFFIXES = (".parquet", ".pq", ".csv", ".tsv", ".txt", ".csv.gz", ".tsv.gz", ".txt.gz")


@dataclass(frozen=True)
class VehiclePartition:
    """One vehicle's files: ``files`` (absolute, in reading order) and ``outputs`` (relative)."""

    vehicle: str
    files: tuple[str, ...]
    outputs: tuple[str, ...]


@dataclass(frozen=True)
class PartitionSummary:
    """What one vehicle's task did: rows written, anomalies (invalid fixes included), alerts.

    ``warnings``: what ``gradgps detect`` would say of each of its files (a rate below
    the lowest validated, repeated timestamps, implausible speeds...), each text led
    by the file's relative path, so that a fleet run is as honest as a one-file run.
    """

    vehicle: str
    rows: int
    anomalies: int
    invalid: int
    alerts: int
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class FleetSummary:
    """Totals over every vehicle of a :func:`detect_fleet` run.

    ``warnings``: every vehicle's input warnings (:attr:`PartitionSummary.warnings`),
    in vehicle order.
    """

    vehicles: int
    rows: int
    anomalies: int
    invalid: int
    alerts: int
    seconds: float
    warnings: tuple[str, ...] = ()


def _data_suffix(name: str) -> str | None:
    lower = name.lower()
    return next(
        (s for s in sorted(_DATA_SUFFIXES, key=len, reverse=True) if lower.endswith(s)), None
    )


def _hidden(name: str) -> bool:
    # pyarrow / Spark conventions: _SUCCESS, _metadata, .crc and temporary files.
    return name.startswith((".", "_"))


def find_partitions(input_dir: str | os.PathLike[str]) -> list[VehiclePartition]:
    """The vehicle partitions of a fleet directory (see the module docstring), sorted by vehicle.

    Raises :class:`InputError` for a missing or empty directory, an unknown
    file in it, or a vehicle present twice.
    """
    root = Path(input_dir)
    if not root.is_dir():
        raise InputError(
            "not a directory",
            source=str(root),
            hint="pass a directory with one file or one key=value folder per vehicle",
        )
    found: dict[str, VehiclePartition] = {}

    def add(part: VehiclePartition, where: Path) -> None:
        if part.vehicle in found:
            raise InputError(
                f"vehicle {part.vehicle!r} appears twice",
                source=str(where),
                hint="keep one file or one key=value folder per vehicle",
            )
        found[part.vehicle] = part

    for entry in sorted(root.iterdir()):
        if _hidden(entry.name):
            continue
        if entry.is_dir():
            if "=" not in entry.name:
                raise InputError(
                    "a folder that is not a key=value partition",
                    source=str(entry),
                    hint="name vehicle folders like vehicle=ID (hive partitioning)",
                )
            vehicle = unquote(entry.name.split("=", 1)[1])
            files = sorted(p for p in entry.iterdir() if not _hidden(p.name))
            for f in files:
                if not f.is_file() or _data_suffix(f.name) is None:
                    raise InputError(
                        "not a CSV or Parquet file",
                        source=str(f),
                        hint=f"a partition folder may hold only {', '.join(_DATA_SUFFIXES)} files",
                    )
            if files:
                add(
                    VehiclePartition(
                        vehicle,
                        tuple(str(f) for f in files),
                        tuple(f"{entry.name}/{f.name}" for f in files),
                    ),
                    entry,
                )
        else:
            suffix = _data_suffix(entry.name)
            if suffix is None:
                raise InputError(
                    "not a CSV or Parquet file",
                    source=str(entry),
                    hint=f"a fleet directory may hold only {', '.join(_DATA_SUFFIXES)} "
                    "files and key=value folders",
                )
            add(VehiclePartition(entry.name[: -len(suffix)], (str(entry),), (entry.name,)), entry)
    if not found:
        raise InputError(
            "no vehicle files in this directory",
            source=str(root),
            hint="expected <vehicle>.parquet/.csv files or vehicle=<id>/ folders",
        )
    return [found[v] for v in sorted(found)]


def _check_output_dir(input_dir: Path, output_dir: Path) -> None:
    if output_dir.exists():
        if not output_dir.is_dir():
            raise ConfigError(
                f"{output_dir}: exists and is not a directory; choose a new directory"
            )
        if output_dir.resolve() == input_dir.resolve():
            raise ConfigError(
                f"{output_dir}: the output directory is the input directory; choose another one"
            )
        if any(output_dir.iterdir()):
            raise ConfigError(
                f"{output_dir}: not empty; choose a new or empty output directory "
                "(detect-fleet never overwrites earlier results)"
            )


def detect_fleet(
    input_dir: str | os.PathLike[str],
    output_dir: str | os.PathLike[str],
    client: Client,
    *,
    task: Callable[..., PartitionSummary],
    settings: RunSettings = DEFAULT_SETTINGS,
    on_partition: Callable[[PartitionSummary], None] | None = None,
    on_start: Callable[[int], None] | None = None,
    chunk_size: int = 200_000,
) -> FleetSummary:
    """Detect every vehicle of ``input_dir`` on ``client``'s cluster with the detector and
    reading of ``settings``; write ``output_dir``.

    ``task(partition, output_dir, settings, chunk_size)`` detects one vehicle
    (:func:`gradgps._run.chunked.detect_partition`; passed in, so that this module
    imports nothing of the detector and the CLI's import chains stay within nine
    modules, ``tests/test_layers.py``); ``chunk_size``: rows per chunk of each task.
    ``on_start(n_vehicles)`` is called once the partitions are known and
    ``on_partition(summary)`` after each vehicle (progress bars). The first
    failing vehicle's error is raised here and the remaining tasks are
    cancelled. Paths must be readable and writable by the workers (a shared
    file system on a real cluster).
    """
    import time

    from distributed import as_completed

    source, target = Path(input_dir), Path(output_dir)
    partitions = find_partitions(source)
    _check_output_dir(source, target)
    if on_start is not None:
        on_start(len(partitions))
    target.mkdir(parents=True, exist_ok=True)
    started = time.perf_counter()
    model = settings.model
    task_settings = replace(settings, model=None if model is None else str(Path(model).resolve()))
    futures = client.map(
        task,
        partitions,
        output_dir=str(target.resolve()),
        settings=task_settings,
        chunk_size=chunk_size,
        pure=False,
    )
    summaries: list[PartitionSummary] = []
    try:
        for future in as_completed(futures):  # type: ignore[no-untyped-call]
            summary = future.result()
            summaries.append(summary)
            if on_partition is not None:
                on_partition(summary)
    finally:
        client.cancel(futures)  # type: ignore[no-untyped-call]
    return _total(summaries, time.perf_counter() - started)


def _total(summaries: Iterable[PartitionSummary], seconds: float) -> FleetSummary:
    items = sorted(summaries, key=lambda s: s.vehicle)

    def total(attr: str) -> int:
        return sum(int(getattr(s, attr)) for s in items)

    return FleetSummary(
        vehicles=len(items),
        rows=total("rows"),
        anomalies=total("anomalies"),
        invalid=total("invalid"),
        alerts=total("alerts"),
        seconds=seconds,
        warnings=tuple(w for s in items for w in s.warnings),
    )


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None) -> Iterator[Client]:
    """A Dask client: on the scheduler at ``scheduler``, else on a fresh local cluster.

    The local cluster has ``workers`` single-thread worker processes (default:
    one per CPU), its HTTP endpoints on a free port (never a clash with another
    cluster on 8787; the dashboard itself needs bokeh, not a dependency) and quiet
    logs; it is shut down on exit. A remote cluster is only disconnected from.
    """
    import logging

    from distributed import Client, LocalCluster

    if scheduler is not None:
        if workers is not None:
            raise ConfigError(
                "--workers is for the local cluster; a remote scheduler has its own "
                "workers (start them with 'dask worker ADDRESS --nthreads 1')"
            )
        with Client(scheduler, timeout=30) as client:  # type: ignore[no-untyped-call]
            yield client
        return
    n = (os.cpu_count() or 1) if workers is None else workers
    if n < 1:
        raise ConfigError(f"workers must be >= 1, got {n}")
    # Logs at CRITICAL only: a failing task comes back as its exception through its future,
    # and what worker logs add is the heartbeat that races the shutdown ("Stream is closed").
    cluster = LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=n,
        threads_per_worker=1,
        processes=True,
        dashboard_address=":0",
        silence_logs=logging.CRITICAL,
    )
    with cluster, Client(cluster) as client:  # type: ignore[no-untyped-call]
        yield client
