"""Calibrate a simulated prototype: plan poses, take noisy readings, identify the model."""

from __future__ import annotations

import math

from spm_pin import calibration as cal

#: The estimates are expected within this many standard deviations of the truth.
WITHIN_STD = 3.0


def main() -> None:
    plan = cal.plan_poses(40, candidates=1000, seed=1)
    print(f"poses: {len(plan.theta)}")
    print(f"observability_index: {plan.observability.index:.4f}")
    print(f"random_poses_index: {plan.random_index:.4f}")
    synthetic = cal.synthetic_readings(plan.theta, seed=2)  # 0.088 deg steps, 0.5 deg noise
    result = cal.calibrate(synthetic.readings)
    print(result.report())
    exact = synthetic.truth.vector(result.start)
    print(f"estimates against the truth (expected within {WITHIN_STD:g} std), in deg:")
    worst = 0.0
    for estimate in result.estimates:
        true_value = exact[cal.PARAMETER_NAMES.index(estimate.name)]
        worst = max(worst, abs(estimate.value - true_value) / estimate.std)
        print(
            f"{estimate.name}: truth {math.degrees(true_value):.4f} "
            f"estimate {math.degrees(estimate.value):.4f} std {math.degrees(estimate.std):.4f}"
        )
    print(f"worst_error_in_std: {worst:.2f}")


if __name__ == "__main__":
    main()
