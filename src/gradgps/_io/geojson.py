"""GeoJSON track files: Point features with a time property, or LineStrings with per-vertex times.

What QGIS, geojson.io, ogr2ogr and many loggers write: a FeatureCollection
(or a single Feature) in WGS84 longitude/latitude. Every Point feature is one
fix, its properties become columns; a LineString or MultiLineString is a
track whose vertices are fixes, with times from a per-vertex array property
(``coordTimes``, ``times``, ``timestamps``, as togeojson writes from GPX) and
the feature's ``name`` (else its index) as its track id. A third coordinate is
the altitude. :mod:`gradgps._io.geojson_rows` says exactly which rows a file gives.

The file is never held whole: its rows are streamed (ijson's C parser), so the
whole-file reader needs the memory of the table only, and :func:`geojson_tables`
reads it in chunks in bounded memory, in two streaming passes as GPX and NMEA
are read. The columns are typed as pandas types the whole file's rows (a
column of whole numbers with a gap is float, one of numbers and words is text
objects...); a chunk holds only some of them, so the first pass notes which
kinds of value (missing, null, true/false, integers of each range, fractions,
text) each column holds, and each chunk is typed together with one value of each
kind, then cut back to its own rows: the dtypes and values the whole file gets.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Final

import pandas as pd

from .._tracks.track import ColumnMap, Table
from .geojson_rows import FeatureRows
from .streamed import StreamedChunks

__all__ = ["geojson_tables", "read_geojson"]

#: One value of each kind of cell, the kinds pandas tells apart when it types a column
#: (the parser gives no integer beyond 64 bits: it refuses them).
_SAMPLES: Final[dict[str, Any]] = {
    "null": None,
    "bool": True,
    "int": 0,
    "negative int": -1,
    "float": 0.5,
    "str": "a",
}
_MISSING: Final = "missing"


def read_geojson(path: str | Path) -> Table:
    """Read a GeoJSON file into a :class:`Table` (see the module docstring)."""
    path = Path(path)
    frame = pd.DataFrame(list(FeatureRows(path)))
    return Table(frame=frame, source=str(path), columns=_column_map("alt" in frame.columns))


def geojson_tables(
    path: str | Path, chunksize: int, max_cells: int | None = None
) -> StreamedChunks:
    """The rows of a GeoJSON file as Tables of at most ``chunksize`` rows (and, given
    ``max_cells``, of at most that many cells: a file's properties can make it as wide as
    they like), in two streaming passes, so memory is bounded by the chunk, not by the file.

    The first pass reads and checks every feature (a bad file fails before any
    output) and learns what only the whole file tells: the columns in the order the
    whole file's rows name them, and the kinds of value each holds. The second pass
    yields the Tables: the rows, columns, values and dtypes :func:`read_geojson`
    gives for the whole file, in chunks.
    """
    path = Path(path)
    source = str(path)
    kinds = _Kinds()
    first = FeatureRows(path)
    for row in first:
        kinds.add(row)
    samples = kinds.samples()
    header = tuple(kinds.columns)
    columns = _column_map("alt" in kinds.columns)
    if max_cells is not None:
        chunksize = max(1, min(chunksize, max_cells // max(1, len(header))))

    def chunks() -> Iterator[Table]:
        offset = 0
        rows: list[dict[str, Any]] = []
        for row in FeatureRows(path, first.doc_type):
            rows.append(row)
            if len(rows) == chunksize:
                yield _table(rows, samples, header, source, columns, offset)
                offset += len(rows)
                rows = []
        if rows:
            yield _table(rows, samples, header, source, columns, offset)

    return StreamedChunks(kinds.rows, header, columns, chunks())


def _column_map(alt: bool) -> ColumnMap:
    return ColumnMap(lat="lat", lon="lon", alt="alt" if alt else None)


def _table(
    rows: list[dict[str, Any]],
    samples: list[dict[str, Any]],
    header: tuple[str, ...],
    source: str,
    columns: ColumnMap,
    offset: int,
) -> Table:
    """The chunk ``rows`` typed as the whole file is: with one sample row of each kind of
    value the file's columns hold, then without them."""
    frame = pd.DataFrame(rows + samples, columns=list(header)).iloc[: len(rows)]
    return Table(frame=frame, source=source, columns=columns, row_offset=offset)


def _kind(value: Any) -> str:
    """The kind of a cell, among those of :data:`_SAMPLES`."""
    if value is None:
        return "null"
    kind = type(value)
    if kind is int:
        return "negative int" if value < 0 else "int"
    return "bool" if kind is bool else "float" if kind is float else "str"


@dataclass
class _Column:
    rows: int = 0
    kinds: set[str] = field(default_factory=set)


@dataclass
class _Kinds:
    """What the first pass learns: the columns, in the order the rows first name them,
    each with the number of rows having it and the kinds of its values."""

    rows: int = 0
    columns: dict[str, _Column] = field(default_factory=dict)

    def add(self, row: dict[str, Any]) -> None:
        self.rows += 1
        for key, value in row.items():
            column = self.columns.get(key)
            if column is None:
                column = self.columns[key] = _Column()
            column.rows += 1
            column.kinds.add(_kind(value))

    def samples(self) -> list[dict[str, Any]]:
        """Rows holding, in every column, one value of each kind the column holds (a
        missing value: a row without the column)."""
        kinds = {
            name: sorted(c.kinds) + ([_MISSING] if c.rows < self.rows else [])
            for name, c in self.columns.items()
        }
        count = max((len(k) for k in kinds.values()), default=0)
        return [
            {
                name: _SAMPLES[k[i % len(k)]]
                for name, k in kinds.items()
                if k[i % len(k)] != _MISSING
            }
            for i in range(count)
        ]
