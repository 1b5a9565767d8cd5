"""Which cameras' views can be trusted now: not while a camera cannot see, nor a robot until it has settled.

A node says, with every frame, whether its detector sees (``Features.state``: "ok", "learning" its
background, "moving"): a camera that does not is left out, so its empty frames are no evidence that
nobody is there and nobody is born from it.

A robot that drives cannot detect anyone (its node sees the whole room move, reports no blobs and
relearns its background from still frames once stopped), and its mutual-calibration pose
(:mod:`~resource_manager.poses.solver`) lags behind the motion and overshoots when it stops. Localising with
its views in that time puts people metres off, and births tracks there. So a mobile camera's views are
left out of matching, localisation and births (the tracks carry on with the other cameras, or coast)
from when it starts moving until:

* its pose has stayed within ``still_m`` (and ``still_yaw_rad``) of where it stopped for ``still_ns``,
  with a small uncertainty (``max_sigma_xy_m``): the pose has re-converged; and
* its node has relearnt the background: its state is "ok" again -- or, from an older node that always
  says "ok", it reports blobs again after the stop, or ``relearn_max_ns`` has passed (nobody in view).

"Moving" is what its node says (its frames say "moving" while the camera moves, whoever moves it). From
an older node that never says, it is seen in the pose itself (more than ``move_m`` from where the robot
stood still last: moved by someone else), or a robot the view planner sent to a goal
(:meth:`ViewPlanner.en_route`) goes blank. A node that reports its state is not judged by its pose: a
mutual-calibration pose that jumps while the robot stands (a band half hidden by a person) is pose
noise, and dropping the views of a robot that stands still costs more than that noise.
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Collection, Mapping
from dataclasses import dataclass, field

from common.angles import angle_diff
from common.schema import DetectorState
from resource_manager.poses.solver import PoseEstimate

__all__ = ["SettleParams", "ViewTrust"]


@dataclass(frozen=True, slots=True)
class SettleParams:
    enabled: bool = True
    move_m: float = 0.25
    """The pose this far from where the robot settled last: it moved (pose noise is ~1-2 cm)."""
    still_m: float = 0.04
    """Stopped: the pose stays within this of its current value..."""
    still_yaw_rad: float = math.radians(1.0)
    still_ns: int = 500_000_000
    """...for this long."""
    max_sigma_xy_m: float = 0.06
    """The settled pose's own uncertainty must be below this."""
    relearn_max_ns: int = 4_000_000_000
    """After the stop, trust the views this long later even if they never showed a blob (nobody in view)."""


@dataclass(slots=True)
class _State:
    history: deque[tuple[int, float, float, float]] = field(default_factory=deque)
    """(t_ns, x, y, yaw) of the pose over the last ``still_ns`` (and a bit)."""
    anchor: tuple[float, float] | None = None
    """Where the robot stands, settled (its views trusted there): the latest pose that was still."""
    moved: bool = False
    """It has moved since it last settled: its node must relearn before its views count."""
    still_since_ns: int | None = None
    """When the robot stopped (it has been still since), while it settles."""
    reports_state: bool = False
    """Its node has said it could not see (``Features.state``): its "ok" means it has relearnt."""


@dataclass(slots=True)
class ViewTrust:
    """Per mobile camera: settled (trusted) or moved and not settled yet (untrusted)."""

    params: SettleParams = field(default_factory=SettleParams)
    states: dict[str, _State] = field(default_factory=dict)

    def update(
        self,
        t_ns: int,
        poses: Mapping[str, PoseEstimate],
        *,
        mobile: Collection[str],
        en_route: Collection[str],
        with_blobs: Collection[str],
        states: Mapping[str, DetectorState] | None = None,
    ) -> frozenset[str]:
        """The cameras whose views must not be used at ``t_ns``.

        Args:
            t_ns: the fusion instant.
            poses: every known pose at ``t_ns``.
            mobile: the mobile cameras.
            en_route: cameras the view planner sent to a goal they have not reached.
            with_blobs: cameras whose aligned view at ``t_ns`` holds at least one blob.
            states: each camera's detector state at ``t_ns`` (``Features.state``; missing: "ok"). Any camera
                not "ok" cannot see now: left out (its empty frames are no evidence, nobody is born from it).
        """
        p = self.params
        if not p.enabled:
            return frozenset()
        states = states or {}
        out: list[str] = [sid for sid, state in states.items() if state != "ok"]
        for sid in mobile:
            pose = poses.get(sid)
            st = self.states.setdefault(sid, _State())
            if pose is None:
                st.history.clear()
                st.still_since_ns = None
                out.append(sid)  # no pose: its views are not used anyway
                continue
            state = states.get(sid, "ok")
            if self._unsettled(st, t_ns, pose, state, en_route=sid in en_route, blank=sid not in with_blobs):
                out.append(sid)
        for sid in [s for s in self.states if s not in mobile]:
            del self.states[sid]
        return frozenset(out)

    def _unsettled(
        self, st: _State, t_ns: int, pose: PoseEstimate, state: DetectorState, *, en_route: bool, blank: bool
    ) -> bool:
        """Follow one mobile camera with a pose; True while its views must not be used (``en_route``: sent to a
        goal not reached yet; ``blank``: no blob in its view now)."""
        p = self.params
        st.history.append((t_ns, pose.x_m, pose.y_m, pose.yaw_rad))
        while st.history and st.history[0][0] < t_ns - 2 * p.still_ns:
            st.history.popleft()
        if st.anchor is None:
            st.anchor = (pose.x_m, pose.y_m)
        if state != "ok":
            st.reports_state = True  # a node that says when it cannot see (older ones always say "ok")
        # Its node says it moves; or, from an older node, it goes blank on its way to a goal.
        driving = state == "moving" or (en_route and blank and not st.reports_state)
        if driving or (not st.reports_state and math.dist(st.anchor, (pose.x_m, pose.y_m)) > p.move_m):
            st.moved = True
        if not st.moved:
            if self._still(st, t_ns, pose):
                st.anchor = (pose.x_m, pose.y_m)  # follows a converging pose, not a robot driving off
            return False  # where it settled: its pose's noise is no reason to drop its views
        if en_route or not self._still(st, t_ns, pose):
            st.still_since_ns = None
            return True
        if st.still_since_ns is None:
            st.still_since_ns = t_ns - p.still_ns  # the window just checked: still since then
        since = t_ns - st.still_since_ns
        # A node that tells says "ok" once relearnt; from an older one, blobs again (or the longest relearn).
        relearnt = (state == "ok") if st.reports_state else (not blank or since >= p.relearn_max_ns)
        if pose.sigma_xy_m <= p.max_sigma_xy_m and relearnt:
            st.moved, st.anchor, st.still_since_ns = False, (pose.x_m, pose.y_m), None
            return False
        return True

    def _still(self, st: _State, t_ns: int, pose: PoseEstimate) -> bool:
        """The pose stayed within ``still_m``/``still_yaw_rad`` of ``pose`` over the last ``still_ns``."""
        p = self.params
        if not st.history or st.history[0][0] > t_ns - p.still_ns:
            return False  # not watched that long yet
        for t, x, y, yaw in st.history:
            if t < t_ns - p.still_ns:
                continue
            if math.hypot(x - pose.x_m, y - pose.y_m) > p.still_m:
                return False
            if abs(angle_diff(yaw, pose.yaw_rad)) > p.still_yaw_rad:
                return False
        return True
