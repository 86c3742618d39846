"""Errors raised by spm-pin.

Every error the library raises derives from :class:`SPMError`. Each subclass also
derives from the builtin exception that fits (``ValueError``, ``RuntimeError``), so
code written against the builtins keeps working. Errors keep the data behind the
failure as attributes; nothing the user gave is lost.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "CommunicationError",
    "ConvergenceError",
    "DesignError",
    "FileFormatError",
    "HardwareError",
    "InputError",
    "PlanningError",
    "SPMError",
    "ServoAlertError",
    "ServoError",
    "SingularityError",
    "UnreachableError",
    "UnsafeCommandError",
]


class SPMError(Exception):
    """Root of every error raised by spm-pin."""


class InputError(SPMError, ValueError):
    """An argument has the wrong shape, type or value (NaN, inf, out of range).

    Attributes:
        argument: Name of the offending argument.
        value: The value that was given.
    """

    def __init__(self, message: str, *, argument: str | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.argument = argument
        self.value = value


class DesignError(InputError):
    """A design parameter is impossible (names the parameter and the allowed range)."""

    def __init__(self, message: str, *, parameter: str | None = None, value: Any = None) -> None:
        super().__init__(message, argument=parameter, value=value)
        self.parameter = parameter


class FileFormatError(SPMError, ValueError):
    """A file (design TOML, readings CSV, ...) is malformed.

    Attributes:
        path: The file, when known.
        line: 1-based line number of the problem, when known.
    """

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None) -> None:
        where = ""
        if path is not None:
            where = f"{path}:{line}: " if line is not None else f"{path}: "
        super().__init__(where + message)
        self.path = path
        self.line = line


class UnreachableError(SPMError, ValueError):
    """A pose or input has no assembly / working mode.

    Attributes:
        leg: 1-based index of the leg that cannot close, when one leg is to blame.
        value: The input that was given.
    """

    def __init__(self, message: str, *, leg: int | None = None, value: Any = None) -> None:
        super().__init__(message)
        self.leg = leg
        self.value = value


class SingularityError(SPMError, ValueError):
    """The requested quantity does not exist at a singular configuration.

    Attributes:
        kind: ``"type I"`` (serial, some b_ii = 0) or ``"type II"`` (parallel, det A = 0).
        value: The input that was given.
    """

    def __init__(self, message: str, *, kind: str, value: Any = None) -> None:
        super().__init__(message)
        self.kind = kind
        self.value = value


class ConvergenceError(SPMError, RuntimeError):
    """An iterative solver did not converge.

    Attributes:
        data: Whatever the solver had when it stopped (iterate, residual, iterations).
    """

    def __init__(self, message: str, *, data: dict[str, Any] | None = None) -> None:
        super().__init__(message)
        self.data = data or {}


class HardwareError(SPMError, RuntimeError):
    """The servo bus or a servo failed (port, model, reply, alert).

    Attributes:
        servo_id: The servo to blame, when one is (None for the whole bus).
        operation: What was being done, e.g. ``"sync read"`` or ``"write Goal Position"``.
    """

    def __init__(
        self, message: str, *, servo_id: int | None = None, operation: str | None = None
    ) -> None:
        super().__init__(message)
        self.servo_id = servo_id
        self.operation = operation


class CommunicationError(HardwareError):
    """No valid status packet after the bounded retries (silent, unplugged, garbled).

    Attributes:
        result: The last dynamixel-sdk result code (e.g. -3001, no status packet), or
            None when the port itself failed.
        servo_ids: Every servo that did not answer, when known.
    """

    def __init__(
        self,
        message: str,
        *,
        servo_id: int | None = None,
        operation: str | None = None,
        result: int | None = None,
        servo_ids: tuple[int, ...] = (),
    ) -> None:
        super().__init__(message, servo_id=servo_id, operation=operation)
        self.result = result
        self.servo_ids = servo_ids or ((servo_id,) if servo_id is not None else ())


class ServoError(HardwareError):
    """A servo answered with an instruction error (the low 7 bits of the error byte).

    Attributes:
        error: The error number (1 result fail, 2 instruction, 3 CRC, 4 data range,
            5 data length, 6 data limit, 7 access).
    """

    def __init__(
        self,
        message: str,
        *,
        servo_id: int | None = None,
        operation: str | None = None,
        error: int = 0,
    ) -> None:
        super().__init__(message, servo_id=servo_id, operation=operation)
        self.error = error


class ServoAlertError(HardwareError):
    """A servo reports a hardware error (alert bit) that the reboot policy cannot clear.

    Attributes:
        status: The Hardware Error Status bits, by servo id.
    """

    def __init__(
        self, message: str, *, servo_id: int | None = None, status: dict[int, int] | None = None
    ) -> None:
        super().__init__(message, servo_id=servo_id, operation="hardware error status")
        self.status = dict(status or {})


class UnsafeCommandError(SPMError, ValueError):
    """A goal that the safety guard refused; nothing was sent to the servos.

    Attributes:
        reasons: Why, one sentence each (unreachable, singular, colliding, limits).
        goal: The refused input angles [rad] (a path: the first unsafe sample).
        index: Index of the first unsafe sample of a path (None for a single goal).
    """

    def __init__(
        self,
        message: str,
        *,
        reasons: tuple[str, ...] = (),
        goal: Any = None,
        index: int | None = None,
    ) -> None:
        super().__init__(message)
        self.reasons = reasons
        self.goal = goal
        self.index = index


class PlanningError(SPMError, ValueError):
    """No safe path: the start or the goal is unsafe, or the goal lies in a part of
    the safe set that the start cannot reach.

    Attributes:
        reasons: Why, one sentence each (which check fails, and where).
        check: The failing check: ``"start"``, ``"goal"`` (unsafe end points) or
            ``"connected"`` (no safe path between them).
        nearest: The safe input angles nearest the unsafe end point [rad], (3,), when
            one was found (None otherwise).
    """

    def __init__(
        self,
        message: str,
        *,
        reasons: tuple[str, ...] = (),
        check: str = "goal",
        nearest: Any = None,
    ) -> None:
        super().__init__(message)
        self.reasons = reasons
        self.check = check
        self.nearest = nearest
