"""A single environment's whole step in one compiled call (numba, extra ``fast``).

A single environment calls the same compiled step as the vector environment, with a
batch of one robot. From Python, most of what is left around the physics is the
crossing into the compiled code: numba converts each array argument at each call
(about 40 ns each), and the step takes about forty of them (the state, the
constants, the cover), then the observation takes ten more. Here they are bundled
once into one numba structure (:class:`SingleCall`, a ``structref`` that holds the
very arrays of the core, not copies), and :func:`kinematic` or :func:`dynamic` runs,
in one call, the step of :mod:`~spm_pin.envs._kinematic_kernel` or
:mod:`~spm_pin.envs._dynamic_kernel` and, unless the robot was handed back to numpy,
:func:`~spm_pin.envs._observe_kernel.observe_record`: a call converts one object.

This module imports numba: it is imported only where :func:`spm_pin._jit.available`.
The functions are compiled by :func:`spm_pin._jit.kernels` (of :data:`KINEMATIC` or
:data:`DYNAMIC`, after the kernels they call), cached on disk like the others.
"""

from __future__ import annotations

from typing import Any

from numba.core import types
from numba.experimental import structref

from ._dynamic_kernel import step as dynamic_step
from ._kinematic_kernel import step as kinematic_step
from ._observe_kernel import observe_record

__all__ = ["DYNAMIC", "KINEMATIC", "SingleCall", "dynamic", "kinematic", "make"]


@structref.register
class SingleCallType(types.StructRef):
    """The numba type of :class:`SingleCall` (its fields' types as given)."""

    def preprocess_fields(self, fields: Any) -> Any:
        return tuple((name, types.unliteral(kind)) for name, kind in fields)  # type: ignore[no-untyped-call]


class SingleCall(structref.StructRefProxy):
    """The arguments of a single environment's step and observation, bundled: ``step``
    (the step kernel's arguments), ``observe`` (those of
    :func:`~spm_pin.envs._observe_kernel.observe_record`) and ``handed`` (the step's
    hand-back flag, (1,)). Made by :func:`make`."""


structref.define_proxy(SingleCall, SingleCallType, ["step", "observe", "handed"])  # type: ignore[no-untyped-call]


def make(step: tuple[Any, ...], observe: tuple[Any, ...], handed: Any) -> Any:
    """The :class:`SingleCall` of these arguments (compiled: cached on disk, unlike the
    proxy's own constructor)."""
    return SingleCall(step, observe, handed)  # type: ignore[no-untyped-call]


def kinematic(call: Any) -> None:
    """The kinematic step of ``call.step``, then the observation and record of
    ``call.observe`` unless the robot was handed back."""
    kinematic_step(*call.step)
    if not call.handed[0]:
        observe_record(*call.observe)


def dynamic(call: Any) -> None:
    """:func:`kinematic` with the dynamic step."""
    dynamic_step(*call.step)
    if not call.handed[0]:
        observe_record(*call.observe)


#: The kernels of a kinematic single environment (after the kinematic and the
#: observation kernels): what :func:`spm_pin._jit.kernels` compiles.
KINEMATIC = (make, kinematic)
#: The kernels of a dynamic single environment (after the dynamic and the observation
#: kernels).
DYNAMIC = (make, dynamic)
