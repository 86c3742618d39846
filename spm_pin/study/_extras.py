"""The study's optional dependencies (MuJoCo, matplotlib, meshcat): whether each
imports, and what is skipped without it and how to install it."""

from __future__ import annotations

import dataclasses
import importlib

from .._records import Record

__all__ = ["INSTALL_DEMO", "OPTIONAL_DEPENDENCIES", "Skipped", "install", "missing"]

#: The command that installs every optional dependency of the demo.
INSTALL_DEMO = 'pip install "spm-pin[demo]"'
#: The demo's optional dependencies -> the extra that brings each alone (MuJoCo for
#: the cross-check, matplotlib for the plots, meshcat for the scenes).
OPTIONAL_DEPENDENCIES: dict[str, str] = {"mujoco": "sim", "matplotlib": "plot", "meshcat": "viz"}
#: Modules imported to check that a dependency works (spm_pin.viz needs meshcat).
_PROBES: dict[str, tuple[str, ...]] = {
    "mujoco": ("mujoco",),
    "matplotlib": ("matplotlib", "matplotlib.backends.backend_agg"),
    "meshcat": ("spm_pin.viz", "meshcat"),
}


@dataclasses.dataclass(frozen=True)
class Skipped:
    """A part of the demo left out because an optional dependency is missing.

    Attributes:
        part: What was left out, e.g. ``"MuJoCo cross-check"``.
        missing: The missing Python package.
        install: The command that brings it.
    """

    part: str
    missing: str
    install: str

    def as_dict(self) -> Record:
        """Plain data (JSON)."""
        return dataclasses.asdict(self)


def install(module: str) -> str:
    extra = OPTIONAL_DEPENDENCIES[module]
    return f'{INSTALL_DEMO} (or "spm-pin[{extra}]" for {module} alone)'


def missing(module: str, part: str) -> Skipped | None:
    """None when ``module`` imports; otherwise what is skipped without it."""
    try:
        for name in _PROBES[module]:
            importlib.import_module(name)
    except ImportError:
        return Skipped(part=part, missing=module, install=install(module))
    return None
