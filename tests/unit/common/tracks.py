"""A published Track as a TrackSet carries it (a standby's leader, a zone's neighbour, a set an agent merges)."""

from __future__ import annotations

from common.schema import Track, TrackState

T0 = 1_700_000_000_000_000_000


def published(
    track_id: str,
    x: float,
    y: float = 5.0,
    vx: float = 0.0,
    t_ns: int = T0,
    mid: str = "m",
    state: TrackState = "confirmed",
) -> Track:
    """A track of manager ``mid`` (confirmed unless ``state`` says) at (``x``, ``y``) moving at ``vx`` along x,
    placed to 0.1 m."""
    return Track(
        manager_id=mid,
        seq=1,
        stamp_ns=t_ns,
        track_id=track_id,
        x_m=x,
        y_m=y,
        height_m=1.7,
        vx_mps=vx,
        vy_mps=0.0,
        cov_xx_m2=0.01,
        cov_xy_m2=0.0,
        cov_yy_m2=0.01,
        state=state,
        method="triangulation",
    )
