"""gradgps: find, classify and repair faults in vehicle GPS and sensor streams.

An implementation of GRAD (REMA + multi-stage sliding-window features + a
small GRU) built for real-time use. The product is exactly ``__all__``: the
:class:`Detector` for one vehicle's stream or whole tables, the
:class:`MultiTrackDetector` for many vehicles' streams, one Detector per
vehicle, the :class:`FleetDetector` for the same with every vehicle's state
in shared arrays, so a batch of fixes of any mix of vehicles is scored in one
compiled call (fleets: a Redis worker's page, a thousand vehicles at 1 Hz;
same verdicts and states as a Detector per vehicle), readers and the track
model, the per-fix :class:`PointResult`, the errors, and the
``speed-gate`` and ``rema`` baselines. The evaluation kit lives in public
submodules: :mod:`gradgps.simulate` (simulated drives), :mod:`gradgps.inject`
(fault injection), :mod:`gradgps.datasets` (the shared data sets) and
:mod:`gradgps.metrics` (benchmark metrics). Everything in underscore modules
is private and may change.
"""

from __future__ import annotations

from . import datasets, inject, metrics, simulate
from ._baselines.rema_detector import RemaDetector
from ._baselines.speed_gate import SpeedGate
from ._exceptions import (
    ConfigError,
    DataNotFoundError,
    GradGPSError,
    InputError,
    InputWarning,
    ModelError,
)
from ._grad.api import clean, detect
from ._grad.detector import Detector, FleetDetector, MultiTrackDetector
from ._grad.detector import TrackStreams as TrackStreams  # deprecated name of MultiTrackDetector
from ._grad.rema import RemaParams
from ._io.read import iter_csv_tables, read_fixes, read_table, write_table
from ._public import claim
from ._result import PointResult
from ._tracks.geo import LocalFrame
from ._tracks.preprocess import Prepared, preprocess
from ._tracks.track import ColumnMap, Table, to_fixes
from ._version import __version__

# The evaluation kit's names, still importable from the top for older code.
from .datasets import load_dataset as load_dataset
from .inject import inject_grad as inject_grad
from .inject import inject_sensor_grid as inject_sensor_grid
from .simulate import SimulatorParams as SimulatorParams
from .simulate import simulate_drive as simulate_drive
from .simulate import simulate_fleet as simulate_fleet

__all__ = [
    "ColumnMap",
    "ConfigError",
    "DataNotFoundError",
    "Detector",
    "FleetDetector",
    "GradGPSError",
    "InputError",
    "InputWarning",
    "LocalFrame",
    "ModelError",
    "MultiTrackDetector",
    "PointResult",
    "Prepared",
    "RemaDetector",
    "RemaParams",
    "SpeedGate",
    "Table",
    "__version__",
    "clean",
    "datasets",
    "detect",
    "inject",
    "iter_csv_tables",
    "metrics",
    "preprocess",
    "read_fixes",
    "read_table",
    "simulate",
    "to_fixes",
    "write_table",
]

claim(globals(), __all__)
