"""Shared fixtures: the bundled seed-002 plant."""
from __future__ import annotations

import pytest

from cable_winch_monitor.model.plant import Plant, load_plant


@pytest.fixture(scope="session")
def plant() -> Plant:
    return load_plant()
