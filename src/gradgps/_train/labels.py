"""The label a training point carries when its loss must not count.

Padding carries it, and so do points whose truth no causal detector could
know when it sees them: the held fixes of a *stale start* (a receiver that
opens a track on a position from before, see
:func:`gradgps._data.inject.inject_freeze`) look like a parked car until the
jump that ends them. Labelling them faulty taught the network to flag every
long stop; labelling them normal would teach it that a frozen fix is fine. So
they teach nothing, while the fixes after the jump (normal, and what a real
logger's cold start looks like) still teach that such a jump ends a fault.
The value is torch's ``CrossEntropyLoss`` ``ignore_index``.
"""

from __future__ import annotations

__all__ = ["IGNORE_LABEL"]

IGNORE_LABEL = -100
