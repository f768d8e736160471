"""ird_ros.graph.domains.lease_domain: exclusive leases, and a process's searches walk on, so a
released ID comes back to it only after the others were tried (whatever outlived a lease in its
domain does not meet the next one's graph)."""

from __future__ import annotations

import pytest

from ird_ros.graph import domains


def test_a_released_id_is_not_leased_again_at_once(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(domains, "_next_start", None)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    monkeypatch.setenv("IRD_TEST_DOMAIN_BASE", "40")
    seen = []
    for _ in range(5):
        with domains.lease_domain() as lease:
            seen.append(lease.domain_id)
    assert len(set(seen)) == 5, seen  # each search started after the last ID (released by then)
    assert seen == sorted(seen) and seen[0] >= 40, seen


def test_held_ids_are_skipped_and_an_explicit_start_is_kept(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(domains, "_next_start", None)
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    with domains.lease_domain(start=60) as first, domains.lease_domain(start=first.domain_id) as second:
        assert second.domain_id != first.domain_id
    with domains.lease_domain(start=first.domain_id) as again:  # released: an explicit start gets it
        assert again.domain_id == first.domain_id
    assert domains._next_start is None  # explicit starts leave the default search where it was


def test_the_search_wraps_around() -> None:
    assert domains.DOMAIN_ID_MAX == 101
    with domains.lease_domain(start=domains.DOMAIN_ID_MAX + 1) as lease:  # start 102 wraps to 0
        assert 0 <= lease.domain_id <= domains.DOMAIN_ID_MAX
