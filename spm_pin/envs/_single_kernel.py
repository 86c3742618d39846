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
:func:`~spm_pin.envs._observe_kernel.observe_record`, with the numbers Python reads
after the step gathered into one array (:data:`SUMMARY`): a call converts one
object.

This module imports numba: it is imported only where :func:`spm_pin._jit.available`.
The functions are compiled by :func:`spm_pin._jit.kernels` (of :data:`KINEMATIC` or
:data:`DYNAMIC`, after the kernels they call), cached on disk like the others.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numba.core import types
from numba.experimental import structref

from ._dynamic_kernel import step as dynamic_step
from ._kinematic_kernel import step as kinematic_step
from ._observe_kernel import observe_record

__all__ = ["DYNAMIC", "KINEMATIC", "SUMMARY", "SingleCall", "dynamic", "kinematic", "make"]


@structref.register
class SingleCallType(types.StructRef):
    """The numba type of :class:`SingleCall` (its fields' types as given)."""

    def preprocess_fields(self, fields: Any) -> Any:
        return tuple((name, types.unliteral(kind)) for name, kind in fields)  # type: ignore[no-untyped-call]


class SingleCall(structref.StructRefProxy):
    """The arguments of a single environment's step and observation, bundled: ``step``
    (the step kernel's arguments), ``observe`` (those of
    :func:`~spm_pin.envs._observe_kernel.observe_record`), the step's buffers ``out``
    (1, 5) and ``handed`` (1,), the core's ``steps`` and the ``summary``
    (:data:`SUMMARY` numbers) written after the step. Made by :func:`make`."""


FIELDS = ["step", "observe", "out", "handed", "steps", "summary"]
structref.define_proxy(SingleCall, SingleCallType, FIELDS)  # type: ignore[no-untyped-call]

#: The numbers of a step's summary, in order: the step's out (reward, orientation
#: error, step fraction, 1.0 / 0.0 for success and unsafe), 1.0 / 0.0 for handed back
#: (-1.0: an action not finite, refused before anything moved), and the robot's steps
#: in its episode. (The cover's checks are added to counts that the lookup tracks:
#: :meth:`~spm_pin.envs._safe_lookup.SafeLookup.track`.)
SUMMARY = 7


def make(
    step: tuple[Any, ...],
    observe: tuple[Any, ...],
    out: Any,
    handed: Any,
    steps: Any,
    summary: Any,
) -> Any:
    """The :class:`SingleCall` of these arguments (compiled: cached on disk, unlike the
    proxy's own constructor)."""
    return SingleCall(step, observe, out, handed, steps, summary)  # type: ignore[no-untyped-call]


def _start(call: Any) -> bool:
    """The step's hand-back flag cleared; False (the summary's hand-back flag -1.0)
    where the action (written by Python, its shape checked) is not finite."""
    action = call.step[1]
    if not (np.isfinite(action[0, 0]) and np.isfinite(action[0, 1]) and np.isfinite(action[0, 2])):
        call.summary[5] = -1.0
        return False
    call.handed[0] = False
    return True


def _finish(call: Any) -> None:
    """The summary of the step written; the observation and the record, unless the
    robot was handed back."""
    summary, out, handed = call.summary, call.out, call.handed
    for j in range(5):
        summary[j] = out[0, j]
    summary[5] = 1.0 if handed[0] else 0.0
    summary[6] = call.steps[0]
    if not handed[0]:
        observe_record(*call.observe)


def kinematic(call: Any) -> None:
    """The kinematic step of ``call.step`` (robot 0), then :func:`_finish`; nothing
    for an action that is not finite (see :func:`_start`)."""
    if _start(call):
        kinematic_step(*call.step)
        _finish(call)


def dynamic(call: Any) -> None:
    """:func:`kinematic` with the dynamic step."""
    if _start(call):
        dynamic_step(*call.step)
        _finish(call)


#: The kernels of a kinematic single environment (after the kinematic and the
#: observation kernels): what :func:`spm_pin._jit.kernels` compiles.
KINEMATIC = (make, _start, _finish, kinematic)
#: The kernels of a dynamic single environment (after the dynamic and the observation
#: kernels).
DYNAMIC = (make, _start, _finish, dynamic)
