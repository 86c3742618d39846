"""``spm servo ...``: the servo commands of the ``spm`` program.

Commands::

    spm servo emulate [--ids 1 2 3] [--baud BPS] [--firmware N] [--positions P1 P2 P3]
    spm servo status --port DEV [--config FILE] [--json]
    spm servo move (T1 T2 T3 | --rpy R P Y | --quaternion W X Y Z) --port DEV [--config FILE]
                   [--turns N] [--straight] [--speed DEG_S] [--json]
    spm servo stream FILE|- --port DEV [--config FILE] [--mode slide|stop] [--rate HZ] [--json]
    spm servo follow --port DEV [--config FILE] [--duration S] [--rate HZ] [--view] [--json]

``emulate`` prints the device path as the last word of its first line and serves the
emulated bus in the foreground until Ctrl-C. The others open the port named by
``--port`` (or the configuration file's), with the joints of ``--config`` (default:
the prototype's servos 1, 2, 3).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
from typing import Any

import numpy as np

from ..errors import InputError

# The hardware package is imported inside the functions: `import spm_pin.cli` loads no
# servo SDK (spm_pin.cli imports this module only inside build_parser).
from ._options import UsageError as _UsageError
from ._options import add_json_option as _add_json_option
from ._options import angle_deg as _angle_deg
from ._options import design_of as _design
from ._options import emit as _emit
from ._options import number as _number

__all__ = ["add_servo_parser"]


def _ids(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a servo id") from None
    if not 0 <= value <= 252:
        raise argparse.ArgumentTypeError(f"servo ids lie in 0..252, got {value}")
    return value


def _positive(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not math.isfinite(value) or value <= 0:
        raise argparse.ArgumentTypeError(f"{text!r} must be a positive number")
    return value


# -------------------------------------------------------------------------- emulate
def _run_emulate(args: argparse.Namespace) -> int:
    from ..hardware.emulated_bus import serve

    ids = tuple(args.ids)
    if len(set(ids)) != len(ids):
        raise InputError(f"--ids must be distinct, got {list(ids)}", argument="ids", value=ids)
    positions = None
    if args.positions is not None:
        if len(args.positions) != len(ids):
            raise InputError(
                f"--positions needs one value per id ({len(ids)}), got {len(args.positions)}",
                argument="positions",
                value=args.positions,
            )
        positions = dict(zip(ids, args.positions, strict=True))

    def announce(path: str) -> None:
        names = " ".join(str(i) for i in ids)
        print(
            f"emulating XM540-W150 servos {names} at {args.baud} bit/s (Ctrl-C stops) on {path}",
            flush=True,
        )

    stats = serve(
        ids,
        baudrate=args.baud,
        firmware=args.firmware,
        positions=positions,
        control_fd=args.control_fd,
        announce=announce,
    )
    if args.control_fd is None:
        print(
            f"stopped after {stats.get('packets', 0)} packets, {stats.get('replies', 0)} replies",
            flush=True,
        )
    return 0


# ------------------------------------------------------------------ status/move/follow
def _config(args: argparse.Namespace) -> Any:
    from ..hardware.config import HardwareConfig

    config = HardwareConfig() if args.config is None else HardwareConfig.load(args.config)
    if args.port is not None:
        config = config.replace(port=args.port)
    if getattr(args, "rate", None) is not None:
        config = config.replace(rate_hz=args.rate)
    return config


def _robot(args: argparse.Namespace) -> Any:
    from ..collision import build_robot

    return build_robot(_design(args))


def _bus(config: Any) -> Any:
    from ..hardware.driver import ServoBus

    return ServoBus(
        config.port,
        config.ids,
        baudrate=config.baudrate,
        latency_timer_ms=config.latency_timer_ms,
        retries=config.retries,
        fast_sync_read=config.fast_sync_read,
    )


def _state_record(state: Any) -> dict[str, Any]:
    from ..rotations import rpy_from_matrix

    record: dict[str, Any] = {
        "theta_deg": np.degrees(state.theta),
        "theta_dot_deg_s": np.degrees(state.theta_dot),
        "current_a": state.current,
        "goal_deg": np.degrees(state.goal),
        "moving": list(state.moving),
        "alert": list(state.alert),
        "reachable": state.reachable,
        "rpy_deg": np.degrees(rpy_from_matrix(state.R)) if state.reachable else None,
    }
    return record


def _run_status(args: argparse.Namespace) -> int:
    from ..hardware.control_table import OPERATING_MODES, HardwareErrorFlag
    from ..hardware.guard import SafetyGuard
    from ..hardware.joints import JointMap

    config = _config(args)
    robot = _robot(args)
    with _bus(config) as bus:
        infos = bus.identify()
        readings = bus.sync_read()
        servos = []
        for joint in config.joints:
            servo_id = joint.servo_id
            errors = bus.hardware_errors(servo_id)
            servos.append(
                {
                    "joint": joint.joint,
                    "id": servo_id,
                    "model": infos[servo_id].model_number,
                    "firmware": infos[servo_id].firmware,
                    "operating_mode": OPERATING_MODES.get(
                        bus.read(servo_id, "Operating Mode"), "unknown"
                    ),
                    "torque": bool(bus.read(servo_id, "Torque Enable")),
                    "hardware_errors": HardwareErrorFlag(errors).describe(),
                    "present_position_pulses": bus.read(servo_id, "Present Position"),
                    "input_voltage_v": bus.read(servo_id, "Present Input Voltage") * 0.1,
                    "temperature_c": bus.read(servo_id, "Present Temperature"),
                }
            )
    joints = JointMap(config.joints, coaxial=robot.design.is_coaxial)
    theta = joints.unwrap(readings.position)
    verdict = SafetyGuard(robot, config.safety).check(theta)
    record: dict[str, Any] = {
        "port": config.port,
        "baudrate": config.baudrate,
        "fast_sync_read": bool(bus.fast_sync_read),
        "theta_deg": np.degrees(theta),
        "reachable": verdict.reachable,
        "singularity_margin": verdict.singularity_margin,
        "safe": verdict.safe,
        "reasons": list(verdict.reasons),
        "servos": servos,
    }
    _emit(record, args.json)
    return 0


def _move_goal(args: argparse.Namespace) -> Any:
    """The goal of ``spm servo move``: input angles [rad] or a rotation matrix."""
    from ..rotations import matrix_from_quaternion, matrix_from_rpy

    args.theta = args.theta or None  # nargs="*": [] when left out
    given = sum(x is not None for x in (args.theta, args.rpy, args.quaternion))
    if args.theta is not None and len(args.theta) != 3:
        raise _UsageError(f"give three input angles T1 T2 T3 [deg], got {len(args.theta)}")
    if given != 1:
        raise _UsageError("give the goal once: T1 T2 T3 [deg], --rpy R P Y or --quaternion W X Y Z")
    if args.turns is not None and args.theta is not None:
        raise _UsageError("--turns applies to an orientation goal (--rpy or --quaternion)")
    if args.straight and args.theta is None:
        raise _UsageError(
            "--straight moves to input angles T1 T2 T3: orientation goals are planned"
        )
    if args.theta is not None:
        return np.radians(args.theta)
    if args.rpy is not None:
        return matrix_from_rpy(np.radians(args.rpy))
    return matrix_from_quaternion(np.asarray(args.quaternion, dtype=float))


def _run_move(args: argparse.Namespace) -> int:
    from ..hardware.orientation import move_planned
    from ..hardware.sync import ServoSync

    goal = _move_goal(args)
    config = _config(args)
    robot = _robot(args)
    if args.speed is not None:
        speed = min(math.radians(args.speed), config.safety.max_speed)
        config = config.replace(safety=dataclasses.replace(config.safety, max_speed=speed))
    planned: dict[str, Any] | None = None
    with _bus(config) as bus, ServoSync(bus, config, robot=robot) as sync:
        start = sync.start()
        if args.straight:
            result = sync.move_to(goal)
            target = goal
        else:
            path, result = move_planned(sync, goal, turns=args.turns or 0)
            target = path.goal
            planned = {
                "waypoints_deg": np.degrees(path.theta),
                "length_deg": path.length_deg,
                "straight_length_deg": path.straight_length_deg,
                "planning_time_ms": path.planning_time_ms,
            }
    record: dict[str, Any] = {
        "port": config.port,
        "from_deg": np.degrees(start.theta),
        "to_deg": np.degrees(target),
        "reached": result.reached,
        "final_error_deg": math.degrees(result.final_error),
        "duration_s": result.duration,
        "cycles": len(result.states),
        "max_lag_deg": math.degrees(result.max_lag),
        "late_cycles": result.late_cycles,
        "planned": planned,
        "events": list(sync.events),
        "final": _state_record(result.final),
        "torque": "off",
    }
    _emit(record, args.json)
    return 0 if result.reached else 1


def _targets(lines: Any, source: str) -> list[Any]:
    """Orientation targets from text lines ``roll pitch yaw`` [deg] (blank lines and
    ``#`` comments skipped; ``hold`` holds one period)."""
    from ..rotations import matrix_from_rpy

    targets: list[Any] = []
    for number, line in enumerate(lines, start=1):
        text = line.split("#", 1)[0].replace(",", " ").strip()
        if not text:
            continue
        if text == "hold":
            targets.append(None)
            continue
        try:
            values = [float(x) for x in text.split()]
        except ValueError:
            values = []
        if len(values) != 3 or not all(math.isfinite(v) for v in values):
            raise InputError(
                f"{source}, line {number}: expected 'roll pitch yaw' [deg] or 'hold', got "
                f"{line.strip()!r}",
                argument="file",
            )
        targets.append(matrix_from_rpy(np.radians(values)))
    return targets


def _run_stream(args: argparse.Namespace) -> int:
    import sys

    from ..hardware.orientation import OrientationStream
    from ..hardware.sync import ServoSync

    if args.file == "-":
        targets = _targets(sys.stdin, "standard input")
    else:
        with open(args.file, encoding="utf-8") as handle:
            targets = _targets(handle, args.file)
    config = _config(args)
    robot = _robot(args)
    with _bus(config) as bus, ServoSync(bus, config, robot=robot) as sync:
        start = sync.start()
        stream = OrientationStream(sync, mode=args.mode)
        steps = stream.run(targets)
        final = sync.read()
    reasons: dict[str, int] = {}
    for step in steps:
        if step.reason is not None:
            reasons[step.reason] = reasons.get(step.reason, 0) + 1
    record: dict[str, Any] = {
        "port": config.port,
        "targets": len(steps),
        "from_deg": np.degrees(start.theta),
        "counts": dict(stream.counts),
        "reasons": reasons,
        "final": _state_record(final),
        "events": list(sync.events),
        "torque": "off",
    }
    _emit(record, args.json)
    return 0


def _run_follow(args: argparse.Namespace) -> int:
    from ..hardware.sync import ServoSync

    config = _config(args)
    robot = _robot(args)
    viewer = None
    if args.view:
        from ..viz import Visualizer

        viewer = Visualizer(robot)
    duration = math.inf if args.duration is None else args.duration
    every = max(1, round(config.rate_hz / args.print_rate))
    count = 0

    def show(state: Any) -> None:
        nonlocal count
        count += 1
        if args.json or (count - 1) % every:
            return
        record = _state_record(state)
        theta = " ".join(f"{round(v, 3) + 0.0:9.3f}" for v in record["theta_deg"])
        rpy = (
            "unreachable"
            if record["rpy_deg"] is None
            else "rpy_deg " + " ".join(f"{round(v, 3) + 0.0:9.3f}" for v in record["rpy_deg"])
        )
        print(f"theta_deg {theta}   {rpy}", flush=True)

    states: list[Any] = []
    try:
        if viewer is not None:
            url = viewer.start()
            print(f"viewer: {url}", flush=True)
        with _bus(config) as bus, ServoSync(bus, config, robot=robot, viewer=viewer) as sync:
            sync.start(torque=False)
            try:
                states = sync.follow(duration, on_state=show, keep=1)
            except KeyboardInterrupt:
                states = [sync.state] if sync.state is not None else []
    finally:
        if viewer is not None:
            viewer.stop()
    record: dict[str, Any] = {
        "port": config.port,
        "samples": count,
        "rate_hz": config.rate_hz,
        "last": _state_record(states[-1]) if states else None,
    }
    if args.json:
        _emit(record, True)
    else:
        print(f"followed {count} samples at {config.rate_hz:g} Hz")
    return 0


def _add_bus_options(parser: argparse.ArgumentParser) -> None:
    parser.add_argument(
        "--port", metavar="DEV", help="serial device (default: the configuration's port)"
    )
    parser.add_argument(
        "--config",
        metavar="FILE",
        help="servo configuration TOML (default: ids 1, 2, 3, zero offsets 2048)",
    )
    from ..design import SPMDesign

    parser.add_argument(
        "--design",
        metavar="NAME|FILE",
        help=f"a preset ({', '.join(SPMDesign.preset_names())}) or a design TOML file "
        "(default: the prototype)",
    )
    _add_json_option(parser)


def add_servo_parser(commands: Any) -> None:
    """Add ``spm servo`` and its subcommands to the ``spm`` subparsers."""
    from ..hardware.control_table import BAUD_RATES, XM540_W150

    servo = commands.add_parser(
        "servo",
        help="XM540-W150 servos: status, move, follow, or an emulated bus",
        description="Drive the prototype's Dynamixel XM540-W150 servos (Protocol 2.0) with "
        "the model in the loop, or emulate a bus of them on a pseudo-terminal.",
    )
    actions = servo.add_subparsers(dest="servo_command", metavar="SUBCOMMAND")
    servo.set_defaults(run=_missing_subcommand)

    emulate = actions.add_parser(
        "emulate",
        help="emulate a bus of XM540-W150 servos on a pseudo-terminal",
        description="Serve emulated XM540-W150 servos (Protocol 2.0) on a new "
        "pseudo-terminal until Ctrl-C. The first line ends with the device path to pass "
        "as --port.",
    )
    emulate.add_argument(
        "--ids", type=_ids, nargs="+", default=[1, 2, 3], metavar="ID", help="servo ids"
    )
    emulate.add_argument(
        "--baud",
        type=int,
        default=BAUD_RATES[XM540_W150["Baud Rate"].default or 0],
        choices=sorted(set(BAUD_RATES.values()) - {4_500_000}),
        metavar="BPS",
        help="baud rate of every servo (default 57600, the factory default; open the "
        "port at the same rate)",
    )
    emulate.add_argument(
        "--firmware", type=int, default=46, help="firmware version (fast sync read from 45)"
    )
    emulate.add_argument(
        "--positions",
        type=int,
        nargs="+",
        metavar="PULSES",
        help="Present Position of each servo at power-up [pulses, 0..4095]",
    )
    emulate.add_argument("--control-fd", type=int, default=None, help=argparse.SUPPRESS)
    emulate.set_defaults(run=_run_emulate)

    status = actions.add_parser(
        "status",
        help="identify the servos and show their state and the model's",
        description="Ping and identify every servo, read its state and hardware errors, "
        "and show the joint angles, the platform orientation and the guard's verdict. "
        "Changes nothing.",
    )
    _add_bus_options(status)
    status.set_defaults(run=_run_status)

    move = actions.add_parser(
        "move",
        help="move to input angles T1 T2 T3 [deg] or an orientation, along a safe path",
        description="Configure the servos, hold where they are, then move to input angles "
        "T1 T2 T3 [deg] or an orientation (--rpy, --quaternion) along a path planned in "
        "the safe set (spm plan: safe along the whole motion, round unsafe parts of the "
        "workspace), after the guard approved every sample (reachable, singularity "
        "margin, no collision, joint/speed/acceleration limits). --straight keeps to the "
        "straight line in joint space and refuses when it is unsafe. Torque goes off at "
        "the end. Exit status 1 if the goal was not reached.",
    )
    move.add_argument(
        "theta", nargs="*", type=_angle_deg, metavar="T", help="input angles T1 T2 T3 [deg]"
    )
    move.add_argument(
        "--rpy",
        nargs=3,
        type=_number,
        metavar=("R", "P", "Y"),
        help="goal orientation: roll, pitch, yaw [deg] (as spm ik --rpy)",
    )
    move.add_argument(
        "--quaternion",
        nargs=4,
        type=_number,
        metavar=("W", "X", "Y", "Z"),
        help="goal orientation: quaternion, scalar first",
    )
    move.add_argument(
        "--turns",
        type=int,
        metavar="N",
        help="whole turns about the axis added to the shortest one (orientation goals)",
    )
    move.add_argument(
        "--straight",
        action="store_true",
        help="the straight line in joint space to T1 T2 T3, refused when unsafe",
    )
    move.add_argument(
        "--speed", type=_positive, metavar="DEG_S", help="joint speed [deg/s] (default: max)"
    )
    _add_bus_options(move)
    move.set_defaults(run=_run_move)

    follow = actions.add_parser(
        "follow",
        help="torque off: the model follows the robot moved by hand",
        description="Read the servos at the loop rate with torque off and print the joint "
        "angles and the platform orientation; with --view, show the robot in meshcat.",
    )
    follow.add_argument(
        "--duration", type=_positive, metavar="S", help="stop after S seconds (default: Ctrl-C)"
    )
    follow.add_argument("--rate", type=_positive, metavar="HZ", help="loop rate [Hz]")
    follow.add_argument(
        "--print-rate",
        type=_positive,
        default=10.0,
        metavar="HZ",
        help="text lines per second (default: 10)",
    )
    follow.add_argument("--view", action="store_true", help="show the robot in meshcat")
    _add_bus_options(follow)
    follow.set_defaults(run=_run_follow)

    stream = actions.add_parser(
        "stream",
        help="stream orientation targets (roll pitch yaw per line) to the servos",
        description="Send one orientation target per loop period, read from FILE (or - for "
        "standard input): 'roll pitch yaw' [deg] per line, or 'hold'. Each target is "
        "solved, rate-limited and checked as a continuous motion in the safe set, then by "
        "the guard; an unsafe target never reaches the bus: with --mode slide (default) "
        "the goal slides along the boundary of the safe set towards it, with --mode stop "
        "it holds. Torque "
        "goes off at the end; the summary counts what each target did and why.",
    )
    stream.add_argument("file", metavar="FILE", help="targets, one per line ('-': stdin)")
    stream.add_argument(
        "--mode",
        choices=("slide", "stop"),
        default="slide",
        help="what an unsafe target does: slide (along the boundary of the safe set, as "
        "near it as is safe) or stop (hold the last safe goal)",
    )
    stream.add_argument("--rate", type=_positive, metavar="HZ", help="loop rate [Hz]")
    _add_bus_options(stream)
    stream.set_defaults(run=_run_stream)


def _missing_subcommand(args: argparse.Namespace) -> int:
    raise _UsageError("spm servo needs a subcommand: emulate, status, move, stream or follow")
