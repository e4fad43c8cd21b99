"""Fault injection (public): the ``grad``, ``gnss`` and ``sensor-grid`` protocols; see :mod:`gradgps._data.inject`."""

from __future__ import annotations

from ._data.inject import *  # noqa: F403
from ._data.inject import __all__ as __all__
from ._public import claim

claim(globals(), __all__)
