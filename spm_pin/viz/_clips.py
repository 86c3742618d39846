"""meshcat animation clips (three.js keyframe tracks) of the SPM's scene nodes."""

from __future__ import annotations

from typing import Any

import numpy as np
import numpy.typing as npt
import pinocchio as pin

FloatArray = npt.NDArray[np.float64]


def clip(path: str, tracks: list[dict[str, Any]]) -> dict[str, Any]:
    """One node's part of a meshcat animation (a three.js clip, times in seconds)."""
    return {"path": path, "clip": {"fps": 1.0, "name": "default", "tracks": tracks}}


def keys(times: FloatArray, values: list[Any]) -> list[dict[str, Any]]:
    """Keyframes: one ``{"time", "value"}`` per time [s]."""
    return [{"time": float(t), "value": v} for t, v in zip(times, values, strict=True)]


def transform_clip(path: str, times: FloatArray, matrices: list[FloatArray]) -> dict[str, Any]:
    """Position and orientation keys of a node from its transforms (4, 4) at ``times``."""
    quaternions = np.array([pin.Quaternion(m[:3, :3]).coeffs() for m in matrices])  # x, y, z, w
    for k in range(1, len(quaternions)):  # the short way round between keys
        if quaternions[k] @ quaternions[k - 1] < 0:
            quaternions[k] = -quaternions[k]
    positions = [m[:3, 3].tolist() for m in matrices]
    return clip(
        path,
        [
            {"name": ".position", "type": "vector3", "keys": keys(times, positions)},
            {
                "name": ".quaternion",
                "type": "quaternion",
                "keys": keys(times, quaternions.tolist()),
            },
        ],
    )


def visibility_clip(path: str, times: FloatArray, visible: list[bool]) -> dict[str, Any]:
    """Keys that show or hide a node (three.js switches booleans, never blends them)."""
    return clip(path, [{"name": ".visible", "type": "boolean", "keys": keys(times, visible)}])
