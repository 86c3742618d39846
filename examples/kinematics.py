"""Forward and inverse kinematics of the coaxial SPM prototype at the study's input."""

from __future__ import annotations

import numpy as np

import spm_pin as spm


def main() -> None:
    design = spm.SPMDesign.prototype()
    theta = np.radians([60.0, 90.0, 120.0])
    modes = spm.forward_kinematics_all(theta, design)
    print(f"{design.summary()}")
    print(f"theta = {np.degrees(theta)} deg: {int(modes.count)} real assembly modes")
    for k in range(int(modes.count)):
        mark = "  <- home" if modes.home[k] else ""
        print(f"  {modes.labels[k]}  residual {modes.residual[k]:.1e}{mark}")
    fk = spm.forward_kinematics(theta, design)
    print("home mode, platform axes v_i (rows):")
    print(np.array2string(fk.v, precision=6, suppress_small=True))
    back = spm.inverse_kinematics(fk.R, design)
    print(f"inverse kinematics gives back theta = {np.degrees(back.theta).round(9)} deg")
    jac = spm.jacobian(theta, design)
    print(
        f"dexterity {float(jac.dexterity):.4f}, singularity margin "
        f"{float(jac.singularity_margin):.4f}"
    )


if __name__ == "__main__":
    main()
