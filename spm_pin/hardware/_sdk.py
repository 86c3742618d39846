"""Loading dynamixel-sdk, and the serial port class that the servo driver opens.

The SDK is imported only when a port is opened (``import spm_pin.hardware`` does not
need it). The port class is the SDK's ``PortHandler`` with a packet timeout measured
on the driver's monotonic clock, from a latency that the driver sets (the SDK defects
this works around are listed in :mod:`spm_pin.hardware.driver`).
"""

from __future__ import annotations

import functools
import inspect
import math
import time
from collections.abc import Callable
from typing import Any

from ..errors import HardwareError

__all__ = ["SDK_BAUD_RATES", "load_sdk", "port_class"]

#: Baud rates that both the SDK and the servo accept [bit/s].
SDK_BAUD_RATES = (9_600, 57_600, 115_200, 1_000_000, 2_000_000, 3_000_000, 4_000_000)


def load_sdk() -> Any:
    """Import ``dynamixel_sdk`` or raise HardwareError with the install command."""
    try:
        import dynamixel_sdk
    except ImportError as exc:
        raise HardwareError(
            "the servo driver needs dynamixel-sdk: pip install 'spm-pin[hardware]'",
            operation="import dynamixel_sdk",
        ) from exc
    # The driver receives status packets undestuffed (rxPacket's fast_option, 4.x).
    parameters = inspect.signature(dynamixel_sdk.Protocol2PacketHandler.rxPacket).parameters
    if "fast_option" not in parameters:
        raise HardwareError(
            "the servo driver needs dynamixel-sdk 4.1 or newer: "
            "pip install --upgrade 'dynamixel-sdk>=4.1'",
            operation="import dynamixel_sdk",
        )
    return dynamixel_sdk


@functools.cache
def port_class() -> type:
    """dynamixel_sdk.PortHandler with the packet timeout's latency as an attribute."""
    sdk = load_sdk()

    class _Port(sdk.PortHandler):  # type: ignore[misc,name-defined]
        latency_ms = 16.0
        #: Clock of the packet timeout [s] (ServoBus sets its own ``clock``).
        clock: Callable[[], float] = staticmethod(time.monotonic)
        #: Clock when the last read of the port began [ms] (see isPacketTimeout).
        last_read_time = -math.inf

        def getCurrentTime(self) -> float:  # the SDK's name; it uses the wall clock
            return self.clock() * 1000.0

        def setPacketTimeout(self, packet_length: int) -> None:  # the SDK's name
            self.packet_start_time = self.getCurrentTime()
            self.packet_timeout = (
                self.tx_time_per_byte * packet_length + 2.0 * self.latency_ms + 2.0
            )

        def readPort(self, length: int) -> Any:  # the SDK's name
            self.last_read_time = self.getCurrentTime()
            return super().readPort(length)

        def isPacketTimeout(self) -> bool:  # the SDK's name
            # Expired only when a read that began after the deadline still came back
            # short: the SDK checks the clock after its read, so a controller preempted
            # between the two would otherwise give up on a reply already waiting.
            if self.last_read_time - self.packet_start_time > self.packet_timeout:
                self.packet_timeout = 0.0
                return True
            return False

    return _Port
