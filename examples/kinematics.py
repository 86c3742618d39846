"""Forward and inverse kinematics of the coaxial SPM prototype at the study's input."""

from __future__ import annotations

import numpy as np

import spm_pin as spm


def numbers(values: np.ndarray) -> str:
    """``values`` as space-separated numbers, to 12 significant digits."""
    return " ".join(f"{x:.12g}" for x in np.ravel(values))


def main() -> None:
    design = spm.SPMDesign.prototype()
    theta = np.radians([60.0, 90.0, 120.0])
    modes = spm.forward_kinematics_all(theta, design)
    print(f"design: {design.summary()}")
    print(f"theta_deg: {numbers(np.degrees(theta))}")
    print(f"modes: {int(modes.count)}  (real assembly modes)")
    for k in range(int(modes.count)):
        mark = " home" if modes.home[k] else ""
        print(f"mode_{k + 1}: {modes.labels[k]} residual {modes.residual[k]:.1e}{mark}")
    fk = spm.forward_kinematics(theta, design)  # the home mode
    for i, v in enumerate(fk.v, start=1):
        print(f"v_{i}: {numbers(v)}  (platform axis, home mode)")
    back = spm.inverse_kinematics(fk.R, design)
    print(f"ik_theta_deg: {numbers(np.degrees(back.theta))}")
    jac = spm.jacobian(theta, design)
    print(f"dexterity: {float(jac.dexterity):.6f}")
    print(f"singularity_margin: {float(jac.singularity_margin):.6f}")


if __name__ == "__main__":
    main()
