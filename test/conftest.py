"""Shared fixtures: the bundled seed-002 plant and a ROS domain id of the test's own for DDS processes."""
from __future__ import annotations

import pytest

from cable_winch_monitor.model.plantfile.plant import Plant, load_plant


@pytest.fixture(scope="session")
def plant() -> Plant:
    return load_plant()


@pytest.fixture
def domain_id(monkeypatch: pytest.MonkeyPatch):
    """ROS domain ids 60-69 for the bag tests' DDS processes, leased as the live-node harness leases its own
    (its lock files), so that no other test run holds the same one."""
    import ros_harness  # rclpy and the message packages, only for the tests that start DDS processes
    monkeypatch.setattr(ros_harness, "DOMAIN_POOL", list(range(60, 70)))
    lease = ros_harness.DomainLease()
    yield lease.domain_id
    lease.release()
