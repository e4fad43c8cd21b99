"""Whole-file detection through the library: the reference ``gradgps detect``'s chunked
outputs must equal, byte for byte.

``gradgps detect`` reads every file in chunks; ``--chunk-size 0`` asks for the
largest chunks, no longer for the whole file (issue 18: it held about 10 GB for a 1 GB
CSV). So a test comparing the chunked output with whole-file detection cannot get the
latter from the CLI any more; :func:`detect_whole` makes it as the CLI's whole-file
branch did: the whole table (:func:`gradgps._io.read.load_table`), one
:meth:`~gradgps._grad.detector.Detector.detect_fixes` call on all of it, the input
columns then the result written by :func:`~gradgps._io.read.write_table`, the events in
the input's time form, the GeoJSON and GPX exports, the report page, and the counts of
the summary line.
"""

from __future__ import annotations

import time
from pathlib import Path

import pandas as pd

from gradgps._cli.detect import _events_in_input_form, _time_column, _time_name
from gradgps._grad.detector import Detector
from gradgps._grad.events import EventBuilder
from gradgps._io.export_streamed import StreamedExports
from gradgps._io.read import load_table, write_table
from gradgps._io.times import output_time_text
from gradgps._result import ResultCounts
from gradgps._tracks.input_checks import input_warnings, validated_rates
from gradgps._tracks.track import ColumnMap, to_fixes


def detect_whole(
    path: Path,
    output: Path | None = None,
    *,
    events: Path | None = None,
    geojson: Path | None = None,
    gpx: Path | None = None,
    report: Path | None = None,
    fmt: str | None = None,
    columns: ColumnMap | None = None,
) -> str:
    """Detect every fix of ``path`` read whole and write what ``gradgps detect`` writes
    (``output``, ``events``, ``geojson``, ``gpx``, ``report``: each where given); the
    summary line's counts (``"N rows, A anomalies (I invalid fixes), L alerts"``)."""
    table = load_table(path, fmt, columns)
    fixes = to_fixes(table)
    detector = Detector()
    started = time.perf_counter()
    result = detector.detect_fixes(fixes)
    elapsed = time.perf_counter() - started
    if output is not None:
        frame = table.frame.reset_index(drop=True)
        write_table(
            pd.concat([frame, result.reset_index(drop=True)], axis=1),
            output,
            geometry=table.geometry,
        )
    builder = EventBuilder()
    builder.add(fixes, result)
    found = builder.events()
    if events is not None:
        write_table(_events_in_input_form(found, _time_column(table.frame, fixes)), events)
    if geojson is not None or gpx is not None:
        with StreamedExports(geojson, gpx) as exports:
            exports.add(fixes, result)
            exports.finish(found)
    if report is not None:
        from gradgps._cli.report import write_report_outputs

        lowest, highest = validated_rates(detector.model_.config)
        write_report_outputs(
            report,
            None,
            fixes,
            result,
            detector,
            elapsed,
            str(path),
            events=found,
            warnings=input_warnings(fixes, min_rate_hz=lowest, max_rate_hz=highest),
            time_text=output_time_text(table.frame, _time_name(fixes)),
        )
    return ResultCounts.of(result).text()
