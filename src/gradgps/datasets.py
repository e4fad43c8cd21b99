"""The shared data sets and their splits (public); see :mod:`gradgps._data.datasets`."""

from __future__ import annotations

from ._data.datasets import *  # noqa: F403
from ._data.datasets import __all__ as __all__
from ._public import claim

claim(globals(), __all__)
