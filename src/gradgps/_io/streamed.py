"""What a streamed reader gives: a file's Tables, a chunk at a time, and what its first
pass learned of the whole file.

Apart from :mod:`gradgps._io.files` (bytes and lines, below every reader) so that the
byte-level helpers import nothing of the track model.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

from .._tracks.track import ColumnMap, Table

__all__ = ["StreamedChunks"]


@dataclass(frozen=True)
class StreamedChunks:
    """A GPX, NMEA, GeoJSON or ROS bag file as Tables of at most a chunk's rows, read in
    two streaming passes (:func:`gradgps._io.gpx.gpx_tables`,
    :func:`gradgps._io.nmea.nmea_tables`, :func:`gradgps._io.geojson.geojson_tables`,
    :func:`gradgps._io.rosbag.rosbag_tables`): what the first pass learned (``n_rows``, the ``header`` and the column roles ``columns``)
    and the chunks the second pass yields."""

    n_rows: int
    header: tuple[str, ...]
    columns: ColumnMap
    chunks: Iterator[Table]
