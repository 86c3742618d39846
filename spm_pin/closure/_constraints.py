"""The loop closures and the actuated joints of a :class:`ClosedLoop`, checked.

Which constraint models count as loop closures (new Pinocchio 4 kinds, legacy ones
converted), which joints may be actuated, and the index arrays of joints in q and v.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from typing import Any

import numpy as np
import pinocchio as pin

from ..errors import InputError
from ._constants import IntArray

#: Joint kinds whose configuration is a vector of coordinates with q_dot = v (the
#: actuated joints must be of these kinds; when every joint is, q is updated in place).
EUCLIDEAN_JOINTS = frozenset(
    {
        "JointModelRX",
        "JointModelRY",
        "JointModelRZ",
        "JointModelRevoluteUnaligned",
        "JointModelPX",
        "JointModelPY",
        "JointModelPZ",
        "JointModelPrismaticUnaligned",
        "JointModelHX",
        "JointModelHY",
        "JointModelHZ",
        "JointModelHelicalUnaligned",
        "JointModelTranslation",
        "JointModelUniversal",
    }
)

#: The loop-closure kinds accepted, as named in error messages.
CONSTRAINT_KINDS = (
    "pin.FrameAnchorConstraintModel, pin.PointAnchorConstraintModel (bare or in "
    "pin.ConstraintModel) or pin.RigidConstraintModel (CONTACT_6D or CONTACT_3D)"
)


def indices(starts: Any, sizes: Any, joints: Sequence[int]) -> IntArray:
    """Indices in q (``model.idx_qs, model.nqs``) or v of the joints' coordinates."""
    return np.array(
        [k for j in joints for k in range(starts[j], starts[j] + sizes[j])], dtype=np.int64
    )


def actuated_ids(model: pin.Model, actuated: Any) -> list[int]:
    """Joint ids of the actuated joints given by name or id, checked."""
    names = [model.names[j] for j in range(1, model.njoints)]
    if isinstance(actuated, (str, bytes)) or not isinstance(actuated, Iterable):
        raise InputError(
            f"actuated must be a sequence of joint names or ids, got {actuated!r}; joints: {names}",
            argument="actuated",
            value=actuated,
        )
    ids: list[int] = []
    for item in actuated:
        if isinstance(item, str):
            if not model.existJointName(item):
                raise InputError(
                    f"actuated joint {item!r} is not a joint of model {model.name!r}; "
                    f"joints: {names}",
                    argument="actuated",
                    value=actuated,
                )
            joint = int(model.getJointId(item))
        elif isinstance(item, (int, np.integer)) and not isinstance(item, bool):
            joint = int(item)
            if not 1 <= joint < model.njoints:
                raise InputError(
                    f"actuated joint id must lie in [1, {model.njoints - 1}] (0 is the "
                    f"universe), got {joint}",
                    argument="actuated",
                    value=actuated,
                )
        else:
            raise InputError(
                f"actuated joints are names (str) or ids (int), got {item!r}",
                argument="actuated",
                value=actuated,
            )
        if joint in ids:
            raise InputError(
                f"actuated joint {model.names[joint]!r} is listed twice",
                argument="actuated",
                value=actuated,
            )
        kind = model.joints[joint].shortname()
        if kind not in EUCLIDEAN_JOINTS:
            raise InputError(
                f"actuated joint {model.names[joint]!r} is a {kind}; actuated joints must "
                f"have plain coordinates ({', '.join(sorted(EUCLIDEAN_JOINTS))})",
                argument="actuated",
                value=actuated,
            )
        ids.append(joint)
    return ids


def loop_constraints(model: pin.Model, constraint_models: Any) -> pin.StdVec_ConstraintModel:
    """The closures as new-style models in a StdVec (legacy ones converted)."""
    if not isinstance(constraint_models, Iterable) or isinstance(constraint_models, (str, bytes)):
        raise InputError(
            f"constraint_models must be an iterable of {CONSTRAINT_KINDS}, "
            f"got {type(constraint_models).__name__}",
            argument="constraint_models",
            value=constraint_models,
        )
    result = pin.StdVec_ConstraintModel()
    items = list(constraint_models)
    if not items:
        raise InputError(
            f"constraint_models is empty: give at least one loop closure ({CONSTRAINT_KINDS})",
            argument="constraint_models",
            value=constraint_models,
        )
    for k, item in enumerate(items):
        inner = item.extract() if isinstance(item, pin.ConstraintModel) else item
        if isinstance(inner, pin.RigidConstraintModel):
            inner = from_rigid(model, inner, k)
        elif not isinstance(
            inner, (pin.FrameAnchorConstraintModel, pin.PointAnchorConstraintModel)
        ):
            raise InputError(
                f"constraint_models[{k}] is a {type(inner).__name__}, not a loop closure; "
                f"allowed: {CONSTRAINT_KINDS}",
                argument="constraint_models",
                value=item,
            )
        for joint in (inner.joint1_id, inner.joint2_id):
            if not 0 <= joint < model.njoints:
                raise InputError(
                    f"constraint_models[{k}] ({inner.name!r}) refers to joint {joint}, but "
                    f"model {model.name!r} has joints 0..{model.njoints - 1}: it was built "
                    "for another model",
                    argument="constraint_models",
                    value=item,
                )
        if getattr(inner, "nv", model.nv) != model.nv:
            raise InputError(
                f"constraint_models[{k}] ({inner.name!r}) was built for a model with "
                f"nv = {inner.nv}, this model has nv = {model.nv}",
                argument="constraint_models",
                value=item,
            )
        wrapped = pin.ConstraintModel(inner)
        wrapped.name = inner.name
        result.append(wrapped)
    return result


def from_rigid(model: pin.Model, rigid: Any, k: int) -> Any:
    """A legacy RigidConstraintModel as the new kind with the same closed set."""
    desired = rigid.desired_contact_placement
    if not desired.isIdentity(1e-14):
        raise InputError(
            f"constraint_models[{k}] ({rigid.name!r}) has a desired_contact_placement other "
            "than the identity; fold it into joint1_placement (joint1_placement * desired)",
            argument="constraint_models",
            value=rigid,
        )
    args = (model, rigid.joint1_id, rigid.joint1_placement, rigid.joint2_id, rigid.joint2_placement)
    if rigid.type == pin.ContactType.CONTACT_6D:
        converted = pin.FrameAnchorConstraintModel(*args)
    elif rigid.type == pin.ContactType.CONTACT_3D:
        converted = pin.PointAnchorConstraintModel(*args)
    else:
        raise InputError(
            f"constraint_models[{k}] ({rigid.name!r}) is a RigidConstraintModel of type "
            f"{rigid.type}; allowed: CONTACT_6D, CONTACT_3D",
            argument="constraint_models",
            value=rigid,
        )
    converted.name = rigid.name
    return converted
