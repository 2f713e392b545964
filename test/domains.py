"""ROS domain ids 60-69 for the bag tests' DDS processes, leased as the live-node harness leases its own."""
from __future__ import annotations

import pytest

import ros_harness


@pytest.fixture
def domain_id(monkeypatch: pytest.MonkeyPatch):
    """A domain id no other test run holds (the harness's lock files, restricted to 60-69)."""
    monkeypatch.setattr(ros_harness, "DOMAIN_POOL", list(range(60, 70)))
    lease = ros_harness.DomainLease()
    yield lease.domain_id
    lease.release()
