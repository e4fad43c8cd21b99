"""Detection over a CSV (Parquet, GPX, NMEA) of any length, chunk by chunk, in bounded memory.

``gradgps detect`` on a big CSV must not hold the file in memory, and its
results must not depend on where chunks happen to end. So this path uses
*streaming* semantics: rows are taken in file order, each track id gets its
own streaming :class:`~gradgps._grad.detector.Detector` on first sight, and that
detector's state carries over from one chunk to the next. Memory is bounded
by the chunk size plus a few kilobytes of state per track id.

What that means for the results (see :mod:`gradgps._grad.detector`): they
equal batch ``Detector().detect`` on the whole file, bit for bit. Both read
each track in row order: a fix whose time is not after the previous usable
fix of its track (a repeated or backward timestamp) is flagged invalid
(``invalid_reason`` "time not after the previous fix"), never sorted in or
merged (:func:`gradgps._tracks.preprocess.stream_reasons`, the one rule every
mode applies); sort the file first if its rows are out of order.

Every input row gives exactly one output row, in input order; invalid fixes
are flagged, never dropped.

A model whose verdicts settle one fix late (a confirm head) decides a fix when
the next fix of its track arrives, possibly in a later chunk: a chunk waits
until its tracks' last fixes are settled, within :data:`HOLD_ROWS` rows behind
it, perhaps in the next file of a vehicle (see :func:`_detect_files`).
"""

from __future__ import annotations

import collections
import contextlib
import os
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
from numpy.typing import NDArray

from .._exceptions import InputError
from .._grad.detector import MultiTrackDetector, load_grad_model
from .._io.read import TableWriter, table_chunks
from .._result import RESULT_DTYPES
from .._tracks.input_checks import InputChecks, validated_rates
from .._tracks.track import to_fixes
from .fleet_dask import PartitionSummary, VehiclePartition
from .settings import DEFAULT_SETTINGS, RunSettings

__all__ = ["DetectSummary", "detect_csv_in_chunks", "detect_partition", "no_fixes"]

#: Rows (at least; a chunk's size if more) that may wait behind a chunk whose tracks'
#: last fixes have not settled yet, before it is written with their verdicts at once.
HOLD_ROWS = 10_000


@dataclass(frozen=True)
class DetectSummary:
    """Counts and timing of one detection run."""

    rows: int
    anomalies: int
    invalid: int
    alerts: int
    tracks: int
    seconds: float
    #: Where the input is outside what the model was validated on
    #: (:class:`gradgps._tracks.input_checks.InputChecks`, fed chunk by chunk).
    warnings: tuple[str, ...] = ()

    @property
    def rows_per_second(self) -> float:
        return self.rows / self.seconds if self.seconds > 0 else float("inf")


def detect_csv_in_chunks(
    input_path: str | os.PathLike[str],
    output: str | os.PathLike[str] | None,
    *,
    settings: RunSettings = DEFAULT_SETTINGS,
    chunk_size: int = 200_000,
    on_start: Callable[[int], None] | None = None,
    on_chunk: Callable[[int], None] | None = None,
    on_result: Callable[[pd.DataFrame, pd.DataFrame, pd.DataFrame], None] | None = None,
    streams: MultiTrackDetector | None = None,
) -> DetectSummary:
    """Detect faults in every row of a CSV, Parquet, GPX or NMEA file (``settings.fmt``, or
    as :func:`gradgps._io.read.resolve_format` finds it), ``chunk_size`` rows at a time,
    with the detector and reading of ``settings``; write ``output``.

    The output (``.csv``, ``.csv.gz`` or ``.parquet``) has every input
    column, in order, then the result columns, one row per input row. It is
    written chunk by chunk and appears under its name only when complete.
    ``on_start(total_rows)`` is called once the file's structure is checked,
    ``on_chunk(rows)`` after each chunk (for progress bars), ``on_result(fixes,
    result, frame)`` with each chunk's canonical fixes, result and input rows
    (for events, a report or exports). ``output`` ``None`` writes no table.
    ``streams``: the per-track detectors to continue; ``None``: fresh ones, from
    ``settings``.
    """
    (summary,) = _detect_files(
        [(input_path, output)],
        settings=settings,
        chunk_size=chunk_size,
        streams=streams,
        on_start=on_start,
        on_chunk=on_chunk,
        on_result=on_result,
    )
    return summary


@dataclass
class _FileOutput:
    """One input file's output while its chunks are detected and written."""

    #: Holds ``writer`` open; closed when the file is complete (under its name then).
    stack: contextlib.ExitStack
    writer: TableWriter | None
    header: list[str]
    checks: InputChecks
    started: float
    counts: NDArray[np.int64] = field(default_factory=lambda: np.zeros(4, np.int64))
    unsettled: int = 0
    seconds: float = 0.0


def _detect_files(
    files: Sequence[tuple[str | os.PathLike[str], str | os.PathLike[str] | None]],
    *,
    settings: RunSettings,
    chunk_size: int,
    streams: MultiTrackDetector | None = None,
    on_start: Callable[[int], None] | None = None,
    on_chunk: Callable[[int], None] | None = None,
    on_result: Callable[[pd.DataFrame, pd.DataFrame, pd.DataFrame], None] | None = None,
) -> list[DetectSummary]:
    """:func:`detect_csv_in_chunks` for files that continue one another (one vehicle's
    files, in order): one set of per-track detectors through them all, one
    :class:`DetectSummary` per file. ``files``: (input, output) pairs.

    Where verdicts settle one fix late, a chunk's rows are final once every track's
    last fix in it has been settled by that track's next fix, in a later chunk,
    perhaps of the next file (:meth:`MultiTrackDetector.update_fixes`): chunks wait,
    in order, until then, or until more than :data:`HOLD_ROWS` rows wait behind
    them (bounded memory), and then are written with the verdicts at once of the
    fixes still pending (counted in a warning). So a file's output is complete,
    and appears, only when the first chunk of the next file has been read.
    """
    if streams is None:
        streams = MultiTrackDetector(settings.model, threshold=settings.threshold)
    validated = validated_rates(load_grad_model(settings.model).config)
    hold_cap = max(chunk_size, HOLD_ROWS)
    outputs: list[_FileOutput] = []
    held: collections.deque[tuple[int, Any, pd.DataFrame, pd.DataFrame]] = collections.deque()
    held_rows = 0
    with contextlib.ExitStack() as all_files:

        def finish(k: int) -> None:
            """File ``k`` is written: close its output, under its name now."""
            out = outputs[k]
            if out.writer is not None and not out.writer.started:  # no chunk: our columns
                empty = pd.DataFrame([], columns=out.header, dtype=object)
                out.writer.write(pd.concat([empty, streams.update_fixes(no_fixes())], axis=1))
            out.stack.close()
            out.seconds = time.perf_counter() - out.started

        def emit(k: int, table: Any, fixes: pd.DataFrame, result: pd.DataFrame) -> None:
            out = outputs[k]
            out.counts += (
                len(result),
                int(result["anomaly"].sum()),
                int((result["invalid_reason"] != "").sum()),
                int(result["alert"].sum()),
            )
            if out.writer is not None:
                joined = pd.concat(
                    [table.frame.reset_index(drop=True), result.reset_index(drop=True)], axis=1
                )
                out.writer.write(joined, geometry=table.geometry)
            if on_result is not None:
                on_result(fixes, result, table.frame)
            if on_chunk is not None:
                on_chunk(len(result))

        finished = 0  # files before this one are written and closed

        def finish_before(k: int) -> None:
            nonlocal finished
            while finished < k:
                finish(finished)
                finished += 1

        def release_first(final: bool = False) -> None:
            """Write the first held chunk; ``final``: the input has ended, so its fixes
            still pending are final as they are (each its track's last)."""
            nonlocal held_rows
            k, table, fixes, result = held.popleft()
            held_rows -= len(result)
            unsettled = streams.release(result)
            if not final:
                outputs[k].unsettled += unsettled
            finish_before(k)  # chunks go out in order: the files before k are complete
            emit(k, table, fixes, result)

        for k, (path, output) in enumerate(files):
            stack = all_files.enter_context(contextlib.ExitStack())
            chunks = table_chunks(
                Path(path), chunk_size, settings.columns, settings.options, settings.fmt
            )
            clash = [c for c in RESULT_DTYPES if c in chunks.header]
            if clash:
                raise InputError(
                    f"the file already has columns {clash}",
                    source=str(path),
                    hint="rename them first: the output adds columns of those names",
                )
            if on_start is not None:
                on_start(chunks.n_rows)
            outputs.append(
                _FileOutput(
                    stack,
                    None
                    if output is None
                    else stack.enter_context(TableWriter(Path(output), RESULT_DTYPES)),
                    list(chunks.header),
                    InputChecks(*validated),
                    time.perf_counter(),
                )
            )
            for table in chunks:
                fixes = to_fixes(table)
                outputs[k].checks.add(fixes)
                result = streams.update_fixes(fixes)
                held.append((k, table, fixes, result))
                held_rows += len(result)
                waiting = streams.pending_frames()
                while held and (
                    id(held[0][3]) not in waiting or held_rows - len(held[0][3]) > hold_cap
                ):
                    release_first()
        while held:
            release_first(final=True)
        finish_before(len(files))
    return [_summary(out, hold_cap, len(streams.detectors)) for out in outputs]


def _summary(out: _FileOutput, hold_cap: int, tracks: int) -> DetectSummary:
    rows, anomalies, invalid, alerts = (int(n) for n in out.counts)
    unsettled = (
        (
            f"{out.unsettled:,} fixes keep their verdict at once: their track's next fix "
            f"came more than {hold_cap:,} rows later in the file; a "
            "larger --chunk-size, or the file sorted by track, gives their settled ones",
        )
        if out.unsettled
        else ()
    )
    return DetectSummary(
        rows=rows,
        anomalies=anomalies,
        invalid=invalid,
        alerts=alerts,
        tracks=tracks,
        seconds=out.seconds,
        warnings=tuple(out.checks.warnings()) + unsettled,
    )


def detect_partition(
    partition: VehiclePartition,
    output_dir: str,
    settings: RunSettings = DEFAULT_SETTINGS,
    chunk_size: int = 200_000,
) -> PartitionSummary:
    """Run the detector on one vehicle's files and write its output files (one Dask task).

    The files are read one after the other, ``chunk_size`` rows at a time
    (:func:`gradgps._run.chunked.detect_csv_in_chunks`), with one set of per-track
    detectors carried from chunk to chunk and file to file: the results of the files
    joined and detected as one table, in the memory of one chunk (issue 18: a task
    used to hold its vehicle's every file and batch features at once), settled
    verdicts included (a file's last fix is settled by the next file's first). Each
    output file holds its input file's rows; they appear when the vehicle is done.
    ``settings``: the detector and how the files are read.
    """
    targets = [Path(output_dir) / relative for relative in partition.outputs]
    partials = [t.parent / f".partial-{uuid.uuid4().hex}-{t.name}" for t in targets]
    for target in targets:
        target.parent.mkdir(parents=True, exist_ok=True)
    try:
        done = _detect_files(
            list(zip(partition.files, partials, strict=True)),
            settings=settings,
            chunk_size=chunk_size,
        )
        for partial, target in zip(partials, targets, strict=True):
            partial.replace(target)
    finally:
        for partial in partials:
            partial.unlink(missing_ok=True)
    return PartitionSummary(
        partition.vehicle,
        sum(d.rows for d in done),
        sum(d.anomalies for d in done),
        sum(d.invalid for d in done),
        sum(d.alerts for d in done),
        tuple(
            f"{relative}: {warning}"
            for relative, d in zip(partition.outputs, done, strict=True)
            for warning in d.warnings
        ),
    )


def no_fixes() -> pd.DataFrame:
    """Canonical fixes of no rows (the columns every result is made from)."""
    return pd.DataFrame(
        {
            "track": pd.Series(dtype=object),
            **{c: pd.Series(dtype=np.float64) for c in ("t", "lat", "lon")},
        }
    )
