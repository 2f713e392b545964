"""Shared fixtures: the bundled seed-002 plant, a ROS domain id of the test's own for DDS processes, and the
package's channels as each test found them."""
from __future__ import annotations

from collections.abc import Iterator

import pytest

from cable_winch_monitor import channels
from cable_winch_monitor.model.plantfile.plant import Plant, load_plant


@pytest.fixture(autouse=True)
def channels_as_they_were() -> Iterator[None]:
    """A test that loads a user's module (which declares its sensors' channels into the package's registry for
    the rest of the process) leaves the registry as it found it: a later test's monitor must not fuse a
    sensor it never heard of, which its update process, a fresh interpreter, does not know either."""
    registry = channels.REGISTRY
    known = dict(registry.channels)
    yield
    if registry.channels != known:
        registry.channels = known
        registry._changed()  # what the samples ask of the channels, worked out again


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
