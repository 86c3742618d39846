"""Train PPO on spm_pin/Orient-v0, test it on held-out goals, drive the emulated servos with it.

Needs the ``rl-train`` extra (stable-baselines3 and PyTorch): ``pip install
"spm-pin[rl-train]"``; without stable-baselines3 it says so and stops. Steps:

1. PPO (stable-baselines3, MLP policy) on ``--envs`` copies of ``spm_pin/Orient-v0``
   (its ``make_vec_env``: Gymnasium environments, each in a ``Monitor``) for
   ``--timesteps`` steps; the episode returns go into a learning-curve PNG.
2. The trained policy (deterministic) and a random policy on held-out episodes
   (seeds from ``HELD_OUT``, far from the training seeds), with
   :func:`spm_pin.envs.evaluate_policy`, ``safety="terminate"``.
3. The policy on the emulated XM540 servo bus, one control period per cycle: the
   observation is built from the servos' readings (the platform rotation of the read
   inputs, sin and cos of the inputs, their speeds), the policy's speeds become the
   next goal positions, and :class:`~spm_pin.hardware.ServoSync` sends only what the
   safety guard accepts (the guard's limits are the environment's).

Run: ``python examples/train_ppo.py`` (1,500,000 steps by default: about two minutes per
100,000 steps on one core; docs/tutorial-learn.md has the figures of one run: 62 % of
held-out goals reached after 1.5 million steps).
"""

from __future__ import annotations

import argparse
import math
import sys
import time
from pathlib import Path

import numpy as np

#: First seed of the held-out evaluation episodes (training seeds stay below it).
HELD_OUT = 10_000


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--timesteps", type=int, default=1_500_000, help="PPO training steps")
    parser.add_argument("--envs", type=int, default=8, help="environments stepped together")
    parser.add_argument("--episodes", type=int, default=50, help="held-out evaluation episodes")
    parser.add_argument("--seed", type=int, default=0, help="seed of training")
    parser.add_argument(
        "--out", type=Path, default=Path("ppo_orient"), help="folder for the model and the PNG"
    )
    parser.add_argument(
        "--hardware-steps", type=int, default=250, help="control periods on the emulated bus"
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    try:
        from stable_baselines3 import PPO
        from stable_baselines3.common.callbacks import BaseCallback
        from stable_baselines3.common.env_util import make_vec_env
    except ImportError:
        print(
            'status: skipped  (stable-baselines3 is not installed: pip install "spm-pin[rl-train]")'
        )
        return 0
    import gymnasium

    from spm_pin.envs import evaluate_policy  # the import registers spm_pin/Orient-v0

    class Curve(BaseCallback):  # type: ignore[misc]
        """Collects (timestep, episode return, success) from the Monitor wrappers."""

        def __init__(self) -> None:
            super().__init__()
            self.points: list[tuple[int, float, bool]] = []

        def _on_step(self) -> bool:
            for info in self.locals.get("infos", ()):
                if "episode" in info:
                    success = bool(info.get("success", False))
                    self.points.append((self.num_timesteps, float(info["episode"]["r"]), success))
            return True

    args.out.mkdir(parents=True, exist_ok=True)
    train_env = make_vec_env("spm_pin/Orient-v0", n_envs=args.envs, seed=args.seed)
    model = PPO("MlpPolicy", train_env, seed=args.seed, verbose=0)
    curve = Curve()
    start = time.perf_counter()
    model.learn(total_timesteps=args.timesteps, callback=curve)
    train_s = time.perf_counter() - start
    train_env.close()
    model.save(args.out / "ppo_orient")
    print(f"timesteps: {args.timesteps}")
    print(f"training_s: {train_s:.1f}")
    print(f"episodes_seen: {len(curve.points)}")
    print(f"learning_curve_png: {save_curve(curve.points, args.out / 'learning_curve.png')}")

    def trained(observation: np.ndarray) -> np.ndarray:
        action, _ = model.predict(observation, deterministic=True)
        return np.asarray(action, dtype=np.float32)

    rng = np.random.default_rng(args.seed)

    def random_policy(observation: np.ndarray) -> np.ndarray:
        return rng.uniform(-1.0, 1.0, 3).astype(np.float32)

    test_env = gymnasium.make("spm_pin/Orient-v0", safety="terminate")
    for name, policy in (("ppo", trained), ("random", random_policy)):
        result = evaluate_policy(test_env, policy, episodes=args.episodes, seed=HELD_OUT)
        print(
            f"{name}_success_rate: {result['success_rate']:.3f}  "
            f"({result['successes']} of {result['episodes']} held-out episodes)"
        )
        print(f"{name}_unsafe_stops: {result['unsafe_stops']}")
        print(f"{name}_mean_final_error_deg: {result['mean_final_error_deg']:.3f}")
    settings = test_env.unwrapped.settings
    test_env.reset(seed=HELD_OUT + args.episodes)  # one more held-out goal, for the servos
    goal_theta = test_env.unwrapped.core.goal_theta[0].copy()
    test_env.close()
    drive_emulated_servos(trained, settings, goal_theta, args.hardware_steps)
    return 0


def save_curve(points: list[tuple[int, float, bool]], path: Path) -> Path:
    """The episode returns against the training steps (and a moving mean) as a PNG."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6.0, 3.5), dpi=100)
    if points:
        steps = np.array([p[0] for p in points])
        returns = np.array([p[1] for p in points])
        window = max(1, len(returns) // 50)
        mean = np.convolve(returns, np.ones(window) / window, mode="valid")
        ax.plot(steps, returns, ".", markersize=2, alpha=0.3, label="episode return")
        ax.plot(steps[window - 1 :], mean, label=f"mean of {window}")
        ax.legend(loc="lower right")
    ax.set_xlabel("training steps")
    ax.set_ylabel("return")
    ax.set_title("PPO on spm_pin/Orient-v0")
    fig.tight_layout()
    fig.savefig(path)
    plt.close(fig)
    return path


def observation_of(
    R: np.ndarray, goal: np.ndarray, theta: np.ndarray, speed: np.ndarray, max_speed: float
) -> np.ndarray:
    """The environment's 21 observed numbers from a state read off the servos."""
    parts = [
        R[:, 0],
        R[:, 1],
        goal[:, 0],
        goal[:, 1],
        np.sin(theta),
        np.cos(theta),
        np.clip(speed / max_speed, -1.0, 1.0),
    ]
    return np.concatenate(parts).astype(np.float32)


def drive_emulated_servos(policy, settings, goal_theta: np.ndarray, steps: int) -> None:
    """Run ``policy`` on emulated servos through ServoSync and its guard (see the module)."""
    import spm_pin as spm
    from spm_pin.envs import geodesic_angle
    from spm_pin.hardware import EmulatedBus, HardwareConfig, ServoBus, ServoSettings, ServoSync
    from spm_pin.hardware.emulated_bus import LATENCY_TIMER_MS

    robot = spm.build_robot(settings.the_design)
    limits = settings.the_limits
    period = settings.control_period
    goal = spm.forward_kinematics(goal_theta, settings.the_design).R
    dv = limits.max_acceleration * period
    with EmulatedBus(ids=(1, 2, 3)) as emulator:
        config = HardwareConfig(
            port=emulator.port,
            baudrate=emulator.baudrate,
            latency_timer_ms=LATENCY_TIMER_MS,
            rate_hz=1.0 / period,
            servo=ServoSettings(
                profile_velocity=math.radians(200), profile_acceleration=math.radians(2000)
            ),
            safety=limits,
        )
        with (
            ServoBus(
                config.port,
                config.ids,
                baudrate=config.baudrate,
                latency_timer_ms=config.latency_timer_ms,
            ) as servos,
            ServoSync(servos, config, robot=robot) as sync,
        ):
            state = sync.start()
            command = np.zeros(3)
            refused = hold = cycles = 0
            error = float(geodesic_angle(state.R, goal))
            next_time = time.perf_counter()
            for _ in range(steps):
                obs = observation_of(state.R, goal, state.theta, state.theta_dot, limits.max_speed)
                action = np.clip(np.asarray(policy(obs), dtype=float), -1.0, 1.0)
                command = np.clip(action * limits.max_speed, command - dv, command + dv)
                next_time += period
                time.sleep(max(0.0, next_time - time.perf_counter()))
                result = sync.step(sync.goal + command * period)
                cycles += 1
                if result.refused:
                    refused += 1
                    command = np.zeros(3)  # the servos hold the last safe goal
                if result.state is not None and result.state.reachable:
                    state = result.state
                error = float(geodesic_angle(state.R, goal))
                hold = hold + 1 if error <= settings.tolerance else 0
                if hold >= settings.hold_steps:
                    break
    print(f"hardware_goal_theta_deg: {' '.join(f'{x:.3f}' for x in np.degrees(goal_theta))}")
    print(f"hardware_cycles: {cycles}")
    print(f"hardware_refused_by_guard: {refused}")
    print(f"hardware_final_error_deg: {math.degrees(error):.3f}")
    print(f"hardware_goal_held: {hold >= settings.hold_steps}")


if __name__ == "__main__":
    sys.exit(main())
