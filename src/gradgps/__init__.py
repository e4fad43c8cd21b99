"""gradgps: find, classify and repair faults in vehicle GPS and sensor streams.

An implementation of GRAD (REMA + multi-stage sliding-window features + a
small GRU) built for real-time use. The public API is exactly ``__all__``;
everything in underscore modules is private and may change.
"""

from __future__ import annotations

from . import metrics
from ._chunked import TrackStreams
from ._datasets import load_dataset
from ._detector import Detector
from ._exceptions import ConfigError, DataNotFoundError, GradGPSError, InputError, ModelError
from ._geo import LocalFrame
from ._inject import inject_grad, inject_sensor_grid
from ._io import iter_csv_tables, read_fixes, read_table, write_table
from ._preprocess import Prepared, preprocess
from ._rema import RemaParams
from ._rema_detector import RemaDetector
from ._result import PointResult
from ._simulator import SimulatorParams, simulate_drive, simulate_fleet
from ._speed_gate import SpeedGate
from ._track import ColumnMap, Table, to_fixes

__version__ = "0.1.0"

__all__ = [
    "ColumnMap",
    "ConfigError",
    "DataNotFoundError",
    "Detector",
    "GradGPSError",
    "InputError",
    "LocalFrame",
    "ModelError",
    "PointResult",
    "Prepared",
    "RemaDetector",
    "RemaParams",
    "SimulatorParams",
    "SpeedGate",
    "Table",
    "TrackStreams",
    "__version__",
    "inject_grad",
    "inject_sensor_grid",
    "iter_csv_tables",
    "load_dataset",
    "metrics",
    "preprocess",
    "read_fixes",
    "read_table",
    "simulate_drive",
    "simulate_fleet",
    "to_fixes",
    "write_table",
]
