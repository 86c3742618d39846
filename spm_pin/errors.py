"""Errors raised by spm-pin.

Every error the library raises derives from :class:`SPMError`. Each subclass also
derives from the builtin exception that fits (``ValueError``, ``RuntimeError``), so
code written against the builtins keeps working. Errors keep the data behind the
failure as attributes; nothing the user gave is lost.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "ConvergenceError",
    "DesignError",
    "FileFormatError",
    "InputError",
    "SPMError",
    "SingularityError",
    "UnreachableError",
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
