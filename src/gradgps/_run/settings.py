"""What a detection run over files is told, as one object: which detector, how to read.

``gradgps detect`` (chunk by chunk) and ``gradgps detect-fleet`` (a Dask task
per vehicle) pass the same five settings from the command line down to the
code that reads a file and makes its detectors; :class:`RunSettings` carries
them, so each layer takes and forwards one object (and a Dask task is sent
one picklable value) instead of five keywords spelled at every step.
"""

from __future__ import annotations

import os
from dataclasses import dataclass

from .._tracks.track import ColumnMap, ReadOptions

__all__ = ["DEFAULT_SETTINGS", "RunSettings"]


@dataclass(frozen=True)
class RunSettings:
    """The detector and the reading of a run.

    ``model``: a model directory (``None``: the default model shipped with
    gradgps); ``threshold``: overrides the model's anomaly threshold;
    ``fmt``: the input format (``None``: from the file's content and name,
    :func:`gradgps._io.read.resolve_format`); ``columns``: column names
    (``None``: found by name); ``options``: the reader options
    (:func:`gradgps._io.read.load_table`).
    """

    model: str | os.PathLike[str] | None = None
    threshold: float | None = None
    fmt: str | None = None
    columns: ColumnMap | None = None
    options: ReadOptions | None = None


#: The settings of a run told nothing: the default model, everything read as found.
DEFAULT_SETTINGS = RunSettings()
