"""A driver for XM540-W150 servos on the official dynamixel-sdk (Protocol 2.0).

:class:`ServoBus` owns one serial port (a U2D2 at ``/dev/ttyUSB0``, or the emulated
bus's pseudo-terminal) and the servos on it. Every transaction checks the SDK's
result code and the status packet's error byte; communication failures are retried a
bounded number of times, then raise :class:`~spm_pin.errors.CommunicationError`
naming the servos that did not answer; instruction errors raise
:class:`~spm_pin.errors.ServoError`; the alert bit (a latched hardware error) is
recorded in :attr:`ServoBus.alerts` while the data that came with it is used.

Known defects of dynamixel-sdk 4.1 and what the driver does about them:

* ``txPacket`` never byte-stuffs instruction packets (it drops what ``addStuffing``
  returns). Within the values written here only a 4-byte value whose low three
  bytes are FF FF FD is affected: the Goal Position -131073 pulses (-32 turns).
  The driver checks every instruction body before sending; a goal position that
  would need stuffing is sent one pulse (0.088 deg) closer to zero (counted in
  :attr:`ServoBus.stuffing_workarounds`); any other such write is refused.
* ``removeStuffing`` drops a byte when a stuffed sequence is followed later in the
  packet by FF FD FD (e.g. in the state block: Goal Position -1000, a Realtime Tick
  ending in FD, Present Current -513, Present Velocity -3); the CRC was checked
  before, so the wrong data looks valid. Fast sync read replies are not destuffed
  at all. The driver
  therefore receives status packets with the SDK's ``rxPacket(port, True)`` (framing
  and CRC checked by the SDK, no destuffing) and destuffs them itself
  (:func:`~spm_pin.hardware.protocol.unstuff`). PING and writes carry no data that
  can be stuffed.
* A failed servo fails a whole GroupSyncRead and ``getData`` then returns 0 for
  every servo: the driver never uses ``getData``; it reads each servo's status
  packet and reports exactly which servos are missing.
* The packet timeout is 2 x 16 ms + 2 ms + wire time, from a module constant:
  :class:`ServoBus` takes ``latency_timer_ms`` instead (1 ms suits a U2D2 whose FTDI
  latency timer is set to 1 ms).
* The packet timeout is a wall-clock (``time.time``) deadline checked after a read:
  a clock step fakes or hides a timeout, and a controller preempted between its last
  read and the check gives up on a reply that is already waiting (seen on a loaded
  machine). The driver's port measures the deadline on the monotonic clock (or the
  ``clock`` given to :class:`ServoBus`) and declares it passed only after a read
  begun past the deadline came back short.
"""

from __future__ import annotations

import contextlib
import termios
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from types import TracebackType
from typing import Any, TypeVar

from ..errors import CommunicationError, HardwareError, InputError, ServoError
from ._sdk import SDK_BAUD_RATES, load_sdk, port_class
from .control_table import (
    ALERT_BIT,
    BAUD_RATES,
    INSTRUCTION_ERRORS,
    MODEL_NUMBER,
    XM540_W150,
    HardwareErrorFlag,
)
from .protocol import BROADCAST_ID, Instruction, ProtocolError, has_unstuffed_header, unstuff
from .servo_data import FAST_SYNC_READ_FIRMWARE, ServoInfo, ServoReadings, ServoSettings

__all__ = [
    "FAST_SYNC_READ_FIRMWARE",
    "STATE_BLOCK",
    "ServoBus",
    "ServoInfo",
    "ServoReadings",
    "ServoSettings",
    "load_sdk",
]

T = TypeVar("T")

#: The block that :meth:`ServoBus.sync_read` reads: Goal Position (116) to Present
#: Position (135), 20 bytes: goal, moving, current, velocity and position at once.
STATE_BLOCK = (116, 20)
#: Result codes after which a transaction is retried.
_RETRYABLE = {-1000, -1001, -1002, -3001, -3002}
#: Error number of a CRC error reported by a servo (retried: the packet was garbled).
_CRC_ERROR = 3
#: Time to wait for a rebooted servo to answer again [s].
REBOOT_TIMEOUT = 2.0
#: The XM540-W150's factory line rate (Baud Rate item 1) [bit/s]: the default of
#: :class:`ServoBus`, as of the emulator and of :class:`HardwareConfig`.
FACTORY_BAUDRATE = BAUD_RATES[XM540_W150["Baud Rate"].default or 0]


class _Failed(Exception):
    """One failed attempt of a transaction (retried, then turned into an SPMError)."""

    def __init__(self, result: int | None, text: str, missing: tuple[int, ...] = ()) -> None:
        super().__init__(text)
        self.result = result
        self.missing = missing


_PORT_ERRORS: tuple[type[BaseException], ...] = (OSError, termios.error, TypeError)


class ServoBus:
    """XM540-W150 servos on one serial port, through dynamixel-sdk.

    Args:
        port: Serial device, e.g. ``/dev/ttyUSB0`` or the emulated bus's ``/dev/pts/N``.
        ids: Servo ids on the bus (the order of :meth:`sync_read`).
        baudrate: Line rate [bit/s]; must equal every servo's Baud Rate item
            (default: the factory setting, 57,600).
        latency_timer_ms: Latency the packet timeout allows for, twice, plus 2 ms
            and the wire time [ms] (16 for a stock FTDI adapter, 1 after
            ``echo 1 > /sys/bus/usb-serial/devices/ttyUSB0/latency_timer``).
        retries: Extra attempts after a failed transaction (timeout, garbled reply).
        fast_sync_read: Use FAST_SYNC_READ (True), never (False), or when every
            servo's firmware has it (None, decided by :meth:`identify`).
        clock: Clock of the packet timeout and of the wait after a reboot [s]
            (default :func:`time.monotonic`; a test may pass a fake one).

    Attributes:
        alerts: Servo id -> True while its status packets carry the alert bit.
        stuffing_workarounds: Goal positions moved by one pulse to avoid the SDK's
            missing byte stuffing.
        stats: Counters: transactions, retries, failures.
    """

    def __init__(
        self,
        port: str,
        ids: Sequence[int] = (1, 2, 3),
        *,
        baudrate: int = FACTORY_BAUDRATE,
        latency_timer_ms: float = 16.0,
        retries: int = 2,
        fast_sync_read: bool | None = None,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        if not isinstance(port, str) or not port:
            raise InputError(
                f"port must be a device path, got {port!r}", argument="port", value=port
            )
        id_list = tuple(ids)
        if (
            not id_list
            or len(set(id_list)) != len(id_list)
            or not all(
                isinstance(i, int) and not isinstance(i, bool) and 0 <= i <= 252 for i in id_list
            )
        ):
            raise InputError(
                f"ids must be distinct integers in 0..252, got {ids!r}", argument="ids", value=ids
            )
        if baudrate not in SDK_BAUD_RATES:
            raise InputError(
                f"baudrate must be one of {list(SDK_BAUD_RATES)} bit/s (the servo's Baud Rate "
                f"values that dynamixel-sdk accepts), got {baudrate!r}",
                argument="baudrate",
                value=baudrate,
            )
        if not isinstance(latency_timer_ms, (int, float)) or not 0 < latency_timer_ms <= 1000:
            raise InputError(
                f"latency_timer_ms must be in (0, 1000] ms, got {latency_timer_ms!r}",
                argument="latency_timer_ms",
                value=latency_timer_ms,
            )
        if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= 10:
            raise InputError(
                f"retries must be an integer in 0..10, got {retries!r}",
                argument="retries",
                value=retries,
            )
        if not callable(clock):
            raise InputError(
                f"clock must be a callable returning seconds, got {clock!r}",
                argument="clock",
                value=clock,
            )
        self.port_name = port
        self.ids = id_list
        self.baudrate = baudrate
        self.latency_timer_ms = float(latency_timer_ms)
        self.retries = retries
        self.fast_sync_read = fast_sync_read
        self.clock = clock
        self.alerts: dict[int, bool] = dict.fromkeys(id_list, False)
        self.stuffing_workarounds = 0
        self.stats: dict[str, int] = {"transactions": 0, "retries": 0, "failures": 0}
        self._sdk: Any = None
        self._port: Any = None
        self._handler: Any = None
        self._groups: dict[tuple[str, int, int], Any] = {}

    def __repr__(self) -> str:
        state = "open" if self.is_open else "closed"
        return f"ServoBus({self.port_name!r}, ids={list(self.ids)}, {self.baudrate} bit/s, {state})"

    # ------------------------------------------------------------------ port
    @property
    def is_open(self) -> bool:
        """The port is open."""
        return self._port is not None

    def open(self) -> ServoBus:
        """Open the port at :attr:`baudrate`.

        Raises:
            HardwareError: the SDK is missing, or the device cannot be opened (wrong
                path, no permission: add the user to the ``dialout`` group).
        """
        if self._port is not None:
            return self
        sdk = load_sdk()
        port = port_class()(self.port_name)
        port.latency_ms = self.latency_timer_ms
        port.clock = self.clock
        port.baudrate = self.baudrate
        try:
            opened = port.openPort()
        except (OSError, termios.error, ValueError) as exc:
            raise HardwareError(
                f"cannot open servo port {self.port_name!r}: {exc} (is the adapter plugged "
                "in, the path right, and the user in the 'dialout' group?)",
                operation="open port",
            ) from exc
        if not opened:
            raise HardwareError(
                f"dynamixel-sdk refused to open {self.port_name!r} at {self.baudrate} bit/s",
                operation="open port",
            )
        self._sdk = sdk
        self._port = port
        self._handler = sdk.PacketHandler(2.0)
        self._groups.clear()
        return self

    def close(self) -> None:
        """Close the port (torque is left as it is: see ServoSync for torque off)."""
        port, self._port = self._port, None
        self._groups.clear()
        if port is not None:
            with contextlib.suppress(*_PORT_ERRORS, AttributeError):
                port.closePort()

    def __enter__(self) -> ServoBus:
        return self.open()

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()

    def _require_open(self, operation: str) -> tuple[Any, Any]:
        if self._port is None:
            raise HardwareError(
                f"the servo port {self.port_name!r} is not open: call open() or use "
                "'with ServoBus(...) as bus:'",
                operation=operation,
            )
        return self._port, self._handler

    # ------------------------------------------------------------ transactions
    def _result_text(self, result: int) -> str:
        text = str(self._handler.getTxRxResult(result)) if self._handler is not None else ""
        return text.replace("[TxRxResult] ", "") or f"result {result}"

    def _attempts(
        self,
        operation: str,
        attempt: Callable[[], T],
        servo_id: int | None = None,
    ) -> T:
        """Run ``attempt`` up to 1 + retries times; _Failed marks a retryable failure."""
        port, _ = self._require_open(operation)
        last: _Failed | None = None
        for number in range(self.retries + 1):
            if number:
                self.stats["retries"] += 1
                # Let late replies arrive, then drop them (txPacket clears the input).
                time.sleep(self.latency_timer_ms / 1000.0)
            self.stats["transactions"] += 1
            try:
                return attempt()
            except _Failed as exc:
                last = exc
                if exc.result is not None and exc.result not in _RETRYABLE:
                    break
            except _PORT_ERRORS as exc:
                port.is_using = False
                self.stats["failures"] += 1
                raise CommunicationError(
                    f"{operation}: the port {self.port_name!r} failed: {exc!r}",
                    servo_id=servo_id,
                    operation=operation,
                ) from exc
            finally:
                port.is_using = False
        self.stats["failures"] += 1
        if last is None:  # pragma: no cover - the loop runs at least once
            raise CommunicationError(f"{operation} failed", operation=operation)
        missing = last.missing or ((servo_id,) if servo_id is not None else ())
        who = f" from servo(s) {list(missing)}" if missing else ""
        raise CommunicationError(
            f"{operation}: {last}{who} after {self.retries + 1} attempt(s) at "
            f"{self.baudrate} bit/s on {self.port_name!r} (check power, cabling, id and baud "
            "rate)",
            servo_id=missing[0] if len(missing) == 1 else servo_id,
            operation=operation,
            result=last.result,
            servo_ids=tuple(missing),
        )

    def _check_error(self, servo_id: int, error: int, operation: str) -> None:
        """Record the alert bit; raise ServoError for an instruction error."""
        if servo_id in self.alerts:
            self.alerts[servo_id] = bool(error & ALERT_BIT)
        number = error & 0x7F
        if number == _CRC_ERROR:
            raise _Failed(None, f"servo {servo_id} reported a CRC error", (servo_id,))
        if number:
            raise ServoError(
                f"{operation}: servo {servo_id} answered error {number}: "
                f"{INSTRUCTION_ERRORS.get(number, 'unknown')}",
                servo_id=servo_id,
                operation=operation,
                error=number,
            )

    def _receive(
        self, ids: Sequence[int], length: int, operation: str
    ) -> dict[int, tuple[int, bytes]]:
        """Status packets of ``ids``, each with ``length`` data bytes: id -> (error, data).

        Uses the SDK's framing and CRC check (``rxPacket(port, True)``, which leaves
        the stuffing in place) and destuffs here. Raises _Failed naming the servos
        whose packet did not arrive.
        """
        port, handler = self._port, self._handler
        wanted = set(ids)
        got: dict[int, tuple[int, bytes]] = {}
        for _ in range(2 * len(ids) + 2):
            if len(got) == len(wanted):
                break
            packet, result = handler.rxPacket(port, True)
            if result != 0:
                missing = tuple(i for i in ids if i not in got)
                raise _Failed(result, self._result_text(result), missing)
            raw = bytes(packet)
            try:
                body = unstuff(raw[7:-2])
            except ProtocolError as exc:
                raise _Failed(-3002, f"badly stuffed status packet: {exc}") from exc
            servo_id = raw[4]
            if servo_id not in wanted or servo_id in got or body[0] != Instruction.STATUS:
                continue  # another servo's packet (the SDK drops these too)
            if len(body) != 2 + length:
                raise _Failed(
                    -3002,
                    f"status packet of servo {servo_id} has {len(body) - 2} data bytes, "
                    f"expected {length}",
                )
            got[servo_id] = (body[1], body[2:])
        missing = tuple(i for i in ids if i not in got)
        if missing:
            raise _Failed(-3002, "unexpected status packets", missing)
        return got

    # ------------------------------------------------------------------ items
    def ping(self, servo_id: int) -> int:
        """PING a servo; returns its model number.

        Raises:
            CommunicationError: no answer after the retries.
        """
        _, handler = self._require_open("ping")

        def attempt() -> int:
            model, result, error = handler.ping(self._port, servo_id)
            if result != 0:
                raise _Failed(result, self._result_text(result))
            self._check_error(servo_id, error, "ping")
            return int(model)

        return self._attempts(f"ping servo {servo_id}", attempt, servo_id)

    def identify(self) -> dict[int, ServoInfo]:
        """Ping every servo, check it is an XM540-W150, read its firmware version.

        Also decides :attr:`fast_sync_read` when it was None (every firmware >= 45).

        Raises:
            CommunicationError: a servo does not answer.
            HardwareError: a servo is another model (names the model number).
        """
        infos: dict[int, ServoInfo] = {}
        for servo_id in self.ids:
            model = self.ping(servo_id)
            if model != MODEL_NUMBER:
                raise HardwareError(
                    f"servo {servo_id} is model {model}, not an XM540-W150 ({MODEL_NUMBER})",
                    servo_id=servo_id,
                    operation="identify",
                )
            firmware = self.read(servo_id, "Firmware Version")
            infos[servo_id] = ServoInfo(servo_id, model, firmware)
        if self.fast_sync_read is None:
            self.fast_sync_read = all(info.fast_sync_read for info in infos.values())
        return infos

    def read_block(self, servo_id: int, address: int, length: int) -> bytes:
        """READ ``length`` bytes from ``address`` of one servo (destuffed correctly)."""
        _, handler = self._require_open("read")
        operation = f"read {length} byte(s) at {address} of servo {servo_id}"

        def attempt() -> bytes:
            result = handler.readTx(self._port, servo_id, address, length)
            if result != 0:
                raise _Failed(result, self._result_text(result))
            error, data = self._receive((servo_id,), length, operation)[servo_id]
            self._check_error(servo_id, error, operation)
            return data

        return self._attempts(operation, attempt, servo_id)

    def read(self, servo_id: int, item: str) -> int:
        """Read a control item (signed where the item is)."""
        spec = XM540_W150[item]
        return spec.decode(self.read_block(servo_id, spec.address, spec.size))

    def write(self, servo_id: int, item: str, value: int) -> None:
        """Write a control item and check the servo's answer.

        EEPROM items (addresses < 64) are written only after checking that torque is
        off (the servo would refuse them with an access error).

        Raises:
            InputError: value out of the item's range.
            HardwareError: an EEPROM item while torque is on; a value that
                dynamixel-sdk would send without the byte stuffing it needs.
            ServoError: the servo refused the value (names the error).
            CommunicationError: no answer after the retries.
        """
        spec = XM540_W150[item]
        if not spec.writable:
            raise InputError(f"{item} is read-only", argument="item", value=item)
        data = spec.encode(value)
        if spec.eeprom and self.read(servo_id, "Torque Enable"):
            raise HardwareError(
                f"{item} lives in EEPROM and is writable only with torque off; servo "
                f"{servo_id} has torque on (call set_torque(False) first)",
                servo_id=servo_id,
                operation=f"write {item}",
            )
        body = bytes((Instruction.WRITE, spec.address & 0xFF, spec.address >> 8)) + data
        if has_unstuffed_header(body):
            raise HardwareError(
                f"{item} = {value} would need byte stuffing, which dynamixel-sdk does not do",
                servo_id=servo_id,
                operation=f"write {item}",
            )
        _, handler = self._require_open("write")
        operation = f"write {item} = {value} to servo {servo_id}"

        if item == "Status Return Level":
            # The servo answers this write only if it already answers writes (level 2):
            # send it without waiting, then read it back (reads are answered from 1 up).
            def send_only() -> None:
                result = handler.writeTxOnly(
                    self._port, servo_id, spec.address, spec.size, list(data)
                )
                if result != 0:
                    raise _Failed(result, self._result_text(result))

            self._attempts(operation, send_only, servo_id)
            if value >= 1 and self.read(servo_id, item) != value:
                raise HardwareError(
                    f"servo {servo_id} did not keep Status Return Level {value}",
                    servo_id=servo_id,
                    operation=operation,
                )
            return

        def attempt() -> None:
            result, error = handler.writeTxRx(
                self._port, servo_id, spec.address, spec.size, list(data)
            )
            if result != 0:
                raise _Failed(result, self._result_text(result))
            self._check_error(servo_id, error, operation)

        self._attempts(operation, attempt, servo_id)

    def hardware_errors(self, servo_id: int) -> HardwareErrorFlag:
        """The Hardware Error Status of a servo, decoded."""
        return HardwareErrorFlag(self.read(servo_id, "Hardware Error Status") & 0x3D)

    # ------------------------------------------------------------------ torque
    def set_torque(self, enabled: bool, ids: Iterable[int] | None = None) -> None:
        """Torque on or off, read back to confirm.

        Raises:
            HardwareError: a servo kept another state (e.g. torque on refused after a
                shutdown: only a reboot clears it).
        """
        targets = tuple(self.ids if ids is None else ids)
        failures: list[str] = []
        for servo_id in targets:
            try:
                self.write(servo_id, "Torque Enable", int(bool(enabled)))
            except ServoError as exc:
                failures.append(str(exc))
        for servo_id in targets:
            if bool(self.read(servo_id, "Torque Enable")) != bool(enabled):
                state = "on" if enabled else "off"
                errors = self.hardware_errors(servo_id)
                why = f" (hardware error: {', '.join(errors.describe())})" if errors else ""
                detail = f"; {'; '.join(failures)}" if failures else ""
                raise HardwareError(
                    f"servo {servo_id} did not turn torque {state}{why}{detail}",
                    servo_id=servo_id,
                    operation="torque",
                )

    def torque_enabled(self) -> dict[int, bool]:
        """Torque Enable of every servo."""
        return {servo_id: bool(self.read(servo_id, "Torque Enable")) for servo_id in self.ids}

    # ------------------------------------------------------------------ configure
    def configure(self, settings: ServoSettings | None = None) -> dict[int, dict[str, int]]:
        """Set every servo up: torque off, extended position mode, limits, profile.

        EEPROM items are written only where they differ (EEPROM wears), with torque
        off; Profile Velocity and Acceleration are written after the Operating Mode
        (changing the mode zeroes them). Every item is read back.

        Returns:
            What each servo holds afterwards: id -> item -> raw value.

        Raises:
            HardwareError: a value did not stick.
        """
        raw = (settings or ServoSettings()).raw()
        for servo_id in self.ids:  # first, so that every later write is answered
            if self.read(servo_id, "Status Return Level") != raw["Status Return Level"]:
                self.write(servo_id, "Status Return Level", raw["Status Return Level"])
        self.set_torque(False)
        result: dict[int, dict[str, int]] = {}
        for servo_id in self.ids:
            for item, value in raw.items():
                if self.read(servo_id, item) != value:
                    self.write(servo_id, item, value)
            held = {item: self.read(servo_id, item) for item in raw}
            wrong = {item: held[item] for item in raw if held[item] != raw[item]}
            if wrong:
                raise HardwareError(
                    f"servo {servo_id} did not keep {wrong} (wanted "
                    f"{ {k: raw[k] for k in wrong} })",
                    servo_id=servo_id,
                    operation="configure",
                )
            result[servo_id] = held
        return result

    def reboot(self, servo_id: int, timeout: float = REBOOT_TIMEOUT) -> None:
        """REBOOT a servo (clears a latched hardware error) and wait until it answers.

        After a reboot the servo has torque off, RAM defaults (Profile Velocity 0!)
        and its multi-turn count restarted within one turn.

        Raises:
            CommunicationError: it did not answer again within ``timeout`` [s].
        """
        _, handler = self._require_open("reboot")
        operation = f"reboot servo {servo_id}"

        def attempt() -> None:
            result, error = handler.reboot(self._port, servo_id)
            if result != 0:
                raise _Failed(result, self._result_text(result))
            self._check_error(servo_id, error, operation)

        self._attempts(operation, attempt, servo_id)
        deadline = self.clock() + timeout
        while True:
            try:
                _, result, error = handler.ping(self._port, servo_id)
            except _PORT_ERRORS as exc:
                raise CommunicationError(
                    f"{operation}: the port failed: {exc!r}", servo_id=servo_id
                ) from exc
            finally:
                self._port.is_using = False
            if result == 0:
                self.alerts[servo_id] = bool(error & ALERT_BIT)
                return
            if self.clock() > deadline:
                raise CommunicationError(
                    f"servo {servo_id} did not answer within {timeout:g} s after REBOOT",
                    servo_id=servo_id,
                    operation=operation,
                    result=result,
                )
            time.sleep(0.01)

    # ------------------------------------------------------------------ sync
    def _group(self, kind: str, address: int, length: int) -> Any:
        key = (kind, address, length)
        group = self._groups.get(key)
        if group is None:
            factory = self._sdk.GroupSyncRead if kind == "read" else self._sdk.GroupSyncWrite
            group = factory(self._port, self._handler, address, length)
            if kind == "read":
                for servo_id in self.ids:
                    if not group.addParam(servo_id):
                        raise HardwareError(f"GroupSyncRead refused id {servo_id}")
            self._groups[key] = group
        return group

    def sync_read_block(
        self, address: int, length: int, *, fast: bool | None = None
    ) -> dict[int, tuple[int, bytes]]:
        """SYNC_READ (or FAST_SYNC_READ) of one block from every servo.

        Returns:
            id -> (error byte, data). Instruction errors raise ServoError; the alert
            bit is recorded in :attr:`alerts`.

        Raises:
            CommunicationError: a servo did not answer (its id is in ``servo_ids``).
        """
        self._require_open("sync read")
        use_fast = bool(self.fast_sync_read) if fast is None else fast
        group = self._group("read", address, length)
        operation = f"{'fast ' if use_fast else ''}sync read of {length} byte(s) at {address}"

        def attempt() -> dict[int, tuple[int, bytes]]:
            sent = group.fastSyncReadTxPacket() if use_fast else group.txPacket()
            if sent != 0:
                raise _Failed(sent, self._result_text(sent))
            replies = (
                self._receive_fast(length)
                if use_fast
                else self._receive(self.ids, length, operation)
            )
            for servo_id, (error, _) in replies.items():
                self._check_error(servo_id, error, operation)
            return replies

        if not use_fast:
            return self._attempts(operation, attempt)
        try:
            return self._attempts(operation, attempt)
        except CommunicationError:
            # A broken fast chain does not say who is missing: ask the plain way, which
            # either answers (and is used) or names the silent servos.
            self.stats["fast_fallbacks"] = self.stats.get("fast_fallbacks", 0) + 1
            return self.sync_read_block(address, length, fast=False)

    def _receive_fast(self, length: int) -> dict[int, tuple[int, bytes]]:
        """The single FAST_SYNC_READ status packet: [error, id, data, CRC] per servo."""
        packet, result = self._handler.rxPacket(self._port, True)
        if result != 0:
            raise _Failed(result, self._result_text(result), self.ids)
        raw = bytes(packet)
        if raw[4] != BROADCAST_ID:
            raise _Failed(-3002, f"fast sync read reply from id {raw[4]}, expected 254")
        try:
            body = unstuff(raw[7:-2])
        except ProtocolError as exc:
            raise _Failed(-3002, f"badly stuffed fast sync read reply: {exc}") from exc
        step = length + 4
        if body[0] != Instruction.STATUS or len(body) != 1 + len(self.ids) * step - 2:
            raise _Failed(-3002, "fast sync read reply of the wrong size")
        replies: dict[int, tuple[int, bytes]] = {}
        for index, servo_id in enumerate(self.ids):
            start = 1 + index * step
            if body[start + 1] != servo_id:
                raise _Failed(-3002, f"fast sync read segment {index} is from id {body[start + 1]}")
            replies[servo_id] = (body[start], body[start + 2 : start + 2 + length])
        return replies

    def sync_read(self) -> ServoReadings:
        """Goal, position, velocity, current and moving flag of every servo, at once."""
        address, length = STATE_BLOCK
        replies = self.sync_read_block(address, length)
        table = XM540_W150

        def field(data: bytes, name: str) -> int:
            item = table[name]
            return item.decode(data[item.address - address : item.end - address])

        datas = [replies[i][1] for i in self.ids]
        return ServoReadings(
            ids=self.ids,
            goal=tuple(field(d, "Goal Position") for d in datas),
            position=tuple(field(d, "Present Position") for d in datas),
            velocity=tuple(field(d, "Present Velocity") for d in datas),
            current=tuple(field(d, "Present Current") for d in datas),
            moving=tuple(bool(field(d, "Moving")) for d in datas),
            alert=tuple(bool(replies[i][0] & ALERT_BIT) for i in self.ids),
            time=time.perf_counter(),
            fast=bool(self.fast_sync_read),
        )

    def sync_write_goals(self, goals: Mapping[int, int]) -> dict[int, int]:
        """SYNC_WRITE Goal Position [pulses] to the given servos (no reply on the bus).

        A goal whose bytes would need stuffing (which the SDK omits) is moved one
        pulse towards zero first.

        Returns:
            The goals actually sent, by id.

        Raises:
            InputError: an unknown id or a goal beyond +-1,048,575 pulses.
            CommunicationError: the packet could not be written.
        """
        item = XM540_W150["Goal Position"]
        sent: dict[int, int] = {}
        for servo_id, value in goals.items():
            if servo_id not in self.ids:
                raise InputError(
                    f"servo {servo_id} is not on this bus (ids {list(self.ids)})",
                    argument="goals",
                    value=servo_id,
                )
            sent[servo_id] = item.check(value)
        sent = self._avoid_stuffing(item.address, item.size, sent)
        group = self._group("write", item.address, item.size)

        def attempt() -> None:
            group.clearParam()
            for servo_id, value in sent.items():
                group.addParam(servo_id, list(item.encode(value)))
            result = group.txPacket()
            if result != 0:
                raise _Failed(result, self._result_text(result))

        self._attempts("sync write of Goal Position", attempt)
        return sent

    def _avoid_stuffing(self, address: int, size: int, values: dict[int, int]) -> dict[int, int]:
        item = XM540_W150["Goal Position"]
        values = dict(values)
        for _ in range(8):
            body = bytearray((Instruction.SYNC_WRITE, address & 0xFF, address >> 8, size, 0))
            spans: list[tuple[int, int]] = []
            for servo_id, value in values.items():
                spans.append((len(body), servo_id))
                body += bytes((servo_id,)) + item.encode(value)
            where = bytes(body).find(b"\xff\xff\xfd")
            if where < 0:
                return values
            culprit = next(i for start, i in reversed(spans) if start <= where + 2)
            value = values[culprit]
            values[culprit] = value + 1 if value < 0 else value - 1
            self.stuffing_workarounds += 1
        raise HardwareError("could not avoid byte stuffing in a sync write", operation="sync write")
