"""Detection over a CSV of any length, chunk by chunk, in bounded memory.

``gradgps detect`` on a big CSV must not hold the file in memory, and its
results must not depend on where chunks happen to end. So this path uses
*streaming* semantics: rows are taken in file order, each track id gets its
own streaming :class:`~gradgps._grad.detector.Detector` on first sight, and that
detector's state carries over from one chunk to the next. Memory is bounded
by the chunk size plus a few kilobytes of state per track id.

What that means for the results (see :mod:`gradgps._grad.detector`): for a file
whose fixes are in time order within each track, without repeated
timestamps, they equal batch ``Detector().detect`` on the whole file, bit
for bit. Where the file is not in order, a fix whose time is not after the
previous valid fix of its track is flagged invalid (``invalid_reason``
"time not after the previous fix") instead of being sorted in and merged as
batch detection does; sort the file first if that matters.

Every input row gives exactly one output row, in input order; invalid fixes
are flagged, never dropped.
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .._grad.detector import RESULT_DTYPES, Detector
from .._io.read import TableWriter, iter_csv_tables
from .._tracks.track import ColumnMap, to_fixes

__all__ = ["DetectSummary", "TrackStreams", "detect_csv_in_chunks"]


class TrackStreams:
    """One streaming :class:`Detector` per track id, made on first sight, kept across calls.

    ``model`` and ``threshold`` are passed to every Detector.
    """

    def __init__(
        self, model: str | os.PathLike[str] | None = None, *, threshold: float | None = None
    ) -> None:
        self.model = model
        self.threshold = threshold
        self.detectors: dict[str, Detector] = {}

    def _detector(self, track: str) -> Detector:
        det = self.detectors.get(track)
        if det is None:
            det = Detector(self.model, threshold=self.threshold)
            self.detectors[track] = det
        return det

    def get_state(self) -> dict[str, Any]:
        """Every track's detector state, as plain JSON-able data (see :meth:`Detector.get_state`)."""
        return {"tracks": {track: det.get_state() for track, det in self.detectors.items()}}

    def set_state(self, state: Mapping[str, Any]) -> TrackStreams:
        """Restore :meth:`get_state` output (same model and threshold); returns self."""
        try:
            tracks = dict(state["tracks"])
        except (KeyError, TypeError, ValueError) as exc:
            raise ConfigError(f"not a track streams state: {exc}") from exc
        self.detectors = {
            str(track): Detector(self.model, threshold=self.threshold).set_state(s)
            for track, s in tracks.items()
        }
        return self

    def update_fixes(self, fixes: pd.DataFrame) -> pd.DataFrame:
        """Feed canonical fixes to their tracks' detectors in row order; one result row per row.

        The result has the batch result columns (``anomaly`` ... ``invalid_reason``)
        and ``fixes``' index.
        """
        n = len(fixes)
        nan = [float("nan")] * n
        tracks = fixes["track"].to_numpy(object)
        t = fixes["t"].to_numpy(np.float64).tolist()
        lat = fixes["lat"].to_numpy(np.float64).tolist()
        lon = fixes["lon"].to_numpy(np.float64).tolist()
        speed = fixes["speed"].to_numpy(np.float64).tolist() if "speed" in fixes else nan
        heading = fixes["heading"].to_numpy(np.float64).tolist() if "heading" in fixes else nan
        columns: dict[str, list[object]] = {name: [] for name in RESULT_DTYPES}
        values = list(columns.values())
        for i in range(n):
            r = self._detector(str(tracks[i])).update(t[i], lat[i], lon[i], speed[i], heading[i])
            for column, value in zip(
                values,
                (
                    r.anomaly,
                    r.score,
                    r.bias_type,
                    r.time_type,
                    r.lat_clean,
                    r.lon_clean,
                    r.alert,
                    r.invalid_reason,
                ),
                strict=True,
            ):
                column.append(value)
        return pd.DataFrame(
            {
                name: pd.Series(v, dtype=RESULT_DTYPES[name], index=fixes.index)
                for name, v in columns.items()
            }
        )


@dataclass(frozen=True)
class DetectSummary:
    """Counts and timing of one detection run."""

    rows: int
    anomalies: int
    invalid: int
    alerts: int
    tracks: int
    seconds: float

    @property
    def rows_per_second(self) -> float:
        return self.rows / self.seconds if self.seconds > 0 else float("inf")


def detect_csv_in_chunks(
    input_path: str | os.PathLike[str],
    output: str | os.PathLike[str],
    *,
    columns: ColumnMap | None = None,
    model: str | os.PathLike[str] | None = None,
    threshold: float | None = None,
    chunk_size: int = 200_000,
    on_start: Callable[[int], None] | None = None,
    on_chunk: Callable[[int], None] | None = None,
) -> DetectSummary:
    """Detect faults in every row of a CSV, ``chunk_size`` rows at a time; write ``output``.

    The output (``.csv``, ``.csv.gz`` or ``.parquet``) has every input
    column, in order, then the result columns, one row per input row. It is
    written chunk by chunk and appears under its name only when complete.
    ``on_start(total_rows)`` is called once the file's structure is checked,
    ``on_chunk(rows)`` after each chunk (for progress bars).
    """
    started = time.perf_counter()
    streams = TrackStreams(model, threshold=threshold)
    chunks = iter_csv_tables(Path(input_path), chunk_size, columns)
    clash = [c for c in RESULT_DTYPES if c in chunks.header]
    if clash:
        raise InputError(
            f"the file already has columns {clash}",
            source=str(input_path),
            hint="rename them first: the output adds columns of those names",
        )
    if on_start is not None:
        on_start(chunks.n_rows)
    counts = np.zeros(3, np.int64)
    with TableWriter(Path(output)) as writer:
        for table in chunks:
            result = streams.update_fixes(to_fixes(table))
            counts += (
                int(result["anomaly"].sum()),
                int((result["invalid_reason"] != "").sum()),
                int(result["alert"].sum()),
            )
            out = pd.concat(
                [table.frame.reset_index(drop=True), result.reset_index(drop=True)], axis=1
            )
            writer.write(out)
            if on_chunk is not None:
                on_chunk(len(out))
        if writer.rows == 0:  # a header-only file: still write the header, with our columns
            empty = pd.DataFrame({name: pd.Series(dtype=object) for name in chunks.header})
            writer.write(pd.concat([empty, streams.update_fixes(_no_fixes())], axis=1))
    return DetectSummary(
        rows=writer.rows,
        anomalies=int(counts[0]),
        invalid=int(counts[1]),
        alerts=int(counts[2]),
        tracks=len(streams.detectors),
        seconds=time.perf_counter() - started,
    )


def _no_fixes() -> pd.DataFrame:
    return pd.DataFrame(
        {
            "track": pd.Series(dtype=object),
            **{c: pd.Series(dtype=np.float64) for c in ("t", "lat", "lon")},
        }
    )
