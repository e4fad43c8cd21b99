"""Benchmark metrics (public): pointwise scores, confusion matrices, events, false alarms, RMSE.

``from gradgps import metrics``; see :mod:`gradgps._eval.metrics` for the definitions.
"""

from __future__ import annotations

from ._eval.metrics import *  # noqa: F403
from ._eval.metrics import __all__ as __all__
from ._public import claim

claim(globals(), __all__)
