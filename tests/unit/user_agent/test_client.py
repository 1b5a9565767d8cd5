"""An agent keeps the latest message of at most MAX_KEPT senders per kind: a flood of fresh ids is bounded."""

from __future__ import annotations

from user_agent.client import MAX_KEPT, _keep


def test_keep_bounds_the_table_and_keeps_the_recently_heard() -> None:
    table: dict[str, int] = {}
    _keep(table, "pano1", 0)
    for i in range(10 * MAX_KEPT):
        _keep(table, f"f{i}", i)
        if i % 50 == 0:
            _keep(table, "pano1", i)  # a real sensor, heard every now and then
    assert len(table) == MAX_KEPT
    assert "pano1" in table and list(table)[-1] == f"f{10 * MAX_KEPT - 1}"
