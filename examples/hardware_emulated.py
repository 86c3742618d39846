"""Move emulated XM540-W150 servos from home to the study's input with the model following."""

from __future__ import annotations

import numpy as np

import spm_pin as spm
from spm_pin.hardware import (
    EmulatedBus,
    HardwareConfig,
    SafetyLimits,
    ServoBus,
    ServoSettings,
    ServoSync,
)
from spm_pin.hardware.emulated_bus import LATENCY_TIMER_MS


def main() -> None:
    robot = spm.build_robot()
    demo = np.radians([60.0, 90.0, 120.0])  # the study's demonstration input
    colliding = np.radians([60.0, 90.0, 220.0])  # the study's colliding input
    # Factory-fresh servos answer at 57600 bit/s; the controller opens the port at the
    # same rate, and allows for the emulator's latency on a busy machine.
    with EmulatedBus(ids=(1, 2, 3)) as emulator:
        config = HardwareConfig(
            port=emulator.port,
            baudrate=emulator.baudrate,
            latency_timer_ms=LATENCY_TIMER_MS,
            servo=ServoSettings(
                profile_velocity=np.radians(200), profile_acceleration=np.radians(2000)
            ),
            safety=SafetyLimits(max_speed=np.radians(150), max_acceleration=np.radians(900)),
        )
        print(f"port: {emulator.port}  (emulated bus)")
        print(f"baudrate: {config.baudrate}")
        with (
            ServoBus(
                config.port,
                config.ids,
                baudrate=config.baudrate,
                latency_timer_ms=config.latency_timer_ms,
            ) as servos,
            ServoSync(servos, config, robot=robot) as sync,
        ):
            start = sync.start()
            print(f"start_theta_deg: {numbers(np.degrees(start.theta))}  (torque on)")
            result = sync.move_to(demo)
            print(f"goal_deg: {numbers(np.degrees(demo))}")
            print(f"duration_s: {result.duration:.2f}")
            print(f"cycles: {len(result.states)}")
            print(f"reached: {result.reached}")
            print(f"final_error_deg: {np.degrees(result.final_error):.4f}")
            print(f"present_position_pulses: {numbers(present(emulator))}  (read by the emulator)")
            # The platform axes read back along the way, against the FK of the read inputs.
            for k, state in enumerate(result.states[:: max(1, len(result.states) // 5)]):
                v = state.R @ robot.design.v0.T
                fk = spm.forward_kinematics(state.theta)
                print(
                    f"sample_{k}: theta_deg {numbers(np.degrees(state.theta))}; "
                    f"v_1 {numbers(v[:, 0])}; R_vs_fk {np.max(np.abs(state.R - fk.R)):.1e}"
                )
            refused = sync.step(colliding)
            print(f"refused_goal_deg: {numbers(np.degrees(colliding))}")
            print(f"refused_because: {'; '.join(refused.verdict.reasons)}")  # type: ignore[union-attr]
        off = [emulator.item(i, "Torque Enable") == 0 for i in (1, 2, 3)]
        print(f"torque_off: {' '.join(map(str, off))}")
        sent = [g.pulses for g in emulator.goal_writes() if g.servo_id == 3]
        print(f"goals_sent_to_servo_3: {len(sent)}")
        print(f"highest_goal_3_pulses: {max(sent)}  (not the refused 220 deg)")


def present(emulator: EmulatedBus) -> list[int]:
    """The Present Position [pulses] of servos 1, 2, 3."""
    return [emulator.item(i, "Present Position") for i in (1, 2, 3)]


def numbers(values: np.ndarray | list[int]) -> str:
    """``values`` as space-separated numbers, to 12 significant digits."""
    return " ".join(f"{x:.12g}" for x in np.ravel(values))


if __name__ == "__main__":
    main()
