"""Fixtures of the hardware tests: one emulated bus per session, reset per test.

Test modules load them with ``pytest_plugins = ["_hardware"]`` and import constants
from ``_hardware_data``. The emulator runs in its own process on a real
pseudo-terminal; the unmodified dynamixel-sdk talks to it through the driver.
"""

from __future__ import annotations

from collections.abc import Iterator

import pytest
from _hardware_data import BAUD, IDS, LATENCY_MS

from spm_pin.hardware import EmulatedBus, ServoBus


@pytest.fixture(scope="session")
def emulator() -> Iterator[EmulatedBus]:
    """One emulated bus of servos 1, 2, 3 for the whole session, at the default rate."""
    with EmulatedBus(IDS) as bus:
        assert bus.baudrate == BAUD == 57_600  # factory-fresh servos
        yield bus


@pytest.fixture
def bus(emulator: EmulatedBus) -> EmulatedBus:
    """The session's emulated bus, powered up afresh (defaults, no faults, empty log)."""
    emulator.reset()
    return emulator


@pytest.fixture
def servo_bus(bus: EmulatedBus) -> Iterator[ServoBus]:
    """An open driver on the fresh emulated bus."""
    with ServoBus(bus.port, IDS, baudrate=BAUD, latency_timer_ms=LATENCY_MS, retries=2) as driver:
        yield driver
