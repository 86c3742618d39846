"""Drive the prototype's Dynamixel XM540-W150 servos with the model in the loop.

Needs the ``hardware`` extra for the driver (``pip install "spm-pin[hardware]"``,
which brings dynamixel-sdk); ``import spm_pin`` never imports this package, and this
package imports the SDK only when a port is opened.

* :mod:`.control_table`: the XM540-W150 control table and unit conversions.
* :mod:`.protocol`: Protocol 2.0 packets (CRC-16, byte stuffing).
* :class:`ServoBus`: the driver on dynamixel-sdk (ping, identify, configure, torque,
  sync read and write, hardware errors, reboot, bounded retries).
* :class:`EmulatedBus`: emulated XM540-W150 servos on a real pseudo-terminal, in a
  process of its own, with fault injection (``spm servo emulate``).
* :class:`HardwareConfig`: joints (servo id, direction, gear ratio, zero offset),
  servo settings and safety limits, in TOML.
* :class:`SafetyGuard`: reachability, singularity margin, collisions, joint, speed
  and acceleration limits of every goal.
* :class:`ServoSync`: the read -> model -> guard -> write loop.
"""

from __future__ import annotations

from .config import HardwareConfig, JointConfig, RebootPolicy, SafetyLimits
from .control_table import (
    MODEL_NUMBER,
    PULSES_PER_TURN,
    XM540_W150,
    ControlItem,
    ControlTable,
    HardwareErrorFlag,
)
from .driver import ServoBus, ServoInfo, ServoReadings, ServoSettings
from .emulated_bus import EmulatedBus, GoalWrite
from .emulator import LogEntry, ServoEmulator
from .guard import PathVerdict, SafetyGuard, Verdict
from .joints import JointMap
from .sync import MoveResult, ServoSync, StepResult, SyncState, Viewer, plan_linear

__all__ = [
    "MODEL_NUMBER",
    "PULSES_PER_TURN",
    "XM540_W150",
    "ControlItem",
    "ControlTable",
    "EmulatedBus",
    "GoalWrite",
    "HardwareConfig",
    "HardwareErrorFlag",
    "JointConfig",
    "JointMap",
    "LogEntry",
    "MoveResult",
    "PathVerdict",
    "RebootPolicy",
    "SafetyGuard",
    "SafetyLimits",
    "ServoBus",
    "ServoEmulator",
    "ServoInfo",
    "ServoReadings",
    "ServoSettings",
    "ServoSync",
    "StepResult",
    "SyncState",
    "Verdict",
    "Viewer",
    "plan_linear",
]
