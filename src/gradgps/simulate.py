"""Simulated drives (public): ``from gradgps import simulate``; see :mod:`gradgps._data.simulator`."""

from __future__ import annotations

from ._data.simulator import *  # noqa: F403
from ._data.simulator import __all__ as __all__
from ._public import claim

claim(globals(), __all__)
