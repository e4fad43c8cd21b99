"""``--geojson`` and ``--gpx`` written from results as they come, in bounded memory (issue 18).

Both files group a track's repaired fixes together (a GPX ``trk``, the GeoJSON
``"repaired track"`` lines of one track after another), but the fixes of a fleet
log arrive interleaved, chunk after chunk, and a 1 GB input has tens of millions
of them. So :class:`StreamedExports` keeps nothing of a chunk in memory: each
chunk's usable repaired fixes go to a temporary *spool* file beside the output,
grouped by track (one index entry per track and chunk), and so do the flagged
fixes (GeoJSON); at the end the files are written track by track from the
spool, a block at a time. Memory: one chunk, a few bytes per track and chunk,
and one fault event's coordinates; disk: 24 bytes per usable fix until the end.

The text is exactly what :func:`gradgps._io.export.geojson_document` and
:func:`~gradgps._io.export.geojson_text` give for the whole result, and what
the whole-result GPX writer gave, whatever the chunks (tested in
``tests/test_export_streamed.py``): the same features in the same order, the
same numbers written the same way (``json`` writes a float as ``repr``), lines
split at the same gaps and cut at the antimeridian at the same points.
"""

from __future__ import annotations

import io
import json
import os
import tempfile
from collections.abc import Iterator
from pathlib import Path
from typing import IO, Any
from xml.sax.saxutils import escape

import numpy as np
import pandas as pd

from .export import (
    GPX_FOOTER,
    GPX_HEADER,
    LINE_GAP_S,
    antimeridian_crossing,
    event_feature,
    flagged_features,
    gpx_point,
    iso_or_none,
    usable_repairs,
)

__all__ = ["StreamedExports", "write_geojson", "write_gpx"]

_JSON = {"allow_nan": False, "separators": (",", ":")}


class _Spool:
    """Rows of ``width`` float64 values per key, appended to one temporary file in row
    order, read back key by key (keys in order of first appearance) a block at a time.

    Memory: one ``(offset, count)`` entry per key and :meth:`add`; a block read back is
    at most one :meth:`add`'s rows of its key.
    """

    def __init__(self, width: int, directory: Path) -> None:
        self._file: IO[bytes] = _scratch(directory)
        self._width = width
        self._blocks: dict[Any, list[tuple[int, int]]] = {}
        self._end = 0

    def add(self, keys: np.ndarray, values: np.ndarray) -> None:
        """Append ``values`` (rows x width), row ``i`` under key ``keys[i]``."""
        if not len(keys):
            return
        codes, uniques = pd.factorize(keys)
        order = np.argsort(codes, kind="stable")
        counts = np.bincount(codes, minlength=len(uniques))
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        self._file.seek(self._end)
        self._file.write(np.ascontiguousarray(values[order], dtype=np.float64).tobytes())
        row_bytes = 8 * self._width
        for key, start, count in zip(
            uniques.tolist(), starts.tolist(), counts.tolist(), strict=True
        ):
            self._blocks.setdefault(key, []).append((self._end + start * row_bytes, count))
        self._end += len(keys) * row_bytes

    def tracks(self) -> list[Any]:
        return list(self._blocks)

    def read(self, key: Any) -> Iterator[np.ndarray]:
        """The rows of ``key`` in the order they were added, a block at a time."""
        for offset, count in self._blocks.get(key, []):
            self._file.seek(offset)
            data = self._file.read(count * 8 * self._width)
            yield np.frombuffer(data, dtype=np.float64).reshape(count, self._width)

    def close(self) -> None:
        self._file.close()


class StreamedExports:
    """Write ``--geojson`` and/or ``--gpx`` from (fixes, result) chunks given in row order.

    :meth:`add` each chunk, then :meth:`finish` with the run's fault events (the
    GeoJSON's event features); each file appears under its name only when complete
    (written beside it as ``<name>.partial``). :meth:`close` drops the spools (also
    after an error).
    """

    def __init__(self, geojson: Path | None, gpx: Path | None) -> None:
        self.geojson, self.gpx = geojson, gpx
        first = geojson if geojson is not None else gpx
        if first is None:
            raise ValueError("StreamedExports needs a GeoJSON or a GPX path")
        for path in (geojson, gpx):
            if path is not None:
                path.parent.mkdir(parents=True, exist_ok=True)
        directory = self._directory = first.parent
        self._lines = _Spool(3, directory)  # t, lat_clean, lon_clean (wrapped)
        self._flagged = _Spool(3, directory) if geojson is not None else None  # row, lon, lat
        self._flagged_text: IO[bytes] | None = _scratch(directory) if geojson is not None else None
        self._n_flagged = 0
        self._rows = 0

    def __enter__(self) -> StreamedExports:
        return self

    def __exit__(self, *_: object) -> None:
        self.close()

    def add(self, fixes: pd.DataFrame, result: pd.DataFrame) -> None:
        """One chunk: canonical fixes and the detector's result, same length, row order."""
        usable, lat_c, lon_c = usable_repairs(result)
        tracks = fixes["track"].to_numpy(object)
        t = fixes["t"].to_numpy(np.float64)
        self._lines.add(tracks[usable], np.column_stack([t, lat_c, lon_c])[usable])
        if self._flagged is not None and self._flagged_text is not None:
            numbers = self._rows + np.arange(len(fixes))
            kept: list[int] = []
            points: list[list[float]] = []
            for i, feature in flagged_features(fixes, result, numbers):
                text = json.dumps(feature, **_JSON)  # type: ignore[arg-type]
                self._flagged_text.write(("," + text).encode())
                kept.append(i)
                points.append([float(numbers[i]), *feature["geometry"]["coordinates"]])
            if kept:
                self._flagged.add(tracks[kept], np.array(points, np.float64))
                self._n_flagged += len(kept)
        self._rows += len(fixes)

    def finish(self, events: pd.DataFrame | None) -> None:
        """Write the files (``events``: the run's fault events, for the GeoJSON)."""
        if self.geojson is not None:
            _atomically(self.geojson, lambda out: self._write_geojson(out, events))
        if self.gpx is not None:
            _atomically(self.gpx, self._write_gpx)

    def close(self) -> None:
        self._lines.close()
        if self._flagged is not None:
            self._flagged.close()
        if self._flagged_text is not None:
            self._flagged_text.close()

    def _write_gpx(self, out: IO[str]) -> None:
        out.write(GPX_HEADER)
        for track in self._lines.tracks():
            out.write(f"<trk><name>{escape(str(track))}</name>\n<trkseg>\n")
            last = None
            for block in self._lines.read(track):
                for t, lat, lon in block.tolist():
                    if last is not None and t - last > LINE_GAP_S:
                        out.write("</trkseg>\n<trkseg>\n")
                    out.write(gpx_point(t, lat, lon))
                    last = t
            out.write("</trkseg>\n</trk>\n")
        out.write(GPX_FOOTER)

    def _write_geojson(self, out: IO[str], events: pd.DataFrame | None) -> None:
        out.write('{"type":"FeatureCollection","features":[')
        first = True
        for track in self._lines.tracks():
            first = _write_lines(out, str(track), self._lines.read(track), first, self._directory)
        if self._flagged_text is not None and self._n_flagged:
            self._flagged_text.seek(0)
            if first:
                self._flagged_text.read(1)  # the leading comma
            while piece := self._flagged_text.read(2**20):
                out.write(piece.decode())
            first = False
        if events is not None and len(events):
            for text in self._event_features(events):
                out.write(text if first else "," + text)
                first = False
        out.write("]}")

    def _event_features(self, events: pd.DataFrame) -> Iterator[str]:
        """Each event's feature text, in the order of ``events``; the coordinates are its
        track's flagged fixes from ``first_row`` to ``last_row``, read from the spool a track
        at a time (the texts wait in a temporary file, so memory holds one event's points)."""
        assert self._flagged is not None
        # Column arrays, one event's record built when it is written (a dict per event
        # would be a kilobyte each).
        columns = {c: events[c].to_numpy() for c in events.columns}
        first_rows = events["first_row"].to_numpy(np.int64)
        last_rows = events["last_row"].to_numpy(np.int64)
        where = np.zeros((len(events), 2), np.int64)
        with _scratch(self._directory) as texts:

            def done(k: int, coords: list[list[float]]) -> None:
                record = {c: values[k] for c, values in columns.items()}
                data = json.dumps(event_feature(record, coords), **_JSON).encode()  # type: ignore[arg-type]
                where[k] = texts.tell(), len(data)
                texts.write(data)

            by_track: dict[Any, list[int]] = {}
            for k, track in enumerate(columns["track"].tolist()):
                by_track.setdefault(track, []).append(k)
            for track, ks in by_track.items():
                ks.sort(key=lambda k: int(first_rows[k]))
                coords: dict[int, list[list[float]]] = {}
                waiting = iter(ks)
                pending = next(waiting, None)
                for block in self._flagged.read(track):
                    rows = block[:, 0]
                    while pending is not None and int(first_rows[pending]) <= rows[-1]:
                        coords[pending] = []
                        pending = next(waiting, None)
                    for k in list(coords):
                        lo = np.searchsorted(rows, int(first_rows[k]), side="left")
                        hi = np.searchsorted(rows, int(last_rows[k]), side="right")
                        coords[k].extend(block[lo:hi, 1:3].tolist())
                        if int(last_rows[k]) <= rows[-1]:
                            done(k, coords.pop(k))
                for k in list(coords):
                    done(k, coords.pop(k))
                while pending is not None:
                    done(pending, [])
                    pending = next(waiting, None)
            for offset, length in where.tolist():
                texts.seek(offset)
                yield texts.read(length).decode()


def _write_lines(
    out: IO[str], track: str, blocks: Iterator[np.ndarray], first: bool, directory: Path
) -> bool:
    """Write the ``"repaired track"`` features of one track's usable repaired fixes (t, lat,
    lon rows in order), each after a comma unless ``first``: a line per run of fixes at
    most :data:`LINE_GAP_S` apart, a Point for a run of one, a MultiLineString where it
    crosses the antimeridian. Returns whether nothing has been written yet."""
    run = _Run(track, directory)
    for block in blocks:
        for t, lat, lon in block.tolist():
            if run.n and t - run.end > LINE_GAP_S:
                first = run.write(out, first)
                run = _Run(track, directory)
            run.add(t, lon, lat)
    if run.n:
        first = run.write(out, first)
    return first


class _Run:
    """One line feature's coordinates as text, as they come. Its geometry's type is known
    only at its end, so the text waits in a list and, past a megabyte, in a temporary
    file (a track of millions of fixes without a gap is one line)."""

    _SPILL = 2**20

    def __init__(self, track: str, directory: Path) -> None:
        self.track = track
        self._directory = directory
        self.n = 0
        self.start = self.end = 0.0
        self.cut = False
        self._last: tuple[float, float] | None = None
        self._pieces: list[str] = []
        self._size = 0
        self._spill: IO[str] | None = None

    def add(self, t: float, lon: float, lat: float) -> None:
        if self.n == 0:
            self.start = t
            text = f"[{lon!r},{lat!r}]"
        else:
            assert self._last is not None
            crossing = antimeridian_crossing(self._last, (lon, lat))
            if crossing is None:
                text = f",[{lon!r},{lat!r}]"
            else:
                self.cut = True
                edge, at = crossing
                text = f",[{edge!r},{at!r}]],[[{-edge!r},{at!r}],[{lon!r},{lat!r}]"
        self._last = (lon, lat)
        self.n += 1
        self.end = t
        self._pieces.append(text)
        self._size += len(text)
        if self._size > self._SPILL:
            if self._spill is None:
                self._spill = io.TextIOWrapper(_scratch(self._directory), encoding="ascii")
            self._spill.write("".join(self._pieces))
            self._pieces, self._size = [], 0

    def write(self, out: IO[str], first: bool) -> bool:
        """Write the feature (after a comma unless ``first``); returns False."""
        if self.n == 1:
            head, tail = '{"type":"Point","coordinates":', "}"
        elif self.cut:
            head, tail = '{"type":"MultiLineString","coordinates":[[', "]]}"
        else:
            head, tail = '{"type":"LineString","coordinates":[', "]}"
        out.write(
            ('{"type":"Feature","geometry":' if first else ',{"type":"Feature","geometry":') + head
        )
        if self._spill is not None:
            self._spill.seek(0)
            while piece := self._spill.read(2**20):
                out.write(piece)
            self._spill.close()
        out.write("".join(self._pieces))
        props = {
            "kind": "repaired track",
            "track": self.track,
            "fixes": self.n,
            "start": iso_or_none(self.start),
            "end": iso_or_none(self.end),
        }
        out.write(tail + ',"properties":' + json.dumps(props, **_JSON) + "}")  # type: ignore[arg-type]
        return False


def _scratch(directory: Path) -> IO[bytes]:
    """A temporary file that disappears when closed (by its owner's ``close``), beside the
    output (``directory``), where there is room for the output anyway."""
    return tempfile.TemporaryFile(dir=directory, prefix=".gradgps-spool-")


def _atomically(path: Path, write: Any) -> None:
    partial = path.with_name(path.name + ".partial")
    try:
        with partial.open("w", encoding="utf-8") as out:
            write(out)
        os.replace(partial, path)
    finally:
        partial.unlink(missing_ok=True)


def write_geojson(
    path: str | os.PathLike[str],
    fixes: pd.DataFrame,
    result: pd.DataFrame,
    events: pd.DataFrame | None = None,
) -> Path:
    """Write the GeoJSON of a whole result (the text of :func:`gradgps._io.export.geojson_text`
    for :func:`~gradgps._io.export.geojson_document`), atomically, as ``--geojson`` does."""
    out = Path(path)
    with StreamedExports(out, None) as exports:
        exports.add(fixes, result)
        exports.finish(events)
    return out


def write_gpx(path: str | os.PathLike[str], fixes: pd.DataFrame, result: pd.DataFrame) -> Path:
    """The repaired track of a whole result as GPX 1.1: one ``trk`` per track, one ``trkseg``
    per run of usable fixes at most :data:`LINE_GAP_S` apart (atomically, as ``--gpx``)."""
    out = Path(path)
    with StreamedExports(None, out) as exports:
        exports.add(fixes, result)
        exports.finish(None)
    return out
