"""The checked link pairs and the settings of a collision check: which link pairs are
checked and which share a joint, the probe and plan-cache defaults, coal's EPA
iteration counts and the check of a safety margin."""

from __future__ import annotations

import math

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..model.geometry import LINK_NAMES

__all__ = [
    "ADJACENT_PAIRS",
    "DEFAULT_PROBES",
    "LINK_PAIRS",
    "PLAN_CACHE",
    "PROBE_MIN_SHARE",
    "PROBE_SAMPLES",
    "LinkPair",
]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]
BoolArray = npt.NDArray[np.bool_]

#: A pair of link names, in the order of :data:`~spm_pin.model.geometry.LINK_NAMES`.
LinkPair = tuple[str, str]

#: Link pairs that share a joint (never checked): u_i, w_i and v_i.
ADJACENT_PAIRS: tuple[LinkPair, ...] = tuple(
    pair
    for leg in (1, 2, 3)
    for pair in (
        ("base", f"proximal_{leg}"),
        (f"proximal_{leg}", f"distal_{leg}"),
        (f"distal_{leg}", "platform"),
    )
)

#: The 19 checked link pairs, in the order of ``LINK_NAMES`` (first name first).
LINK_PAIRS: tuple[LinkPair, ...] = tuple(
    (a, b)
    for i, a in enumerate(LINK_NAMES)
    for b in LINK_NAMES[i + 1 :]
    if (a, b) not in ADJACENT_PAIRS
)

#: Links whose placement follows from theta alone (no loop closure needed).
_THETA_LINKS = frozenset({"base", "proximal_1", "proximal_2", "proximal_3"})

#: Default largest number of probe piece pairs tried per link pair before its BVH.
DEFAULT_PROBES = 4
#: Seeded inputs sampled to choose the probes.
PROBE_SAMPLES = 256
#: A probe is kept only if it catches a collision of its link pair, missed by the
#: earlier probes, in at least this fraction of the samples.
PROBE_MIN_SHARE = 0.02
#: Largest number of margins whose check set-up (tables and engine) is kept (the
#: oldest first out).
PLAN_CACHE = 24

#: EPA iterations in collision requests: the contact itself comes from GJK; EPA
#: would only refine a penetration depth that is not used.
_EPA_ITERATIONS = 0
#: EPA iterations where a penetration depth certifies a collision (tables only).
_EPA_CERTIFY_ITERATIONS = 128


def _check_margin(margin: object) -> float:
    if (
        isinstance(margin, bool)
        or not isinstance(margin, (int, float, np.integer, np.floating))
        or not math.isfinite(float(margin))
        or float(margin) < 0.0
    ):
        raise InputError(
            f"margin must be a finite distance >= 0 [m], got {margin!r}",
            argument="margin",
            value=margin,
        )
    return float(margin) + 0.0
