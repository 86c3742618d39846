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
        print(f"emulated bus on {emulator.port} at {config.baudrate} bit/s")
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
            print(f"start: theta = {np.degrees(start.theta).round(3)} deg, torque on")
            result = sync.move_to(demo)
            print(
                f"moved in {result.duration:.2f} s, {len(result.states)} cycles, "
                f"reached {result.reached}, final error {np.degrees(result.final_error):.3f} deg"
            )
            print("platform axes v_i (rows) read back along the way, against the FK:")
            for state in result.states[:: max(1, len(result.states) // 5)]:
                v = state.R @ robot.design.v0.T
                fk = spm.forward_kinematics(state.theta)
                deviation = np.max(np.abs(state.R - fk.R))
                print(
                    f"  theta {np.degrees(state.theta).round(2)} deg  v_1 {v[:, 0].round(4)}"
                    f"  |R - FK| {deviation:.1e}"
                )
            refused = sync.step(colliding)
            print(f"goal {np.degrees(colliding)} deg refused: {refused.verdict.reasons}")  # type: ignore[union-attr]
        print("torque off:", [emulator.item(i, "Torque Enable") == 0 for i in (1, 2, 3)])
        sent = [g.pulses for g in emulator.goal_writes() if g.servo_id == 3]
        highest = np.degrees((max(sent) - 2048) * 2 * np.pi / 4096)
        print(
            f"{len(sent)} goals reached each servo; the highest theta_3 sent was "
            f"{highest:.2f} deg, not the refused 220 deg"
        )


if __name__ == "__main__":
    main()
