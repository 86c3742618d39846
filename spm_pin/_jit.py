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

``kernels(..., lanes=True)`` compiles a second family of twins for loops over robots
that LLVM turns into vector instructions (one robot per lane): numpy's error model (a
float division by zero gives inf or NaN instead of raising, so no exception branch
stops the vectoriser; the operations, and so the bits, are otherwise the same) and
every function but the :func:`nogil` entry points and the :func:`standalone` passes
inlined into its callers (LLVM alone leaves some callees of a long loop body as
calls, which no vector loop may hold). A function it does not list is called as the
plain family's twin, compiled before.

The machine code is cached on disk (numba's cache, beside the sources) under each
kernel's name and a digest of its code, of the kernels it calls and of the constants
it names (:func:`_digest`): numba stamps a cache with the kernel's own file alone, so
a change in another file would otherwise leave a caller's stale machine code in use.
"""

from __future__ import annotations

import hashlib
import os
import threading
import types
import warnings
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

__all__ = [
    "ENV_VARIABLE",
    "available",
    "entry",
    "inline",
    "kernels",
    "nogil",
    "ready",
    "standalone",
]

#: Set to ``0`` to run the Python kernels even where numba is installed.
ENV_VARIABLE = "SPM_PIN_JIT"

_lock = threading.Lock()
_cache: dict[tuple[tuple[Callable[..., Any], ...], bool], dict[str, Callable[..., Any]]] = {}
#: Compiled twins by the id of their Python function and their family (``lanes``),
#: the functions kept alive by ``_originals``.
_compiled: dict[tuple[int, bool], Callable[..., Any]] = {}
_originals: list[Callable[..., Any]] = []
#: The digest of each compiled function (by the id of its Python function and its
#: family): see :func:`_digest`.
_digests: dict[tuple[int, bool], str] = {}
#: The attributes :func:`inline`, :func:`nogil` and :func:`standalone` set on a
#: function.
_INLINE = "_spm_pin_jit_inline"
_NOGIL = "_spm_pin_jit_nogil"
_STANDALONE = "_spm_pin_jit_standalone"

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


def standalone(function: F) -> F:
    """Mark a kernel of the ``lanes`` family to be compiled as a function of its own
    rather than inlined into its callers, returned unchanged: a function that holds
    a vectorised loop (one pass over the robots), called a few times per step of its
    callers. Inlining it would compile its body again in each caller, and the
    largest bodies cost most of a family's compile time; the loops inside are
    vectorised the same way in either case."""
    setattr(function, _STANDALONE, True)
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


def kernels(
    functions: Sequence[Callable[..., Any]], *, lanes: bool = False
) -> dict[str, Callable[..., Any]]:
    """The functions compiled by numba (``njit``, cached on disk), by name.

    Args:
        functions: Plain Python functions, each after the functions it calls (a
            compiled function calls the compiled twins of the functions compiled
            before it, in this call or an earlier one, of its family; each is
            compiled once per family).
        lanes: The family for vectorised loops over robots (see the module).

    Returns:
        Name -> compiled function, or name -> the function itself where numba is
        not available (see :func:`available`). Compiled on first use of each.
    """
    key = (tuple(functions), lanes)
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
            compiled = _compiled.get((id(function), lanes))
            if compiled is None:
                compiled = _compile(numba, function, lanes)
                _compiled[(id(function), lanes)] = compiled
                _originals.append(function)
            out[function.__name__] = compiled
        _cache[key] = out
        return out


def _code_text(code: types.CodeType) -> list[str]:
    """What a code object computes, as text: its bytecode, names and constants
    (nested code objects the same way; frozensets sorted, so the text does not
    depend on the interpreter's hash seed)."""
    parts = [code.co_code.hex(), repr(code.co_names), repr(code.co_varnames)]
    for const in code.co_consts:
        if isinstance(const, types.CodeType):
            parts.extend(_code_text(const))
        elif isinstance(const, frozenset):
            parts.append(repr(sorted(repr(item) for item in const)))
        else:
            parts.append(repr(const))
    return parts


def _value_text(value: Any) -> str | None:
    """A global value numba would freeze into machine code, as text (numbers,
    strings, arrays and tuples of them); None for anything else (modules, classes,
    functions: their text would not be the same in another process)."""
    if isinstance(value, (bool, int, float, complex, str, bytes)):
        return repr(value)
    if isinstance(value, tuple):
        items = [_value_text(item) for item in value]
        texts = [text for text in items if text is not None]
        return f"({','.join(texts)})" if len(texts) == len(items) else None
    tobytes = getattr(value, "tobytes", None)
    if callable(tobytes) and hasattr(value, "dtype") and hasattr(value, "shape"):
        digest = hashlib.sha256(tobytes()).hexdigest()[:16]
        return f"array({value.dtype},{value.shape},{digest})"
    return None


def _digest(function: Callable[..., Any], lanes: bool) -> str:
    """A digest of what ``function`` compiles to in its family (``lanes``): its code,
    its :func:`inline`, :func:`nogil` and :func:`standalone` marks, the family, the
    digests of the compiled functions it calls and the values of the numbers,
    strings, arrays and tuples of its module that it names (numba freezes them into
    the machine code).

    numba's cache on disk is stamped with the source file of each function alone:
    a caller compiled from one file keeps the machine code of its callees in
    another file, and of constants computed from other modules, after they changed
    (an editable install, a user's own kernel). The digest, part of the name the
    cache is kept under, makes a change anywhere down the calls a new entry.
    """
    code: types.CodeType = function.__code__
    parts = [
        function.__module__,
        function.__qualname__,
        repr(getattr(function, _INLINE, False)),
        repr(getattr(function, _NOGIL, False)),
        repr(getattr(function, _STANDALONE, False)),
        f"lanes={lanes}",
        repr(function.__defaults__),
        *_code_text(code),
    ]
    names = set(code.co_names)
    for const in code.co_consts:  # names used by nested code too
        if isinstance(const, types.CodeType):
            names.update(const.co_names)
    namespace = function.__globals__
    for name in sorted(names):
        if name not in namespace:
            continue
        value = namespace[name]
        callee = _digests.get((id(value), lanes)) or _digests.get((id(value), False))
        if callee is not None:
            parts.append(f"{name}={callee}")
        else:
            text = _value_text(value)
            if text is not None:
                parts.append(f"{name}={text}")
    return hashlib.sha256("\n".join(parts).encode()).hexdigest()[:16]


def _twin(value: Any, lanes: bool) -> Any:
    """The compiled twin of ``value`` in the family ``lanes``; in the ``lanes`` family,
    where it has none, the plain family's (a function called once per robot, outside
    the vectorised loops, need not be compiled again); else ``value`` itself."""
    twin = _compiled.get((id(value), lanes))
    if twin is None and lanes:
        twin = _compiled.get((id(value), False))
    return value if twin is None else twin


def _compile(numba: Any, function: Callable[..., Any], lanes: bool) -> Callable[..., Any]:
    """A numba twin of ``function`` in its family (``lanes``): a clone whose globals
    name the compiled twins of the functions compiled before it (by identity, in the
    same family), so the original stays Python. Its cache on disk is kept under its
    name and :func:`_digest`."""
    namespace = {
        name: _twin(value, lanes) if callable(value) else value
        for name, value in function.__globals__.items()
    }
    clone = types.FunctionType(
        function.__code__,
        namespace,
        function.__name__,
        function.__defaults__,
        function.__closure__,
    )
    digest = _digest(function, lanes)
    _digests[(id(function), lanes)] = digest
    clone.__qualname__ = f"{function.__qualname__}-{digest}"
    clone.__module__ = function.__module__
    with warnings.catch_warnings():  # a read-only install cannot cache: fine
        warnings.simplefilter("ignore", numba.NumbaWarning)
        free = bool(getattr(function, _NOGIL, False))
        alone = free or bool(getattr(function, _STANDALONE, False))
        inlined = getattr(function, _INLINE, False) or (lanes and not alone)
        compiled: Callable[..., Any] = numba.njit(
            cache=True,
            nogil=free,
            inline="always" if inlined else "never",
            error_model="numpy" if lanes else "python",
        )(clone)
    return compiled


def entry(kernel: Callable[..., Any], args: Sequence[Any]) -> Callable[..., Any]:
    """The machine code of a kernel of :func:`kernels` for the types of ``args``
    (compiled if needed), callable without numba's dispatch: a caller that calls a
    kernel again and again with the same arrays and constants (one robot's step)
    skips typing each argument every time (a few microseconds for a few dozen).

    The entry point converts its arguments by those types without checking them:
    call it only with arguments of the very types of ``args`` (the same objects, or
    arrays of their dtype, dimensions and layout). Without numba, or for a function
    that numba did not compile, the function itself."""
    numba = _numba()
    overloads = getattr(kernel, "overloads", None)
    if numba is None or overloads is None:
        return kernel
    signature = tuple(kernel.typeof_pyval(value) for value in args)  # type: ignore[attr-defined]
    if signature not in overloads:
        kernel.compile(signature)  # type: ignore[attr-defined]
    point: Callable[..., Any] = overloads[signature].entry_point
    return point


def ready(
    functions: Sequence[Callable[..., Any]], *, lanes: bool = False
) -> dict[str, Callable[..., Any]] | None:
    """What :func:`kernels` gave for these functions (and family), if it was called
    in this process; else None (nothing is compiled or imported here)."""
    return _cache.get((tuple(functions), lanes))
