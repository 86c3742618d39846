r"""Which assembly mode to show or check at given input angles: one rule, one place.

Every function and command that takes input angles and needs one platform pose
(``spm collide``, ``spm show``, ``spm animate``, the workspace maps, the viewer)
follows :func:`select_assembly`:

1. the home assembly mode (:func:`~spm_pin.forward_kinematics`) where it exists;
2. else the real assembly mode nearest to it: fewest of the four signs (b_11, b_22,
   b_33, det A) that differ from the home mode's, then the smallest tilt of the
   platform normal from its home direction (compared to 1e-9 in its cosine: modes
   related by a symmetry tilt equally), then the slot order of
   :func:`~spm_pin.forward_kinematics_all` (whose labels are unique); the result
   names the mode by its label;
3. with no real assembly at all, none: ``exists`` is False and ``R`` is NaN.

The hardware guard is stricter on purpose: it lets a goal reach the servos only
where the home mode exists (rule 1), since the real robot cannot jump to another
assembly mode.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import numpy.typing as npt

from ..design import SPMDesign
from ._common import BoolArray, FloatArray, as_theta, check_design
from .fk import forward_kinematics, forward_kinematics_all, label_array, sign_label

__all__ = ["Assembly", "home_mode_label", "select_assembly"]

#: Mode label of an input with no real assembly.
NO_ASSEMBLY = ""


@dataclasses.dataclass(frozen=True)
class Assembly:
    """The assembly mode chosen at each input by :func:`select_assembly`.

    Attributes:
        theta: Input angles [rad], shape (..., 3).
        R: Platform rotation (..., 3, 3); NaN where no real assembly exists.
        label: Mode label (a str for one input, nested lists for a batch), as in
            :attr:`~spm_pin.kinematics.FKAllResult.labels`; ``""`` where none exists.
        home: (...,) the chosen mode is the home assembly mode.
        exists: (...,) a real assembly exists (the home mode or another one).
    """

    theta: FloatArray
    R: FloatArray
    label: object
    home: BoolArray
    exists: BoolArray

    @property
    def description(self) -> str:
        """One line naming the mode of a single input, for reports and pages."""
        if self.theta.ndim != 1:
            return f"assembly modes of {self.theta.shape[0]} inputs"
        if not bool(self.exists):
            return "no real assembly mode"
        if bool(self.home):
            return f"home assembly mode {self.label}"
        return f"assembly mode {self.label} (no home-mode assembly; the real mode nearest to it)"


def _differing_signs(b: FloatArray, det_a: FloatArray, design: SPMDesign) -> npt.NDArray[np.int64]:
    """How many of the signs of b_11, b_22, b_33, det A differ from the home mode's."""
    home_det = np.sign(design.home_det_a)
    result: npt.NDArray[np.int64] = np.sum(b <= 0, axis=-1) + (np.sign(det_a) != home_det)
    return result


def select_assembly(theta: npt.ArrayLike, design: SPMDesign | None = None) -> Assembly:
    """The assembly mode the library shows and checks at input angles ``theta``.

    The home mode where it exists, else the real mode nearest to it (see the module
    docstring), else none.

    Args:
        theta: Input angles [rad], shape (3,) or (..., 3).
        design: The SPM (default: the prototype).

    Returns:
        Assembly, with the label of the chosen mode.

    Raises:
        InputError: bad ``theta`` or ``design``.
    """
    design = check_design(design)
    theta_in = as_theta(theta)
    shape = theta_in.shape[:-1]
    flat = theta_in.reshape(-1, 3)
    fk = forward_kinematics(flat, design)
    R = fk.R.copy()
    home = np.asarray(fk.reachable, dtype=bool).copy()
    exists = home.copy()
    # The home mode satisfies the home sign rule: its label is the home signs.
    labels = [home_mode_label(design) if h else NO_ASSEMBLY for h in home]
    rest = np.nonzero(~home)[0]
    if rest.size:
        every = forward_kinematics_all(flat[rest], design)
        distance = np.where(every.valid, _differing_signs(every.b, every.det_a, design), 99)
        # Modes related by a symmetry tilt equally: compare tilts to 1e-9, then the
        # slot order decides.
        tilt_key = np.round(-np.nan_to_num(every.R[..., 2, 2], nan=2.0), 9)
        slots = every.valid.shape[-1]
        row = np.repeat(np.arange(rest.size), slots)
        slot = np.tile(np.arange(slots), rest.size)
        order = np.lexsort((slot, tilt_key.ravel(), distance.ravel(), row))
        pick = slot[order[::slots]]
        found = np.any(every.valid, axis=-1)
        j = np.nonzero(found)[0]
        R[rest[j]] = every.R[j, pick[j]]
        exists[rest[j]] = True
        every_labels = label_array(every.b, every.det_a, every.valid)
        for jj in j:
            labels[int(rest[jj])] = str(every_labels[jj, pick[jj]])
    label: object = (
        labels[0] if not shape else np.array(labels, dtype=object).reshape(shape).tolist()
    )
    return Assembly(
        theta=theta_in,
        R=R.reshape(*shape, 3, 3),
        label=label,
        home=home.reshape(shape),
        exists=exists.reshape(shape),
    )


def home_mode_label(design: SPMDesign) -> str:
    """The label of the home assembly mode of ``design`` (``"+++/-"`` for the
    prototype): every b_ii positive, det A of its sign at home."""
    return sign_label(np.ones(3), float(design.home_det_a))
