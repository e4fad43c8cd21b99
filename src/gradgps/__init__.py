"""gradgps: find, classify and repair faults in vehicle GPS and sensor streams.

An implementation of GRAD (REMA + multi-stage sliding-window features + a
small GRU) built for real-time use. The public API is exactly ``__all__``;
everything in underscore modules is private and may change.
"""

from __future__ import annotations

from types import FunctionType as _FunctionType

from . import metrics
from ._baselines.rema_detector import RemaDetector
from ._baselines.speed_gate import SpeedGate
from ._data.datasets import load_dataset
from ._data.inject import inject_grad, inject_sensor_grid
from ._data.simulator import SimulatorParams, simulate_drive, simulate_fleet
from ._exceptions import ConfigError, DataNotFoundError, GradGPSError, InputError, ModelError
from ._grad.api import clean, detect
from ._grad.detector import Detector, TrackStreams
from ._grad.rema import RemaParams
from ._io.read import iter_csv_tables, read_fixes, read_table, write_table
from ._result import PointResult
from ._tracks.geo import LocalFrame
from ._tracks.preprocess import Prepared, preprocess
from ._tracks.track import ColumnMap, Table, to_fixes
from ._version import __version__

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
    "clean",
    "detect",
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

# The curated classes and functions report the module they are reached
# through (``gradgps.Detector``, not ``gradgps._grad.detector.Detector``).
for _name in __all__:
    _obj = globals()[_name]
    if isinstance(_obj, (type, _FunctionType)) and _obj.__module__.startswith(f"{__name__}._"):
        _obj.__module__ = __name__
del _name, _obj
