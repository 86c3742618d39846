"""Calibrate a simulated prototype: plan poses, take noisy readings, identify the model."""

from __future__ import annotations

import math

from spm_pin import calibration as cal


def main() -> None:
    plan = cal.plan_poses(40, candidates=1000, seed=1)
    print(
        f"planned {len(plan.theta)} poses: observability index "
        f"{plan.observability.index:.3f} (random poses {plan.random_index:.3f})"
    )
    synthetic = cal.synthetic_readings(plan.theta, seed=2)  # 0.088 deg steps, 0.5 deg noise
    result = cal.calibrate(synthetic.readings)
    print(result.report())
    exact = synthetic.truth.vector(result.start)
    print("parameter   truth [deg]  estimate [deg]  error / std")
    for estimate in result.estimates:
        true_value = exact[cal.PARAMETER_NAMES.index(estimate.name)]
        print(
            f"{estimate.name:10} {math.degrees(true_value):12.4f} "
            f"{math.degrees(estimate.value):15.4f} "
            f"{(estimate.value - true_value) / estimate.std:12.2f}"
        )


if __name__ == "__main__":
    main()
