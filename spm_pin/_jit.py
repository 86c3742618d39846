"""Optional compilation of the single-input float kernels with numba (extra ``fast``).

The control loop's single-input code (:mod:`spm_pin.kinematics._fk_single`, the
closed configuration of :mod:`spm_pin.collision._configuration`) is written in
Python floats and tuples, in a form that numba compiles unchanged: the same
operations in the same order, no fused multiply-adds (numba does not contract them
unless ``fastmath`` is asked for, and it is not), ``math`` functions from the same C
library. The compiled kernels therefore give the Python kernels' bits, which are the
batch code's bits; ``tests/test_jit`` compares them.

:func:`kernels` compiles a list of functions, callees first, each one a clone of the
Python function whose globals see the compiled callees, so the Python functions
themselves stay as they are (numba is imported only when kernels are asked for: the
command line does not pay for it); :func:`ready` gives them to library functions
that use them once something (the guard of a control loop) has compiled them. A
kernel marked by :func:`nogil` releases the GIL (kernels touch no Python object), so
threads may run it on disjoint rows at once; :func:`inline` marks the few callees a
hot loop should have inlined. Without numba, or with the environment variable
``SPM_PIN_JIT=0``, it gives the Python functions: same results, slower.
"""

from __future__ import annotations

import os
import threading
import types
import warnings
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = ["ENV_VARIABLE", "available", "inline", "kernels", "nogil", "ready"]

#: Set to ``0`` to run the Python kernels even where numba is installed.
ENV_VARIABLE = "SPM_PIN_JIT"

_lock = threading.Lock()
_cache: dict[tuple[Callable[..., Any], ...], dict[str, Callable[..., Any]]] = {}
#: Compiled twins by the id of their Python function (kept alive by ``_originals``).
_compiled: dict[int, Callable[..., Any]] = {}
_originals: list[Callable[..., Any]] = []
#: The attributes :func:`inline` and :func:`nogil` set on a function.
_INLINE = "_spm_pin_jit_inline"
_NOGIL = "_spm_pin_jit_nogil"

F = TypeVar("F", bound=Callable[..., Any])


def nogil(function: F) -> F:
    """Mark a kernel to release the GIL while it runs (numba's ``nogil=True``),
    returned unchanged: threads may then run it on disjoint data at once. Only for
    long calls: a thread that gives the GIL up must win it back, which, beside a busy
    thread, can take the interpreter's switch interval (5 ms), so many short calls
    would each risk that wait."""
    setattr(function, _NOGIL, True)
    return function


def inline(function: F) -> F:
    """Mark a kernel to be inlined into its compiled callers (numba's
    ``inline="always"``), returned unchanged.

    For a kernel that takes arrays (a tuple of constants, say): a compiled call passes
    each array with its reference count raised and lowered, which for a small kernel
    costs more than its arithmetic. Inlining changes no operation, so no bit. Mark
    only the few callees on a hot path: each inlined call is compiled again in every
    caller.
    """
    setattr(function, _INLINE, True)
    return function


def _numba() -> Any | None:
    if os.environ.get(ENV_VARIABLE, "1").strip() == "0":
        return None
    try:
        import numba
    except ImportError:
        return None
    return numba


def available() -> bool:
    """Whether :func:`kernels` compiles (numba installed and not switched off)."""
    return _numba() is not None


def kernels(functions: Sequence[Callable[..., Any]]) -> dict[str, Callable[..., Any]]:
    """The functions compiled by numba (``njit``, cached on disk), by name.

    Args:
        functions: Plain Python functions, each after the functions it calls (a
            compiled function calls the compiled twins of the functions compiled
            before it, in this call or an earlier one; each is compiled once).

    Returns:
        Name -> compiled function, or name -> the function itself where numba is
        not available (see :func:`available`). Compiled on first use of each.
    """
    key = tuple(functions)
    with _lock:
        found = _cache.get(key)
        if found is not None:
            return found
        numba = _numba()
        out: dict[str, Callable[..., Any]] = {}
        for function in functions:
            if numba is None:
                out[function.__name__] = function
                continue
            compiled = _compiled.get(id(function))
            if compiled is None:
                compiled = _compile(numba, function)
                _compiled[id(function)] = compiled
                _originals.append(function)
            out[function.__name__] = compiled
        _cache[key] = out
        return out


def _compile(numba: Any, function: Callable[..., Any]) -> Callable[..., Any]:
    """A numba twin of ``function``: a clone whose globals name the compiled twins of
    the functions compiled before it (by identity), so the original stays Python."""
    namespace = {
        name: _compiled.get(id(value), value) if callable(value) else value
        for name, value in function.__globals__.items()
    }
    clone = types.FunctionType(
        function.__code__,
        namespace,
        function.__name__,
        function.__defaults__,
        function.__closure__,
    )
    clone.__qualname__ = function.__qualname__
    clone.__module__ = function.__module__
    with warnings.catch_warnings():  # a read-only install cannot cache: fine
        warnings.simplefilter("ignore", numba.NumbaWarning)
        how = "always" if getattr(function, _INLINE, False) else "never"
        free = bool(getattr(function, _NOGIL, False))
        compiled: Callable[..., Any] = numba.njit(cache=True, nogil=free, inline=how)(clone)
    return compiled


def ready(functions: Sequence[Callable[..., Any]]) -> dict[str, Callable[..., Any]] | None:
    """What :func:`kernels` gave for these functions, if it was called in this
    process; else None (nothing is compiled or imported here)."""
    return _cache.get(tuple(functions))
