"""Small numeric helpers shared by the tiers, defined once."""

from __future__ import annotations

import math

__all__ = ["clip"]


def clip(x: float, lo: float, hi: float) -> float:
    """``x`` as a Python float bounded to [lo, hi]; NaN stays NaN (a schema's range check then names it).

    ``np.clip`` for one number without numpy's per-call cost: used where values cross the wire boundary.
    """
    x = float(x)
    return x if math.isnan(x) else min(max(x, lo), hi)
