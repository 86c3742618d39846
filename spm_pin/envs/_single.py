"""Robot 0 of a core stepped as a single environment, with the least work around the
compiled kernels.

The vector environment steps its robots with :meth:`OrientCore.step_rows
<spm_pin.envs._core.OrientCore.step_rows>` and a dozen array calls around it; for
one robot that work, not the physics, would be most of a step. :class:`SingleStep`
does the same step of robot 0 (the same kernel, the same numbers: the tests compare
it with the vector environment of one robot, bit for bit) with its calls gathered
once:

* the step kernel's arguments, and those of the observation and of the info's
  numbers (:func:`~spm_pin.envs._observe_kernel.observe_record`), are gathered on
  the first step; the kernels are then called through their compiled entry points
  (:func:`spm_pin._jit.entry`: no typing of the arguments by numba at each step);
* where both are the modules' own kernels, one compiled call does both
  (:mod:`~spm_pin.envs._single_kernel`: the arguments bundled in one numba
  structure, so a step converts one object instead of about fifty arrays);
* a float action of shape (3,) is written as it is and its values checked by the
  whole step's compiled call (:func:`~spm_pin.envs._actions.fill_action` in Python
  where the calls are apart; anything else by
  :func:`~spm_pin.envs._actions.check_actions` first); the results are read as
  Python numbers from one array, the info's arrays as views of one copy made per
  step; the cover's checks are counted by the lookup, which tracks the kernel's
  counters (:meth:`~spm_pin.envs._safe_lookup.SafeLookup.track`).

A robot the kernel hands back is stepped by numpy (:meth:`OrientCore._hand_back
<spm_pin.envs._core.OrientCore._hand_back>`) and observed afterwards; without the
compiled step (no cover, no numba, ``fused`` off) it is :meth:`step_rows` of row 0.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, NamedTuple

import numpy as np
import numpy.typing as npt

from .. import _jit
from . import _observe_kernel
from ._actions import check_actions, fill_action
from ._core import _ROW, OBSERVATION_SIZE, BoolArray, FloatArray, IntArray, OrientCore, StepOne

__all__ = ["SingleStep"]

ObsArray = npt.NDArray[np.float32]


class _One(NamedTuple):
    """The step kernel's call: its buffers (robot 0's action row, out, handed,
    counts), the kernel, its entry point and its arguments."""

    action: FloatArray
    out: FloatArray
    handed: BoolArray
    counts: IntArray
    kernel: Any
    call: Callable[..., None]
    args: tuple[Any, ...]


class _Record(NamedTuple):
    """The observation's call: its entry point and arguments, the observation row
    (21,) and the record it writes, and the record's parts (info key, slice or
    index)."""

    call: Callable[..., None]
    args: tuple[Any, ...]
    obs: ObsArray
    record: FloatArray
    parts: tuple[tuple[str, Any], ...]


class _Whole(NamedTuple):
    """The whole step's compiled call and what a step reads around it, unpacked once
    per step: the entry point, its bundle, the summary (:data:`~spm_pin.envs.
    _single_kernel.SUMMARY` numbers), robot 0's action row, the record and the
    observation row it writes, the record's parts (as :class:`_Record`'s) and the
    episode's step limit."""

    call: Callable[..., None]
    bundle: Any
    summary: FloatArray
    action: FloatArray
    record: FloatArray
    obs: ObsArray
    parts: tuple[tuple[str, Any], ...]
    max_steps: int


class SingleStep:
    """Robot 0 of ``core`` stepped and observed as a single environment (see the
    module).

    Args:
        core: The core of one robot.
    """

    def __init__(self, core: OrientCore) -> None:
        self.core = core
        self._one: _One | None = None
        self._record: _Record | None = None
        #: The whole step's compiled call and what a step reads, once made.
        self._whole: _Whole | None = None
        #: Whether the whole step's call was found not to apply.
        self._apart = False
        self._max_steps = core.settings.max_steps

    # ---------------------------------------------------------------- the calls
    def _prepared_one(self) -> _One | None:
        """The step kernel's call, made on first use while ``fused``; None where the
        compiled step does not apply."""
        if self._one is not None and self.core.fused:
            return self._one
        core = self.core
        arguments = core._compiled_step()
        if arguments is None:
            return None
        if self._one is None:
            rows, actions, out = np.zeros(1, dtype=np.int64), np.empty((1, 3)), np.empty((1, 5))
            handed, counts = np.zeros(1, dtype=bool), np.zeros(2, dtype=np.int64)
            kernel, args = core._step_call(rows, actions, out, handed, counts, arguments)
            entry = _jit.entry(kernel, args)
            assert core.lookup is not None  # a compiled step has a cover
            core.lookup.track(counts)  # the kernel adds to counts, never reset
            self._one = _One(actions[0], out, handed, counts, kernel, entry, args)
        return self._one

    def _prepared_record(self) -> _Record | None:
        """The observation's call, made on first use; None where it does not apply
        (observation noise, calibration errors, ``fused`` off, no numba)."""
        core = self.core
        if core.settings.observation_noise != 0.0 or core.believed is not None or not core.fused:
            return None
        if self._record is None:
            if not _jit.available():
                return None
            obs = np.empty((1, OBSERVATION_SIZE), dtype=np.float32)
            sources = core.record_sources()
            record = np.empty(sum(source.shape[1] for source in sources))
            rows = np.zeros(1, dtype=np.int64)
            speed_limit = float(core.limits.max_speed)
            state = (core.R, core.goal, core.theta, core.speed)
            args = (rows, *state, speed_limit, obs, sources, record)
            kernel = _jit.kernels(_observe_kernel.KERNELS)["observe_record"]
            at, parts = 0, []
            for (key, _, size), source in zip(core.RECORD, sources, strict=True):
                width = source.shape[1]
                parts.append((key, slice(at, at + width) if size else at))
                at += width
            self._record = _Record(_jit.entry(kernel, args), args, obs[0], record, tuple(parts))
        return self._record

    def _prepared_whole(self) -> _Whole | None:
        """The whole step's compiled call (:mod:`~spm_pin.envs._single_kernel`) and
        what a step reads, made on first use; None where it does not apply (either call
        missing, or a step kernel other than the module's own)."""
        one, record = self._prepared_one(), self._prepared_record()
        if one is None or record is None or self._apart:
            return None
        if self._whole is None:
            compiled = _jit.ready(self.core.STEP_KERNELS)
            if compiled is None or one.kernel is not compiled["step"]:
                self._apart = True
                return None
            from . import _single_kernel  # imports numba

            family = getattr(_single_kernel, self.core.SINGLE)
            kernels = _jit.kernels(family)
            summary = np.zeros(_single_kernel.SUMMARY)
            parts = (one.out, one.handed, self.core.steps, summary)
            bundle = kernels["make"](one.args, record.args, *parts)
            whole = kernels[family[-1].__name__]
            self._whole = _Whole(
                _jit.entry(whole, (bundle,)), bundle, summary, one.action, record.record,
                record.obs, record.parts, self._max_steps,
            )  # fmt: skip
        return self._whole

    # ---------------------------------------------------------------- the step
    def _start(self, one: _One, action: npt.ArrayLike) -> None:
        """The action into the step's buffer (checked), the flag cleared."""
        fill_action(one.action, action)
        one.handed[0] = False

    def _result(self, one: _One) -> StepOne:
        """The step's result from the kernel's buffers (a robot handed back: stepped
        by numpy; the cover's checks are counted by the lookup, which tracks the
        kernel's counts)."""
        core = self.core
        if one.handed[0]:
            return StepOne.of(core._hand_back(_ROW, one.action[None].copy()))
        reward, error, fraction, success, unsafe = one.out[0].tolist()
        terminated = success != 0.0 or unsafe != 0.0
        truncated = not terminated and int(core.steps[0]) >= self._max_steps
        return StepOne(
            reward, terminated, truncated, error, fraction, success != 0.0, unsafe != 0.0
        )

    def step_one(self, action: npt.ArrayLike) -> StepOne:
        """:meth:`~spm_pin.envs._core.OrientCore.step_rows` of robot 0 with the
        normalised action (3,), checked as
        :func:`~spm_pin.envs._actions.check_actions` checks it."""
        one = self._prepared_one()
        if one is None:
            return StepOne.of(self.core.step_rows(_ROW, check_actions(action, (3,))[None]))
        self._start(one, action)
        one.call(*one.args)
        return self._result(one)

    def _read(self, record: _Record) -> tuple[ObsArray, dict[str, Any]]:
        """The observation and the info's numbers from the record (copies)."""
        numbers = record.record.copy()  # the info's arrays: views of this copy
        return record.obs.copy(), {key: numbers[part] for key, part in record.parts}

    def observe_one(self, rng: np.random.Generator) -> tuple[ObsArray, dict[str, Any]]:
        """Robot 0's observation (21,) (:meth:`~spm_pin.envs._core.OrientCore.observe`,
        its noise from ``rng``) and its ``RECORD`` entries for a step's info (copies,
        never views of the state)."""
        record = self._prepared_record()
        if record is None:
            core = self.core
            obs = core.observe(_ROW, [rng])[0]
            return obs, {key: getattr(core, name)[0].copy() for key, name, _ in core.RECORD}
        record.call(*record.args)
        return self._read(record)

    @staticmethod
    def info(result: StepOne, numbers: dict[str, Any]) -> dict[str, Any]:
        """A step's info: ``orientation_error`` [rad], ``step_fraction``, ``success``,
        ``unsafe`` and the ``RECORD`` entries ``numbers``."""
        return {
            "orientation_error": result.error,
            "step_fraction": result.fraction,
            "success": result.success,
            "unsafe": result.unsafe,
            **numbers,
        }

    def step(
        self, action: npt.ArrayLike, rng: np.random.Generator
    ) -> tuple[ObsArray, float, bool, bool, dict[str, Any]]:
        """One step of robot 0 with the normalised action (3,): what a Gymnasium
        step returns (the observation after it, the reward, terminated, truncated, the
        info (:meth:`info`)); ``rng``: the observation noise's generator."""
        whole = self._whole
        if whole is None or not self.core.fused:
            whole = self._prepared_whole()
            if whole is None:
                result = self.step_one(action)
                obs, numbers = self.observe_one(rng)
                return self._gymnasium(obs, result, numbers)
        call, bundle, summary, row, record, obs, parts, max_steps = whole
        if type(action) is np.ndarray and action.shape == (3,) and action.dtype.kind == "f":
            row[...] = action  # its values are checked by the compiled call
        else:
            row[...] = check_actions(action, (3,))
        call(bundle)
        reward, error, fraction, success, unsafe, handed, steps = summary.tolist()
        if handed:
            return self._handed(action, handed)
        numbers = record.copy()  # the info's arrays: views of this copy
        info = {
            "orientation_error": error,
            "step_fraction": fraction,
            "success": success != 0.0,
            "unsafe": unsafe != 0.0,
        }
        for key, part in parts:
            info[key] = numbers[part]
        terminated = success != 0.0 or unsafe != 0.0
        truncated = not terminated and steps >= max_steps
        return obs.copy(), reward, terminated, truncated, info

    def _handed(
        self, action: npt.ArrayLike, handed: float
    ) -> tuple[ObsArray, float, bool, bool, dict[str, Any]]:
        """A step the whole call did not end (its summary's flag ``handed``): an
        action not finite (-1.0: refused, nothing moved) raises the InputError; a robot
        handed back (1.0) is stepped by numpy, then observed."""
        one, record = self._one, self._record
        assert one is not None and record is not None
        if handed < 0.0:
            check_actions(action, (3,))  # raises the InputError
            raise AssertionError("the compiled step refused a finite action")
        result = StepOne.of(self.core._hand_back(_ROW, one.action[None].copy()))
        record.call(*record.args)
        obs, numbers = self._read(record)
        return self._gymnasium(obs, result, numbers)

    def _gymnasium(
        self, obs: ObsArray, result: StepOne, numbers: dict[str, Any]
    ) -> tuple[ObsArray, float, bool, bool, dict[str, Any]]:
        """What a Gymnasium step returns, from the step's parts."""
        info = self.info(result, numbers)
        return obs, result.reward, result.terminated, result.truncated, info
