"""Reading and writing track files: a path on disk <-> a :class:`Table`.

Formats are chosen by extension (``.csv``, ``.txt``, ``.tsv``, ``.parquet``/
``.pq``, ``.gpx``, ``.nmea``/``.nma``/``.log``; a trailing ``.gz`` means
gzip-compressed text) or named explicitly (``fmt``); a file with an unknown
extension is recognised by its first bytes. GPX, NMEA and ROS bags (``.bag``,
``.mcap``, ``.db3`` or a ROS 2 bag directory; extra ``ros``) have their own
modules (:mod:`gradgps._io.gpx`, :mod:`gradgps._io.nmea`, :mod:`gradgps._io.rosbag`);
CSV and Parquet live here, GeoParquet's geometry in :mod:`gradgps._io.geoparquet`.

CSV files are read in two passes. The first pass, with the standard
:mod:`csv` module, checks the *structure* (UTF-8 text, a header line, proper
quoting, the same number of fields on every row) and reports the exact file
line of the first problem; pandas would otherwise pad short rows with missing
values without a word and report long rows by a line count that ignores
blank lines. The second pass lets pandas parse and type the columns (the
track-id column, when it can be found from the header, stays text so ``007``
keeps its zeros; values pandas treats as missing, like ``NA``, become an
empty track id). Every input column is kept under its original name and in its original order
(pandas renames duplicate names ``x``, ``x.1``... and unnamed ones
``Unnamed: 0``); *values* are checked later by :func:`gradgps.to_fixes`, whose
errors name the row, the file line and the column.

Where guessing is not good enough, the caller says what a file holds
(:class:`~gradgps._tracks.track.ReadOptions`: ``decimal``, ``time_format``,
``skip_rows``, ``speed_unit``, ``crs``; the CLI's ``--decimal`` etc.). Each applies
where it means something (CSV; Parquet for all but ``skip_rows``) and is an
error elsewhere, so an option is never silently ignored.
"""

from __future__ import annotations

import csv
import gzip
import itertools
import warnings
from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, replace
from pathlib import Path
from typing import IO, Any, Final, Unpack

import numpy as np
import pandas as pd

from .._exceptions import ConfigError, InputError
from .._tracks.track import (
    ColumnMap,
    GeoPoints,
    ReadKeywords,
    ReadOptions,
    Table,
    check_keywords,
    resolve_columns,
    to_fixes,
)
from .files import READ_ERRORS, check_readable, open_bytes, text_lines
from .geojson import geojson_tables, read_geojson
from .geoparquet import (
    geo_metadata,
    primary_column,
    read_geoparquet,
    wkt_points,
    write_geoparquet,
)
from .gpx import gpx_tables, read_gpx
from .nmea import nmea_tables, read_nmea
from .rosbag import is_rosbag, read_rosbag, rosbag_tables
from .streamed import StreamedChunks
from .times import csv_ready

__all__ = [
    "FORMATS",
    "CsvChunks",
    "TableWriter",
    "iter_csv_tables",
    "load_table",
    "read_fixes",
    "read_table",
    "resolve_format",
    "table_chunks",
    "write_table",
]

FORMATS: Final = ("csv", "parquet", "gpx", "nmea", "geojson", "rosbag")

_EXTENSIONS: Final = {
    ".csv": "csv",
    ".txt": "csv",
    ".tsv": "csv",
    ".parquet": "parquet",
    ".pq": "parquet",
    ".gpx": "gpx",
    ".geojson": "geojson",
    ".json": "geojson",
    ".nmea": "nmea",
    ".nma": "nmea",
    ".log": "nmea",
    ".bag": "rosbag",
    ".mcap": "rosbag",
    ".db3": "rosbag",
}

# Delimiters tried on the header line; the most frequent one wins.
_DELIMITERS: Final = (",", ";", "\t", "|")
#: Most cells (rows x columns) of one chunk: a chunk of a very wide file has fewer rows.
MAX_CHUNK_CELLS: Final = 4_000_000
#: Most rows of one chunk, however narrow the file: detection holds far more per row of a
#: chunk than its cells (features, states, the result, the output's text), so a narrow
#: file's chunk under the cell bound alone (2 M rows of 2 columns) could pass 1 GB. With
#: this cap ``--chunk-size 0`` peaked at 772 MB on a 305 MB CSV (docs/reliability.md,
#: round three, ``benchmarks/memory_modes.py``).
MAX_CHUNK_ROWS: Final = 500_000
#: Columns of the widest table the GPX, NMEA and ROS bag readers give (every optional
#: column filled), which cut their chunks before the first pass has learned the header:
#: 10 today (GPX track, time, lat, lon, alt, speed, course, hdop, satellites, fix; NMEA
#: time, lat, lon, speed, course, alt, hdop, fix_quality, satellites, line; a bag 8), with
#: room for a reader that gains a column. ``tests/test_bounded_chunks.py`` checks it.
STREAMED_WIDEST_ROW: Final = 12


def chunk_rows(chunk_size: int) -> int:
    """The rows per chunk that ``--chunk-size`` asks for: itself, or for 0 the largest chunk
    the memory bound allows (:data:`MAX_CHUNK_ROWS`; the readers cut it further by
    :data:`MAX_CHUNK_CELLS` for a wide file). ``gradgps detect`` has no mode holding the
    file: 0 used to read it whole, about 10 GB for a 1 GB CSV, for outputs byte for byte
    those of the chunks (issue 18), and stays accepted for the scripts that pass it."""
    return chunk_size if chunk_size > 0 else MAX_CHUNK_ROWS


def _bounded_rows(chunksize: int, columns: int) -> int:
    """Rows of one chunk asked for ``chunksize`` of a table of ``columns`` columns: never
    more than :data:`MAX_CHUNK_ROWS`, nor than :data:`MAX_CHUNK_CELLS` cells, in every
    chunked format (a ``--chunk-size`` of 100 million must not hold the file either)."""
    return max(1, min(chunksize, MAX_CHUNK_ROWS, MAX_CHUNK_CELLS // max(1, columns)))


def resolve_format(path: str | Path, fmt: str | None = None) -> str:
    """The format of ``path``: ``fmt`` when given, else from its content, else its extension.

    The content wins over the extension (NMEA saved as ``.txt``, GeoJSON as
    ``.json``, a CSV named ``.log``): the first bytes say ``PAR1`` (Parquet),
    ``<`` (XML: GPX), ``{`` (GeoJSON), ``$``/``!`` (NMEA 0183). Anything else
    is what the extension says, and CSV when it says nothing.
    """
    path = Path(path)
    if fmt is not None:
        name = fmt.lower()
        if name not in FORMATS:
            raise ConfigError(f"unknown format {fmt!r}; use one of {', '.join(FORMATS)}")
        return name
    by_extension = _extension_format(path)
    if by_extension == "rosbag" or is_rosbag(path):  # binary bags: the extension decides
        return "rosbag"
    if not path.is_file():
        return by_extension or "csv"  # the reader says what is wrong with the path
    try:
        with open_bytes(path) as raw:
            head = raw.read(256).lstrip(b"\xef\xbb\xbf \t\r\n")
    except READ_ERRORS as exc:
        if by_extension is not None:
            return by_extension  # the reader reports what is wrong with the file
        raise InputError(f"cannot read compressed data: {exc}", source=str(path)) from None
    if head.startswith(b"PAR1"):
        return "parquet"
    if head.startswith(b"<"):
        return "gpx"
    if head.startswith(b"{"):
        return "geojson"
    if head.startswith((b"$", b"!")):
        return "nmea"
    if by_extension == "nmea":
        # A CSV named .log is a CSV; a banner line before NMEA sentences is still NMEA.
        return "csv" if _looks_like_csv(head) else "nmea"
    return by_extension or "csv"


def read_table(
    path: str | Path,
    fmt: str | None = None,
    columns: ColumnMap | None = None,
    **options: Unpack[ReadKeywords],
) -> Table:
    """Read a track file into a :class:`Table`, keeping every input column.

    ``columns`` names the role of columns (anything ``None`` is auto-detected
    later by :func:`gradgps.to_fixes`); it overrides what a reader already
    knows (GPX and NMEA readers set their own column map). The other
    keywords say what guessing cannot (``None``: guessed as before):
    ``decimal`` ``"."`` or ``","`` (the decimal separator of numbers written
    as text), ``time_format`` (a strptime format of the time column, e.g.
    ``"%d.%m.%Y %H:%M:%S"``), ``skip_rows`` (lines before a CSV header, e.g.
    a row count), ``speed_unit`` (``"m/s"``, ``"km/h"``, ``"mph"``,
    ``"knots"``; speeds are converted to m/s), ``crs`` (the coordinate
    reference system of projected ``X``/``Y`` columns, e.g. ``"EPSG:25832"``;
    converted to WGS84 longitude/latitude with pyproj, extra ``geo``). They
    are kept on the table for :func:`gradgps.to_fixes`, which applies them.
    """
    return load_table(path, fmt, columns, reader_options(options))


def reader_options(options: ReadKeywords) -> ReadOptions:
    """The reader keywords of :func:`read_table` and its kin as one :class:`ReadOptions`
    (a keyword that is not one is a ``TypeError``, as for any Python function)."""
    check_keywords(options, ReadKeywords)
    return ReadOptions(**options)


def load_table(
    path: str | Path,
    fmt: str | None = None,
    columns: ColumnMap | None = None,
    options: ReadOptions | None = None,
) -> Table:
    """:func:`read_table` with the reader options as one object.

    The CLI calls this with ``ReadOptions(cli=True)``, so that errors name its
    flags (``--time-format``) instead of Python's keyword arguments.
    """
    path = Path(path)
    options = (options or ReadOptions()).checked()
    kind = resolve_format(path, fmt)
    _check_options_apply(kind, options, str(path))
    if kind == "rosbag":
        table = read_rosbag(path)
        return (
            table if columns is None else replace(table, columns=_override(table.columns, columns))
        )
    check_readable(path)
    if kind == "csv":
        table = _read_csv(path, columns, options)
    elif kind == "parquet":
        table = _read_parquet(path)
    elif kind == "gpx":
        table = read_gpx(path)
    elif kind == "geojson":
        table = read_geojson(path)
    else:
        table = read_nmea(path)
    if columns is not None:
        table = replace(table, columns=_override(table.columns, columns))
    return replace(table, options=options)


def read_fixes(
    path: str | Path,
    fmt: str | None = None,
    columns: ColumnMap | None = None,
    channels: tuple[str, ...] | list[str] = (),
    **options: Unpack[ReadKeywords],
) -> pd.DataFrame:
    """Read a track file straight into the canonical fixes frame (see :mod:`gradgps._tracks.track`).

    The keywords are :func:`read_table`'s.
    """
    return to_fixes(read_table(path, fmt, columns, **options), channels=channels)


#: The formats where each reader option means something (the others type their own values).
_OPTION_FORMATS: Final = {
    "decimal": ("csv", "parquet"),
    "time_format": ("csv", "parquet"),
    "skip_rows": ("csv",),
    "speed_unit": ("csv", "parquet"),
    "crs": ("csv", "parquet"),
}


def _check_options_apply(kind: str, options: ReadOptions, source: str) -> None:
    """An option given for a format it does not apply to is an error, never silently ignored."""
    for option in options.given:
        formats = _OPTION_FORMATS[option]
        if kind not in formats:
            raise ConfigError(
                f"{source}: {options.name(option)} applies to "
                f"{' and '.join(f.upper() if f == 'csv' else f.title() for f in formats)} "
                f"files, not to {kind}; leave it out for this file"
            )


def write_table(
    frame: pd.DataFrame,
    path: str | Path,
    fmt: str | None = None,
    *,
    geometry: GeoPoints | None = None,
) -> None:
    """Write ``frame`` as CSV (gzip for ``.gz``) or Parquet, without the index.

    CSV floats are written in their shortest exact form, so reading the file
    back gives the same numbers; datetime columns as ISO-8601 text.
    ``geometry``: the points of a GeoParquet input (``Table.geometry``),
    whose column ``frame`` still holds as WKB: Parquet output stays
    GeoParquet (the same ``geo`` metadata), CSV output gets them as WKT.
    """
    path = Path(path)
    kind = resolve_format(path, fmt) if fmt is not None else _extension_format(path)
    if kind is None:
        raise ConfigError(
            f"cannot tell the output format of {str(path)!r} from its extension; "
            "name it .csv, .csv.gz or .parquet (from Python, write_table also takes fmt=)"
        )
    if kind not in ("csv", "parquet"):
        raise ConfigError(f"writing {kind} is not supported; write csv or parquet")
    try:
        if kind == "csv":
            if geometry is not None and geometry.column in frame.columns:
                frame = frame.copy()
                frame[geometry.column] = wkt_points(geometry.x, geometry.y)
            csv_ready(frame).to_csv(path, index=False)
        elif geometry is not None and geometry.column in frame.columns:
            write_geoparquet(frame, path, geometry)
        else:
            frame.to_parquet(path, index=False)
    except ImportError as exc:
        raise ConfigError(f"writing Parquet needs pyarrow ({exc}); install gradgps[io]") from None
    except OSError as exc:
        raise ConfigError(f"cannot write {str(path)!r}: {exc.strerror or exc}") from None


class TableWriter:
    """Write a table chunk by chunk (CSV, gzip CSV or Parquet), atomically.

    For outputs too big to hold in memory: every :meth:`write` appends rows
    (the CSV header comes from the first chunk; later chunks must have the
    same columns). Rows go to ``<name>.partial`` beside the target, renamed to
    the target only by a clean exit from the ``with`` block, so a run stopped
    by an error never leaves a truncated file that looks finished.

    Parquet column types: ``types`` (column -> pandas dtype name, e.g.
    :data:`gradgps._result.RESULT_DTYPES`) fixes the type of the columns it
    names from the first chunk on, text (``object``) as strings, so a first
    chunk with no invalid rows or no bias types cannot type those columns
    otherwise. Any other column is typed by what the chunks hold, because
    no chunk can tell the whole file's type (a column empty in the first
    chunk reads as float, one with a word only in a later chunk as text):
    when a later chunk needs a wider type (null < integer < float < text),
    the rows already written are copied once into a file of the wider
    schema, one row group at a time, so memory stays bounded and no value is
    lost; a chunk whose column is empty fits any type.
    """

    def __init__(self, path: str | Path, types: Mapping[str, str] | None = None) -> None:
        self.path = Path(path)
        kind = _extension_format(self.path)
        if kind not in ("csv", "parquet"):
            raise ConfigError(
                f"cannot write {str(self.path)!r}: use a .csv, .csv.gz or .parquet output"
            )
        self.kind = kind
        self.partial = self.path.with_name(self.path.name + ".partial")
        self.rows = 0
        self.types = dict(types or {})
        self._columns: list[str] | None = None
        self._text: IO[str] | None = None
        self._parquet: Any = None
        self._working = self.partial  # the Parquet file being written (changes when widened)
        self._rewrites = 0
        self._geo: bytes | None = None  # the ``geo`` metadata of a GeoParquet output

    def __enter__(self) -> TableWriter:
        return self

    def __exit__(self, kind: type[BaseException] | None, *_: object) -> None:
        self._close()
        if kind is None:
            self.partial.replace(self.path)
        else:
            self.partial.unlink(missing_ok=True)
            self._working.unlink(missing_ok=True)

    @property
    def started(self) -> bool:
        """Whether a frame (perhaps an empty one, fixing the columns) was written."""
        return self._columns is not None

    def write(self, frame: pd.DataFrame, geometry: GeoPoints | None = None) -> None:
        """Append ``frame``'s rows (without its index). ``geometry``: the chunk's points of
        a GeoParquet input (``Table.geometry``), whose column ``frame`` holds as WKB: written
        as :func:`write_table` writes them (WKT in a CSV; a Parquet output keeps the WKB and
        gets the input's ``geo`` metadata)."""
        if geometry is not None and geometry.column in frame.columns:
            if self.kind == "csv":
                frame = frame.copy()
                frame[geometry.column] = wkt_points(geometry.x, geometry.y)
            elif self._geo is None:
                self._geo = geometry.metadata
        columns = [str(c) for c in frame.columns]
        if self._columns is None:
            self._columns = columns
        elif columns != self._columns:
            raise ConfigError(
                f"chunk columns {columns} differ from the first chunk's {self._columns}"
            )
        try:
            if self.kind == "csv":
                self._write_csv(frame)
            else:
                self._write_parquet(frame, columns)
        except OSError as exc:
            raise ConfigError(f"cannot write {str(self.path)!r}: {exc.strerror or exc}") from None
        self.rows += len(frame)

    def _write_csv(self, frame: pd.DataFrame) -> None:
        first = self._text is None
        if self._text is None:
            if self.path.suffix.lower() == ".gz":
                self._text = gzip.open(self.partial, "wt", encoding="utf-8", newline="")  # noqa: SIM115
            else:
                self._text = open(self.partial, "w", encoding="utf-8", newline="")  # noqa: SIM115
        csv_ready(frame).to_csv(self._text, index=False, header=first)

    def _write_parquet(self, frame: pd.DataFrame, names: list[str]) -> None:
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError as exc:
            raise ConfigError(
                f"writing Parquet needs pyarrow ({exc}); install gradgps[io]"
            ) from None
        old = None if self._parquet is None else self._parquet.schema
        arrays: list[Any] = []
        types: list[Any] = []
        for k, name in enumerate(names):
            array = _arrow_array(frame.iloc[:, k])
            declared = self.types.get(name)
            if declared is not None:
                target = _arrow_type(declared)
            elif old is None:
                target = array.type
            elif array.null_count == len(array):
                target = old.field(k).type
            else:
                target = _wider(old.field(k).type, array.type)
            if array.type != target:
                try:
                    array = (
                        pa.nulls(len(array), target)
                        if array.null_count == len(array)
                        else array.cast(target)
                    )
                except (pa.ArrowInvalid, pa.ArrowTypeError, pa.ArrowNotImplementedError) as exc:
                    raise ConfigError(
                        f"cannot write {str(self.path)!r}: column {name!r} of rows "
                        f"{self.rows + 1}.. is not {declared or target} ({exc})"
                    ) from None
            arrays.append(array)
            types.append(target)
        schema = pa.schema(
            [pa.field(n, t) for n, t in zip(names, types, strict=True)],
            metadata=None if self._geo is None else {b"geo": self._geo},
        )
        if old is None:
            self._parquet = pq.ParquetWriter(self._working, schema)
        elif not schema.equals(old):
            self._widen(schema)
        self._parquet.write_table(pa.Table.from_arrays(arrays, schema=schema))

    def _widen(self, schema: Any) -> None:
        """Copy the rows written so far into a new working file of ``schema`` (wider types)."""
        import pyarrow as pa
        import pyarrow.parquet as pq

        self._parquet.close()
        previous = self._working
        self._rewrites += 1
        self._working = self.partial.with_name(f"{self.partial.name}.{self._rewrites}")
        self._parquet = pq.ParquetWriter(self._working, schema)
        for batch in pq.ParquetFile(previous).iter_batches():
            self._parquet.write_table(pa.Table.from_batches([batch]).cast(schema))
        previous.unlink()

    def _close(self) -> None:
        if self._columns is None:
            # Nothing written: still leave a (header-less, empty) file behind.
            self.partial.touch()
        if self._text is not None:
            self._text.close()
            self._text = None
        if self._parquet is not None:
            self._parquet.close()
            self._parquet = None
            if self._working != self.partial:
                self._working.replace(self.partial)
                self._working = self.partial


def _arrow_type(dtype: str) -> Any:
    """The Parquet type of a declared pandas dtype (``object`` columns hold text)."""
    import pyarrow as pa

    return pa.string() if dtype == "object" else pa.from_numpy_dtype(np.dtype(dtype))


def _arrow_array(series: pd.Series) -> Any:
    """A column as Arrow (NaN/None -> null); values of mixed Python types as their text."""
    import pyarrow as pa

    try:
        return pa.array(series, from_pandas=True)
    except (pa.ArrowInvalid, pa.ArrowTypeError):
        return pa.array([None if pd.isna(v) else str(v) for v in series], type=pa.string())


def _wider(have: Any, new: Any) -> Any:
    """The narrowest type holding both (null < integer < float < text; anything else: text)."""
    import pyarrow as pa

    t = pa.types
    text = (t.is_string(have) or t.is_large_string(have)) and (
        t.is_string(new) or t.is_large_string(new)
    )
    if have == new or t.is_null(new) or text:
        return have
    if t.is_null(have):
        return new
    if t.is_integer(have) and t.is_integer(new):
        return pa.int64()
    numeric = (t.is_integer(have) or t.is_floating(have)) and (
        t.is_integer(new) or t.is_floating(new)
    )
    return pa.float64() if numeric else pa.string()


def iter_csv_tables(
    path: str | Path,
    chunksize: int,
    columns: ColumnMap | None = None,
    **options: Unpack[ReadKeywords],
) -> CsvChunks:
    """Read a big CSV as a stream of Tables of at most ``chunksize`` rows each.

    Memory stays bounded by the chunk size (at most :data:`MAX_CHUNK_ROWS` rows and
    :data:`MAX_CHUNK_CELLS` cells, whatever is asked). Each chunk's ``row_offset`` and
    ``first_line`` say where it sits in the file, so value errors found in a
    later chunk name the right row and line. The structure of the whole file
    is checked here, before any chunk is handed out (one streaming pass), so
    a ragged row near the end fails at once, not after hours of work; that
    pass also counts the rows (:attr:`CsvChunks.n_rows`, for progress bars).
    The keywords are :func:`read_table`'s.
    """
    return table_chunks(path, chunksize, columns, reader_options(options), "csv")


@dataclass
class CsvChunks(Iterator[Table]):
    """The chunks of a CSV (an iterator of Tables) plus what the structure pass learned.

    ``n_rows``: data rows in the file; ``header``: the column names as written.
    """

    n_rows: int
    header: tuple[str, ...]
    chunks: Iterator[Table]

    def __next__(self) -> Table:
        return next(self.chunks)


def _pandas_csv(
    path: Path, layout: _CsvLayout, columns: ColumnMap | None, source: str, **options: Any
) -> Any:
    """``pd.read_csv`` as every CSV reader here calls it (``options``: e.g. ``chunksize``).

    Each frame or chunk is typed as a whole (``low_memory=False``: no
    mixed-type columns, no DtypeWarning); label columns stay text.
    """
    return pd.read_csv(
        path,
        sep=layout.delimiter,
        encoding="utf-8",
        skiprows=layout.skip,
        low_memory=False,
        dtype=_label_dtypes(layout, columns, source),
        **options,
    )


def _csv_chunks(
    path: Path, layout: _CsvLayout, chunksize: int, columns: ColumnMap, options: ReadOptions
) -> Iterator[Table]:
    source = str(path)
    offset = 0
    # Memory is rows x columns: a very wide file is read in fewer rows at a time.
    chunksize = _bounded_rows(chunksize, len(layout.header))
    with _pandas_errors(source):
        reader = _pandas_csv(path, layout, columns, source, chunksize=chunksize)
        with reader:
            for chunk in reader:
                first_line = layout.first_line + offset if layout.lines_regular else None
                yield Table(
                    frame=chunk,
                    source=source,
                    columns=columns,
                    first_line=first_line,
                    row_offset=offset,
                    options=options,
                )
                offset += len(chunk)


def _looks_like_csv(head: bytes) -> bool:
    """A first line with delimiters and no ``$`` sentence: a header row."""
    first = head.split(b"\n", 1)[0]
    return b"$" not in first and any(first.count(d.encode()) >= 2 for d in _DELIMITERS)


def _override(base: ColumnMap, given: ColumnMap) -> ColumnMap:
    chosen = base.as_dict()
    chosen.update({k: v for k, v in given.as_dict().items() if v is not None})
    return ColumnMap(**chosen)


def _extension_format(path: Path) -> str | None:
    """The format named by the extension (ignoring a final ``.gz``), or None."""
    suffixes = [s.lower() for s in path.suffixes]
    if suffixes and suffixes[-1] == ".gz":
        suffixes = suffixes[:-1]
    return _EXTENSIONS.get(suffixes[-1]) if suffixes else None


@dataclass(frozen=True)
class _CsvLayout:
    """What the structure pass learned: enough to parse and to map rows to lines."""

    delimiter: str
    header: tuple[str, ...]
    first_line: int  # file line of data row 1 when lines are regular
    n_rows: int
    lines_regular: bool  # data row k sits on line first_line + k - 1 (no blank or multi-line rows)
    skip: int = 0  # lines before the header (a row-count line)


def _is_blank(record: list[str]) -> bool:
    # pandas skips empty and whitespace-only lines; so must the row count.
    return not record or (len(record) == 1 and not record[0].strip())


def _scan_csv(path: Path, options: ReadOptions | None = None) -> _CsvLayout:
    """Check the structure of a CSV in one streaming pass (see the module docstring).

    ``options.skip_rows`` lines before the header are skipped unread; ``None`` skips
    a first line that is a row count (GPSLogger), a guess a header of one
    numeric column name would defeat.
    """
    source = str(path)
    options = options or ReadOptions()
    skip_rows = options.skip_rows
    with open_bytes(path) as raw:
        lines = text_lines(raw, source)
        header_line = 0
        header_text = ""
        for _ in itertools.islice(lines, skip_rows or 0):
            header_line += 1
        for text in lines:
            header_line += 1
            if text.strip():
                header_text = text
                break
        skip = skip_rows or 0
        if skip_rows is None and _is_count_line(header_text):
            # GPSLogger and others write the number of rows on the first line.
            skip = header_line
            header_text = ""
            for text in lines:
                header_line += 1
                if text.strip():
                    header_text = text
                    break
        if not header_text and skip:
            raise InputError(
                f"no header line after the {skip} skipped lines",
                source=source,
                hint=f"skip fewer lines with {options.name('skip_rows')}",
            )
        if not header_text:
            raise InputError(
                "empty file: no header line and no data",
                source=source,
                hint="a CSV needs a header line naming the columns, then one row per fix",
            )
        delimiter = max(_DELIMITERS, key=header_text.count)
        if header_text.count(delimiter) == 0:
            delimiter = ","
        reader = csv.reader(itertools.chain([header_text], lines), delimiter=delimiter, strict=True)
        # reader.line_num counts lines from the header; file line = line_num + base.
        base = header_line - 1
        prev_end = header_line
        n_rows = 0
        regular = True
        try:
            header = next(reader)
            _check_header(header, source, header_line)
            for record in reader:
                end = reader.line_num + base
                start = prev_end + 1
                prev_end = end
                if _is_blank(record):
                    continue
                n_rows += 1
                if end != header_line + n_rows:
                    regular = False
                if len(record) != len(header):
                    raise InputError(
                        f"{len(record)} fields where the header has {len(header)}",
                        source=source,
                        row=n_rows,
                        line=start,
                        hint="a truncated line, a stray delimiter or an unquoted text field; fix that line",
                    )
        except csv.Error as exc:
            raise InputError(
                f"malformed CSV record starting here: {exc}",
                source=source,
                line=prev_end + 1,
                hint="check the quoting on that line (a quote must close its field)",
            ) from None
    return _CsvLayout(
        delimiter=delimiter,
        header=tuple(header),
        first_line=header_line + 1,
        n_rows=n_rows,
        lines_regular=regular,
        skip=skip,
    )


def _is_count_line(text: str) -> bool:
    """A first line that is one whole number (a row count), not a header."""
    return text.strip().lstrip("\ufeff").isdigit()


def _check_header(header: list[str], source: str, line: int) -> None:
    def is_number(text: str) -> bool:
        try:
            float(text)
        except ValueError:
            return False
        return True

    if header and all(is_number(name) for name in header):
        raise InputError(
            "the first line holds numbers, not column names: the file has no header",
            source=source,
            line=line,
            hint="add a header line naming the columns, e.g. 't,lat,lon'",
        )


@contextmanager
def _pandas_errors(source: str) -> Iterator[None]:
    """Turn what pandas may still raise after the structure pass into InputError."""
    try:
        yield
    except (pd.errors.ParserError, pd.errors.EmptyDataError, UnicodeDecodeError) as exc:
        raise InputError(f"cannot parse as CSV: {exc}", source=source) from None
    except READ_ERRORS as exc:
        raise InputError(f"cannot read: {exc}", source=source) from None


def _label_dtypes(layout: _CsvLayout, columns: ColumnMap | None, source: str) -> dict[str, str]:
    """Read the track-id column as text: ``007`` is a label, not the number 7.

    Only when the column map can already be resolved from the header; when it
    cannot, :func:`gradgps.to_fixes` reports why later.
    """
    try:
        track = resolve_columns(layout.header, columns, source=source).track
    except InputError:
        return {}
    return {track: "string"} if track is not None else {}


def _read_csv(path: Path, columns: ColumnMap | None, options: ReadOptions) -> Table:
    source = str(path)
    layout = _scan_csv(path, options)
    with _pandas_errors(source):
        frame = _pandas_csv(path, layout, columns, source)
    regular = layout.lines_regular and len(frame) == layout.n_rows
    return Table(frame=frame, source=source, first_line=layout.first_line if regular else None)


def _parquet_tables(
    path: Path, chunksize: int, columns: ColumnMap, options: ReadOptions
) -> CsvChunks:
    """A Parquet file as a stream of Tables of at most ``chunksize`` rows: record batches of
    one row group at a time, so memory is bounded by the chunk and the file's largest row
    group, not by the file. Each chunk is converted to pandas exactly as
    :func:`pandas.read_parquet` converts the whole file; a stored (non-range) index, which
    pandas writes for a time-indexed frame, becomes leading columns in each chunk as in the
    whole file (:func:`_index_as_columns`)."""
    source = str(path)
    check_readable(path)
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError as exc:
        raise _no_pyarrow(exc) from None
    try:
        # pre_buffer off: on, pyarrow reads ahead the column chunks of every row group
        # still to come and holds them (84 MB more at 4.69 M fixes, a 103 MB file; the
        # peak grew with the file, docs/reliability.md "Round two").
        file = pq.ParquetFile(path, pre_buffer=False)
        schema = file.schema_arrow
        n_rows = int(file.metadata.num_rows)
        # The columns the chunks will have: a stored index comes first, under its name.
        header = tuple(_index_as_columns(schema.empty_table().to_pandas()).columns)
    except (ValueError, OSError, TypeError) as exc:
        raise _unreadable_parquet(exc, source) from None
    geo = geo_metadata(path)
    geometry = None if geo is None else primary_column(geo)

    def chunks() -> Iterator[Table]:
        offset = 0
        rows = _bounded_rows(chunksize, len(schema.names))
        batches = file.iter_batches(batch_size=rows, use_pandas_metadata=True)
        while True:
            try:
                batch = next(batches, None)
                if batch is None:
                    return
                frame = _arrow_to_pandas(
                    pa.Table.from_batches([batch], schema=schema), keep_binary=geometry
                )
            except (ValueError, OSError, TypeError) as exc:
                raise _unreadable_parquet(exc, source) from None
            frame = _index_as_columns(frame)
            if geo is None:
                yield Table(
                    frame=frame, source=source, columns=columns, row_offset=offset, options=options
                )
            else:  # GeoParquet: each chunk's points decoded as the whole file's would be
                table = read_geoparquet(path, frame, geo, row_offset=offset)
                yield replace(table, columns=_override(table.columns, columns), options=options)
            offset += len(frame)

    return CsvChunks(n_rows=n_rows, header=header, chunks=chunks())


def table_chunks(
    path: str | Path,
    chunksize: int,
    columns: ColumnMap | None = None,
    options: ReadOptions | None = None,
    fmt: str | None = None,
) -> CsvChunks:
    """A track file of any of :data:`FORMATS` (``fmt``, or as :func:`resolve_format`
    finds it; any other format is read as CSV) as a stream of Tables of at most
    ``chunksize`` rows: a CSV as :func:`iter_csv_tables` describes, a Parquet file a row
    group at a time, GPX, NMEA, GeoJSON and ROS bags in two streaming passes
    (:func:`gradgps._io.gpx.gpx_tables`, :func:`gradgps._io.nmea.nmea_tables`,
    :func:`gradgps._io.geojson.geojson_tables`, :func:`gradgps._io.rosbag.rosbag_tables`);
    the rows,
    values and column roles :func:`load_table` gives for the whole file, in chunks, in
    bounded memory. Whatever ``chunksize`` asks, a chunk has at most :data:`MAX_CHUNK_ROWS`
    rows and :data:`MAX_CHUNK_CELLS` cells in every format (GPX, NMEA and bags counted at
    their widest row, :data:`STREAMED_WIDEST_ROW`; GeoJSON, whose properties make its
    columns, at the width its first pass finds), so no size holds the file. ``options``:
    the reader options as one object (see :func:`load_table`)."""
    found = resolve_format(path, fmt)
    kind = found if found in FORMATS else "csv"
    path, options = _chunked_read(path, chunksize, options, kind)
    if kind == "parquet":
        return _parquet_tables(path, chunksize, columns or ColumnMap(), options)
    if kind in ("gpx", "nmea", "geojson", "rosbag"):
        if kind == "geojson":  # as wide as its properties: cut once the first pass knows them
            check_readable(path)
            reader: StreamedChunks = geojson_tables(
                path, _bounded_rows(chunksize, 1), max_cells=MAX_CHUNK_CELLS
            )
        elif kind == "rosbag":  # a file or a ROS 2 bag directory
            reader = rosbag_tables(path, _bounded_rows(chunksize, STREAMED_WIDEST_ROW))
        else:
            check_readable(path)
            streamed = {"gpx": gpx_tables, "nmea": nmea_tables}
            reader = streamed[kind](path, _bounded_rows(chunksize, STREAMED_WIDEST_ROW))
        cmap = reader.columns if columns is None else _override(reader.columns, columns)
        return CsvChunks(
            n_rows=reader.n_rows,
            header=reader.header,
            chunks=(replace(t, columns=cmap, options=options) for t in reader.chunks),
        )
    layout = _scan_csv(path, options)
    return CsvChunks(
        n_rows=layout.n_rows,
        header=layout.header,
        chunks=_csv_chunks(path, layout, chunksize, columns or ColumnMap(), options),
    )


def _arrow_to_pandas(table: Any, keep_binary: str | None = None) -> pd.DataFrame:
    """A pyarrow table as :func:`pandas.read_parquet` converts one, so a file read chunk by
    chunk gives the frame it gives read whole: pandas 3 names its converter
    (``pandas.io._util.arrow_table_to_pandas``); pandas 2.2, which ``pyproject.toml``
    allows, has none and calls ``to_pandas`` itself (Arrow strings only under
    ``future.infer_string``).

    ``keep_binary``: a column (a GeoParquet chunk's WKB geometry) kept as Arrow binary
    (``pd.ArrowDtype``) in its place, not made a Python ``bytes`` per row: those, made and
    dropped chunk after chunk, kept Python's allocator growing with the file (issue 18,
    docs/reliability.md "Round three"); the output writes the same values either way."""
    if keep_binary is not None and keep_binary in table.column_names:
        at = table.column_names.index(keep_binary)
        rest = _arrow_to_pandas(table.remove_column(at))
        values = pd.arrays.ArrowExtensionArray(table.column(at))
        rest.insert(at, keep_binary, pd.Series(values, index=rest.index))
        return rest
    try:
        from pandas.io._util import (  # type: ignore[import-not-found]
            arrow_table_to_pandas,
        )
    except ImportError:
        mapper = None
        with warnings.catch_warnings():  # deprecated (and always on) from pandas 3
            warnings.simplefilter("ignore")
            infer_string = pd.get_option("future.infer_string")
        try:
            from pandas.io._util import arrow_string_types_mapper
        except ImportError:  # no string mapper in this pandas: plain to_pandas
            infer_string = False
        if infer_string:
            mapper = arrow_string_types_mapper()
        frame: pd.DataFrame = table.to_pandas(types_mapper=mapper)
        return frame
    converted: pd.DataFrame = arrow_table_to_pandas(table)
    return converted


def _chunked_read(
    path: str | Path, chunksize: int, options: ReadOptions | None, kind: str
) -> tuple[Path, ReadOptions]:
    """Check a chunked reader's arguments once (every chunked format alike),
    including, as :func:`load_table` does, that every option given applies to ``kind``."""
    if isinstance(chunksize, bool) or not isinstance(chunksize, int) or chunksize < 1:
        raise ConfigError(f"chunksize must be a positive integer, got {chunksize!r}")
    checked = (options or ReadOptions()).checked()
    _check_options_apply(kind, checked, str(path))
    return Path(path), checked


def _unreadable_parquet(exc: Exception, source: str) -> InputError:
    """The one error for a file pyarrow cannot read (pyarrow's ArrowInvalid is a
    ValueError: not Parquet, truncated, damaged), whole or chunk by chunk."""
    return InputError(
        f"not a readable Parquet file: {exc}",
        source=source,
        hint="check the file, or pass the right format",
    )


def _no_pyarrow(exc: ImportError) -> ConfigError:
    return ConfigError(f"reading Parquet needs pyarrow ({exc}); install gradgps[io]")


def _index_as_columns(frame: pd.DataFrame) -> pd.DataFrame:
    """``frame`` with a stored index (often the time of a time-indexed frame) made leading
    columns like the rest, and a fresh range index: one rule for the whole file and for
    each chunk, so both have the same columns."""
    if not isinstance(frame.index, pd.RangeIndex):
        frame = frame.reset_index()
    return frame.reset_index(drop=True)


def _read_parquet(path: Path) -> Table:
    source = str(path)
    try:
        frame = pd.read_parquet(path)
    except ImportError as exc:
        raise _no_pyarrow(exc) from None
    except (ValueError, OSError, TypeError) as exc:
        raise _unreadable_parquet(exc, source) from None
    frame = _index_as_columns(frame)
    geo = geo_metadata(path)
    if geo is not None:
        return read_geoparquet(path, frame, geo)
    return Table(frame=frame, source=source)
