"""Shared test data: the designs under test, seeded samplers and hypothesis settings.

Test modules import the helpers below with ``from conftest import ...`` (pytest puts
this directory on ``sys.path``); fixtures are used as usual.
"""

from __future__ import annotations

import math
import os
from collections.abc import Callable
from typing import NoReturn

import numpy as np
import pytest
from hypothesis import HealthCheck, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

import spm_pin as spm

# Deterministic property tests (every run draws the same examples), no per-example
# deadline: the examples are vectorised batches whose run time varies with the batch.
settings.register_profile(
    "spm",
    deadline=None,
    derandomize=True,
    suppress_health_check=[HealthCheck.too_slow],
)
settings.load_profile("spm")


def general_design() -> spm.SPMDesign:
    """A general (non-coaxial) 3-RRR SPM built with the constructor.

    Base axes tilted by different amounts from -z and not at the leg azimuths, so they
    are neither coaxial nor mutually orthogonal; unequal leg azimuths eta; alpha1,
    alpha2 and beta all different.
    """
    eta = tuple(math.radians(e) for e in (0.0, 115.0, 250.0))
    tilt = [math.radians(g) for g in (30.0, 42.0, 36.0)]
    azimuth = [e + math.radians(s) for e, s in zip(eta, (5.0, -8.0, 3.0), strict=True)]
    axes = tuple(
        (math.sin(g) * math.cos(a), math.sin(g) * math.sin(a), -math.cos(g))
        for g, a in zip(tilt, azimuth, strict=True)
    )
    return spm.SPMDesign(
        alpha1=math.radians(60.0),
        alpha2=math.radians(80.0),
        beta=math.radians(70.0),
        eta=eta,
        base_axes=axes,
        name="general",
    )


#: Every design the kinematics tests run on, by name.
DESIGNS: dict[str, Callable[[], spm.SPMDesign]] = {
    "prototype": spm.SPMDesign.prototype,
    "agile_eye": spm.SPMDesign.agile_eye,
    "coaxial_50_75_100": lambda: spm.SPMDesign.coaxial(50.0, 75.0, 100.0),
    "general": general_design,
}
DESIGN_NAMES = tuple(DESIGNS)
COAXIAL_NAMES = ("prototype", "coaxial_50_75_100")

# Hypothesis strategies shared by the property tests.
#: Seeds of the numpy generators that draw each example's batch.
seeds = st.integers(min_value=0, max_value=2**32 - 1)
#: The designs under test, by name (see ``get_design``).
design_names = st.sampled_from(DESIGN_NAMES)

_CACHE: dict[str, spm.SPMDesign] = {}


def get_design(name: str) -> spm.SPMDesign:
    """The design called ``name`` (built once)."""
    if name not in _CACHE:
        _CACHE[name] = DESIGNS[name]()
    return _CACHE[name]


@pytest.fixture(scope="session", params=DESIGN_NAMES)
def design(request: pytest.FixtureRequest) -> spm.SPMDesign:
    """Each design under test in turn."""
    return get_design(request.param)


@pytest.fixture(scope="session")
def prototype() -> spm.SPMDesign:
    return get_design("prototype")


#: Level of the environments' test cover (root cells and their halves).
ENV_COVER_LEVEL = 1


@pytest.fixture(scope="session")
def env_cover_path(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A saved cover of the prototype's safe set with the environments' default
    limits, filled to :data:`ENV_COVER_LEVEL` (made once per session)."""
    from spm_pin.envs import OrientSettings
    from spm_pin.planning import SafeCover, safe_set_of

    settings = OrientSettings()
    cover = SafeCover(safe_set_of(settings.the_design, settings.plan_settings))
    cover.fill(max_level=ENV_COVER_LEVEL)
    path = tmp_path_factory.mktemp("env-cover") / "cover.npz"
    cover.save(path)
    return str(path)


# --------------------------------------------------------------------------- helpers
def wrap(angle: np.ndarray) -> np.ndarray:
    """Angles into [-pi, pi)."""
    return np.mod(np.asarray(angle) + np.pi, 2 * np.pi) - np.pi


def rot_z(angle: float) -> np.ndarray:
    """Rotation about +z by ``angle`` [rad], built here, not by the library."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def random_rotations(rng: np.random.Generator, n: int) -> np.ndarray:
    """n uniformly distributed rotation matrices (scipy), shape (n, 3, 3)."""
    return Rotation.random(n, random_state=rng).as_matrix()


def random_inputs(rng: np.random.Generator, n: int) -> np.ndarray:
    """n input vectors uniform in [-pi, pi)^3, shape (n, 3)."""
    return rng.uniform(-np.pi, np.pi, size=(n, 3))


def reachable_inputs(design: spm.SPMDesign, rng: np.random.Generator, n: int) -> np.ndarray:
    """n random inputs that have a home-mode assembly (rejection sampling), (n, 3)."""
    found: list[np.ndarray] = []
    count = 0
    while count < n:
        theta = random_inputs(rng, 4 * n)
        theta = theta[spm.forward_kinematics(theta, design).reachable]
        found.append(theta)
        count += theta.shape[0]
    return np.concatenate(found)[:n]


def proximal_axes(design: spm.SPMDesign, theta: np.ndarray) -> np.ndarray:
    """w_i(theta_i): w_i0 turned about u_i by theta_i (Rodrigues), rows, (..., 3, 3)."""
    theta = np.asarray(theta, dtype=float)
    u, w0 = design.u, design.w0
    c, s = np.cos(theta)[..., None], np.sin(theta)[..., None]
    along = np.sum(u * w0, axis=-1, keepdims=True) * u
    return along + c * (w0 - along) + s * np.cross(u, w0)


def platform_axes(design: spm.SPMDesign, R: np.ndarray) -> np.ndarray:
    """v_i = R v_i0 as rows, (..., 3, 3)."""
    return np.einsum("...jk,ik->...ij", np.asarray(R), design.v0)


def loop_residual(design: spm.SPMDesign, theta: np.ndarray, R: np.ndarray) -> np.ndarray:
    """max_i |w_i . v_i - cos a2|, (...)."""
    w = proximal_axes(design, theta)
    v = platform_axes(design, R)
    return np.abs(np.sum(w * v, axis=-1) - math.cos(design.alpha2)).max(axis=-1)


def leg_signs(design: spm.SPMDesign, theta: np.ndarray, R: np.ndarray) -> tuple[np.ndarray, ...]:
    """b_ii = (u_i x w_i) . v_i (..., 3), A with rows w_i x v_i (..., 3, 3) and det A (...)."""
    w = proximal_axes(design, theta)
    v = platform_axes(design, R)
    b = np.sum(np.cross(design.u, w) * v, axis=-1)
    A = np.cross(w, v)
    return b, A, np.linalg.det(A)


# ------------------------------------------------- no silent skips under CI
#: Skips for a missing module (pytest.importorskip): fine on a partial local install,
#: a failure under CI, where `pip install ".[test]"` installs every test dependency.
_MISSING_MODULE_SKIPS: list[str] = []


def _under_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


def missing_dependency(reason: str) -> NoReturn:
    """Skip a test whose optional dependency is missing (not a module, so no
    pytest.importorskip: data files, a browser); under CI, where every test dependency
    is installed, fail instead."""
    if _under_ci():
        pytest.fail(f"{reason}; under CI (CI=true) every test dependency must be installed")
    pytest.skip(reason)


def _record_missing_module(report: pytest.CollectReport | pytest.TestReport) -> None:
    if report.skipped and "could not import" in str(report.longrepr):
        _MISSING_MODULE_SKIPS.append(f"{report.nodeid}: {report.longrepr}")


def pytest_collectreport(report: pytest.CollectReport) -> None:
    _record_missing_module(report)


def pytest_runtest_logreport(report: pytest.TestReport) -> None:
    _record_missing_module(report)


def pytest_sessionfinish(session: pytest.Session, exitstatus: int) -> None:
    if _under_ci() and _MISSING_MODULE_SKIPS:
        print("\nunder CI, tests skipped for a missing module:", *_MISSING_MODULE_SKIPS, sep="\n")
        session.exitstatus = pytest.ExitCode.TESTS_FAILED
