"""A ground truth's own breaks of who is who, as benchmarks/bench_ground_truth.py finds them."""

from __future__ import annotations

from benchmarks.bench_ground_truth import find_artifacts
from user_agent.groundtruth import GroundTruth, GtPoint

FPS = 2.0
MAX_SPEED = 2.5


def _gt(paths: dict[str, dict[int, tuple[float, float]]]) -> GroundTruth:
    frames: dict[int, list[GtPoint]] = {}
    for pid, path in paths.items():
        for k, (x, y) in path.items():
            frames.setdefault(k, []).append(GtPoint(k, pid, x, y))
    return GroundTruth(frames=frames)


def _walk(frames: range, x0: float, step: float, y: float = 0.0) -> dict[int, tuple[float, float]]:
    return {k: (x0 + step * (k - frames.start), y) for k in frames}


def test_a_step_faster_than_anyone_walks_is_a_jump_and_a_walk_is_not() -> None:
    path = _walk(range(1, 9), 0.0, 0.6)  # 1.2 m/s
    for k in range(5, 9):
        path[k] = (path[k][0] + 2.0, 0.0)  # 2.6 m in the half second from frame 4 to 5
    found = find_artifacts(_gt({"a": path, "b": _walk(range(1, 9), 0.0, 0.6, y=5.0)}), FPS, MAX_SPEED)
    assert dict(found.jumps) == {"a": {4, 5}}
    assert found.near("a", 6) == "jump" and found.near("a", 7) is None and found.near("b", 5) is None


def test_a_person_missing_from_one_frame_between_two_is_a_gap() -> None:
    path = _walk(range(1, 9), 0.0, 0.5)
    del path[4]
    found = find_artifacts(_gt({"a": path}), FPS, MAX_SPEED)
    assert dict(found.gaps) == {"a": {4}} and not found.jumps
    assert found.counts() == {"jumps": 0, "one_frame_gaps": 1, "id_handovers": 0}


def test_an_id_that_starts_where_another_could_have_walked_is_a_handover_and_one_far_off_is_not() -> None:
    old = _walk(range(1, 7), 0.0, 0.5)  # ends at x = 2.5, frame 6
    new = _walk(range(8, 12), 3.5, 0.5)  # starts 1 m on, a second later: within 2.5 m/s and a body's width
    far = _walk(range(8, 12), 20.0, 0.5)
    late = _walk(range(12, 15), 3.0, 0.5)  # three seconds later: past the handover window
    found = find_artifacts(_gt({"old": old, "new": new, "far": far, "late": late}), FPS, MAX_SPEED)
    assert ("old", "new") in found.handovers
    assert all(a != "far" and b != "far" for a, b in found.handovers)
    assert ("old", "late") not in found.handovers
    assert found.near("new", 8) == "handover" and found.near("old", 6) == "handover"
