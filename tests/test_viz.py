"""The meshcat visualizer without a browser: the scene it builds against Pinocchio and
the analytic kinematics, bad input, the server's lifetime (no process or port left
behind), HTML export, and the ``spm show`` / ``spm animate`` commands.

What a real browser makes of the scene is tested in test_viz_browser.py.
"""

from __future__ import annotations

import base64
import gc
import html
import json
import math
import os
import re
import signal
import socket
import subprocess
import sys
import time
import urllib.request
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import umsgpack

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.collision import check_input
from spm_pin.model.geometry import LINK_NAMES, link_meshes
from spm_pin.model.robot import SPMRobot
from spm_pin.rotations import matrix_from_quaternion
from spm_pin.viz import (
    COLLIDING_COLOR,
    DEFAULT_VIEW,
    LINK_COLORS,
    ROOT,
    VIEWS,
    MeshcatServer,
    ViewerError,
    Visualizer,
    link_path,
)
from spm_pin.viz.views import (
    CAMERA_FOV,
    ISO_MIN_FACING,
    choose_iso_direction,
    view_direction,
)

#: Tolerances, by what they compare.
TOL = {
    "transform": 1e-12,  # a transform in the scene against Pinocchio's placement
    "analytic": 1e-9,  # a drawn axis against the analytic forward kinematics
    "float32": 1e-6,  # mesh vertices and animation keys sent as float32 [m, 1]
    "camera": 1e-9,  # the camera fit, recomputed here
}
#: How long a stopped or orphaned server may take to vanish [s].
VANISH_S = 10.0

DEMO_DEG = [60.0, 90.0, 120.0]  # the published study's demonstration input
STUDY_COLLIDING_DEG = [60.0, 90.0, 220.0]  # the study's colliding input (no home mode)
#: An input with a home-mode assembly whose proximal links 2 and 3 overlap: the gap
#: between them, 120 + theta_2 - theta_3 = 40 deg, is narrower than the links.
HOME_COLLIDING_DEG = [0.0, 0.0, 80.0]

CAMERA = "/Cameras/default/rotated/<object>"


@pytest.fixture(scope="module")
def robot() -> SPMRobot:
    return spm.build_robot()


@pytest.fixture
def viz(robot: SPMRobot) -> Visualizer:
    return Visualizer(robot)


def study_colliding_q(robot: SPMRobot) -> np.ndarray:
    """The study's colliding input in its first real assembly mode."""
    theta = np.radians(STUDY_COLLIDING_DEG)
    modes = spm.forward_kinematics_all(theta)
    return robot.configuration(theta, modes.labels[0])


def decode(packed: bytes) -> Any:
    return umsgpack.unpackb(packed)


def ext_array(ext: Any, dtype: type) -> np.ndarray:
    return np.frombuffer(ext.data, dtype=dtype)


def html_commands(text: str) -> list[dict[str, Any]]:
    """The meshcat commands a saved page runs, decoded."""
    match = re.search(r"var commands = (\[.*?\]);", text, re.DOTALL)
    assert match is not None, "no command list in the page"
    return [decode(base64.b64decode(item)) for item in json.loads(match.group(1))]


def shown_black(viz: Visualizer) -> set[str]:
    """Links whose black copy is visible (and whose coloured one is hidden)."""
    black = set()
    for name in LINK_NAMES:
        free = viz.scene.property(f"{link_path(name)}/free", "visible")
        colliding = viz.scene.property(f"{link_path(name)}/colliding", "visible")
        assert free != colliding, f"{name}: exactly one of its two meshes must be visible"
        if colliding:
            black.add(name)
    return black


# ------------------------------------------------------------------------ imports
def test_core_never_imports_viz(tmp_path: Path) -> None:
    code = (
        "import sys, spm_pin as spm\n"
        "spm.build_robot().configuration([0.1, 0.2, 0.3])\n"
        "loaded = [m for m in sys.modules if m.split('.')[0] == 'meshcat' or "
        "m.startswith('spm_pin.viz')]\n"
        "assert not loaded, loaded\n"
    )
    subprocess.run([sys.executable, "-c", code], check=True, cwd=tmp_path, env=_env())


def _env() -> dict[str, str]:
    root = str(Path(spm.__file__).resolve().parent.parent)
    path = os.pathsep.join(p for p in (root, os.environ.get("PYTHONPATH")) if p)
    return {**os.environ, "PYTHONPATH": path}


# -------------------------------------------------------------------------- scene
def test_one_node_per_link_in_its_colour(viz: Visualizer) -> None:
    assert viz.scene.children(f"{ROOT}/links") == list(LINK_NAMES)
    for name in LINK_NAMES:
        assert viz.scene.children(link_path(name)) == ["free", "colliding"]
        for child, color in (("free", LINK_COLORS[name]), ("colliding", COLLIDING_COLOR)):
            obj = viz.scene.object(f"{link_path(name)}/{child}")
            assert obj is not None
            material = obj["materials"][0]
            expected = sum(round(255 * c) << s for c, s in zip(color[:3], (16, 8, 0), strict=True))
            assert material["color"] == expected
    assert shown_black(viz) == set()


def test_legs_have_distinct_colours_and_the_base_is_neutral() -> None:
    legs = [{LINK_COLORS[f"proximal_{i}"], LINK_COLORS[f"distal_{i}"]} for i in (1, 2, 3)]
    assert all(not (a & b) for k, a in enumerate(legs) for b in legs[k + 1 :])
    for name in ("base", "platform"):
        r, g, b, _ = LINK_COLORS[name]
        assert max(r, g, b) - min(r, g, b) < 0.05, f"{name} should be a grey"
    assert all(max(color[:3]) > 0.3 for color in LINK_COLORS.values()), "no link looks black"


def test_drawn_meshes_are_the_model_meshes(viz: Visualizer) -> None:
    meshes = link_meshes(viz.robot.design)
    for name in LINK_NAMES:
        obj = viz.scene.object(f"{link_path(name)}/free")
        assert obj is not None
        geometry = obj["geometries"][0]["data"]
        drawn = ext_array(geometry["attributes"]["position"]["array"], np.float32)
        drawn = drawn.reshape(-1, 3).astype(float)
        faces = ext_array(geometry["index"]["array"], np.uint32).reshape(-1, 3)
        assert faces.shape == meshes[name].faces.shape
        # every drawn vertex is a model vertex (the copy only splits sharp edges)
        distance = np.linalg.norm(drawn[:, None, :] - meshes[name].vertices[None], axis=-1)
        assert distance.min(axis=1).max() < TOL["float32"]
        np.testing.assert_allclose(
            drawn[faces].mean(axis=(0, 1)),
            meshes[name].vertices[meshes[name].faces].mean(axis=(0, 1)),
            atol=TOL["float32"],
        )


@pytest.mark.parametrize(
    "theta_deg", [[0.0, 0.0, 0.0], DEMO_DEG, [-35.0, 20.0, 10.0], [400.0, 420.0, 380.0]]
)
def test_display_puts_links_at_their_placements(viz: Visualizer, theta_deg: list[float]) -> None:
    theta = np.radians(theta_deg)
    viz.display(theta)
    q = viz.robot.configuration(theta)
    np.testing.assert_array_equal(viz.q, q)
    for name in LINK_NAMES:
        expected = viz.robot.placement(q, name).homogeneous
        np.testing.assert_allclose(
            viz.scene.transform(link_path(name)), expected, atol=TOL["transform"]
        )
    # the arrows of w_i and v_i point where the analytic kinematics put the axes
    fk = spm.forward_kinematics(theta)
    design = viz.robot.design
    for i in range(3):
        w_node = viz.scene.transform(f"{ROOT}/overlays/joint_axes/w_{i + 1}")
        v_node = viz.scene.transform(f"{ROOT}/overlays/joint_axes/v_{i + 1}")
        assert w_node is not None and v_node is not None
        u, w0 = design.u[i], design.w0[i]
        c, s = math.cos(theta[i]), math.sin(theta[i])
        w = c * w0 + s * np.cross(u, w0) + (1 - c) * (u @ w0) * u  # w0 turned by theta_i
        np.testing.assert_allclose(w_node[:3, :3] @ w0, w, atol=TOL["analytic"])
        np.testing.assert_allclose(v_node[:3, :3] @ design.v0[i], fk.v[i], atol=TOL["analytic"])
    frame = viz.scene.transform(f"{ROOT}/overlays/platform_frame")
    assert frame is not None
    np.testing.assert_allclose(frame[:3, :3], fk.R, atol=TOL["analytic"])


def test_display_of_q_equals_display_of_theta(robot: SPMRobot) -> None:
    by_theta, by_q = Visualizer(robot), Visualizer(robot)
    theta = np.radians(DEMO_DEG)
    by_theta.display(theta)
    by_q.display(robot.configuration(theta))
    assert by_theta.scene.commands() == by_q.scene.commands()


def test_display_in_another_assembly_mode(viz: Visualizer) -> None:
    theta = np.radians(STUDY_COLLIDING_DEG)
    modes = spm.forward_kinematics_all(theta)
    for k in range(int(modes.count)):
        viz.display(theta, mode=modes.labels[k])
        platform = viz.scene.transform(link_path("platform"))
        assert platform is not None
        np.testing.assert_allclose(platform[:3, :3], modes.R[k], atol=TOL["analytic"])


# ---------------------------------------------------------------------- collisions
def test_colliding_links_turn_black_and_back(viz: Visualizer) -> None:
    robot = viz.robot
    q = study_colliding_q(robot)
    pairs = viz.display(q)
    assert pairs == robot.collisions(q)
    expected = {name for pair in pairs for name in pair}
    assert {"proximal_2", "proximal_3"} <= expected
    assert shown_black(viz) == expected == viz.colliding_links
    assert viz.display(np.radians(DEMO_DEG)) == []
    assert shown_black(viz) == set() == viz.colliding_links


def test_home_mode_colliding_input(viz: Visualizer) -> None:
    theta = np.radians(HOME_COLLIDING_DEG)
    pairs = viz.display(theta)
    assert ("proximal_2", "proximal_3") in pairs
    assert {"proximal_2", "proximal_3"} <= shown_black(viz)


def test_collision_checking_can_be_off(robot: SPMRobot) -> None:
    viz = Visualizer(robot, check_collisions=False)
    assert viz.display(study_colliding_q(robot)) == []
    assert shown_black(viz) == set()


def test_collision_margin_reaches_further(robot: SPMRobot) -> None:
    theta = np.radians([0.0, 0.0, 71.0])  # proximal links 2 and 3 close, not touching
    margin = 0.0005  # [m], below the 0.94 mm between the nested drive tubes
    gap = robot.distances(theta)[("proximal_2", "proximal_3")]
    assert 0 < gap < margin
    assert Visualizer(robot).display(theta) == []
    viz = Visualizer(robot, collision_margin=margin)
    assert viz.display(theta) == [("proximal_2", "proximal_3")]
    assert shown_black(viz) == {"proximal_2", "proximal_3"}


# ------------------------------------------------------------------------ overlays
def test_overlays_are_hidden_unless_asked(robot: SPMRobot) -> None:
    plain = Visualizer(robot)
    for name in ("joint_axes", "platform_frame"):
        assert plain.scene.property(f"{ROOT}/overlays/{name}", "visible") is False
    both = Visualizer(robot, joint_axes=True, platform_frame=True)
    for name in ("joint_axes", "platform_frame"):
        assert both.scene.property(f"{ROOT}/overlays/{name}", "visible") is True
    both.set_overlays(joint_axes=False)
    assert both.scene.property(f"{ROOT}/overlays/joint_axes", "visible") is False
    assert both.scene.property(f"{ROOT}/overlays/platform_frame", "visible") is True
    names = plain.scene.children(f"{ROOT}/overlays/joint_axes")
    assert names == [f"{a}_{i}" for a in "uwv" for i in (1, 2, 3)]
    assert plain.scene.children(f"{ROOT}/overlays/platform_frame") == ["x", "y", "z"]


# -------------------------------------------------------------------------- camera
def _project(viz: Visualizer, points: np.ndarray, aspect: float) -> np.ndarray:
    """Normalised device coordinates (x, y) of world points, computed here from the
    camera properties in the scene the way three.js does (camera looking at O)."""
    x3, y3, z3 = viz.scene.property(CAMERA, "position")
    eye = np.array([x3, -z3, y3])  # three.js is y-up
    zoom = viz.scene.property(CAMERA, "zoom")
    view = viz.scene.property(CAMERA, "view")
    forward = -eye / np.linalg.norm(eye)
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    relative = points - eye
    depth = relative @ forward
    top = math.tan(math.radians(75.0) / 2) / zoom
    height = 2 * top
    top -= view["offsetY"] * height / view["fullHeight"]
    bottom = top - height
    half_width = aspect * height / 2
    x = (relative @ right / depth) / half_width
    y = 2 * ((relative @ up / depth) - bottom) / height - 1
    return np.stack([x, y], axis=-1)


def test_default_camera_frames_the_robot(viz: Visualizer) -> None:
    for theta_deg in ([0.0, 0.0, 0.0], DEMO_DEG):
        viz.display(np.radians(theta_deg))
        viz.set_camera()
        placements = viz.robot.placements(viz.q)
        points = np.concatenate(
            [
                mesh.vertices @ placements[name].rotation.T
                for name, mesh in link_meshes(viz.robot.design).items()
            ]
        )
        ndc = _project(viz, points, aspect=4.0 / 3.0)
        assert np.all(np.abs(ndc) <= 0.8 + TOL["camera"]), "the robot leaves the view"
        # it fills the view: height 80 % (the default fill), centred
        np.testing.assert_allclose(np.ptp(ndc[:, 1]), 1.6, atol=0.01)
        np.testing.assert_allclose(ndc[:, 1].max() + ndc[:, 1].min(), 0.0, atol=TOL["camera"])


def test_camera_direction(viz: Visualizer) -> None:
    viz.set_camera(azimuth=math.radians(90.0), elevation=math.radians(30.0))
    x3, y3, z3 = viz.scene.property(CAMERA, "position")
    eye = np.array([x3, -z3, y3])
    expected = [0.0, math.cos(math.radians(30.0)), math.sin(math.radians(30.0))]
    np.testing.assert_allclose(eye / np.linalg.norm(eye), expected, atol=TOL["camera"])


def _eye(viz: Visualizer) -> np.ndarray:
    x3, y3, z3 = viz.scene.property(CAMERA, "position")
    return np.array([x3, -z3, y3])  # three.js is y-up


def _link_points(viz: Visualizer, q: np.ndarray) -> np.ndarray:
    placements = viz.robot.placements(q)
    return np.concatenate(
        [
            mesh.vertices @ placements[name].rotation.T + placements[name].translation
            for name, mesh in link_meshes(viz.robot.design).items()
        ]
    )


def _world_meshes(robot: SPMRobot, q: np.ndarray) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    placements = robot.placements(q)
    return {
        name: (
            mesh.vertices @ placements[name].rotation.T + placements[name].translation,
            mesh.faces,
        )
        for name, mesh in link_meshes(robot.design).items()
    }


@pytest.mark.parametrize("name", list(VIEWS))
def test_preset_views_look_at_o_from_their_direction_and_frame_the_robot(
    robot: SPMRobot, name: str
) -> None:
    viz = Visualizer(robot, view=name)
    viz.display(np.radians(DEMO_DEG))
    viz.set_view(name)
    assert viz.view == name
    preset = VIEWS[name]
    eye = _eye(viz)
    expected = view_direction(preset.azimuth, preset.elevation)
    np.testing.assert_allclose(eye / np.linalg.norm(eye), expected, atol=TOL["camera"])
    # the camera stands where the bounding sphere about O fits its field of view
    points = _link_points(viz, viz.q)
    radius = np.linalg.norm(points, axis=1).max()
    assert np.linalg.norm(eye) * math.sin(CAMERA_FOV / 2) >= radius
    ndc = _project(viz, points, aspect=4.0 / 3.0)
    assert np.all(np.abs(ndc) <= 0.8 + TOL["camera"]), f"the robot leaves the {name} view"
    np.testing.assert_allclose(ndc[:, 1].max() + ndc[:, 1].min(), 0.0, atol=TOL["camera"])


def test_default_view_is_iso_and_sees_the_platform_face(robot: SPMRobot) -> None:
    assert DEFAULT_VIEW == next(iter(VIEWS)) == "iso"
    viz = Visualizer(robot)
    assert viz.view == "iso"
    q = robot.configuration(np.radians(DEMO_DEG))
    normal = robot.placement(q, "platform").rotation[:, 2]
    # the iso direction is what the documented rule chooses for the study's input
    azimuth, elevation = choose_iso_direction(_world_meshes(robot, q), normal)
    np.testing.assert_allclose(
        [azimuth, elevation], [VIEWS["iso"].azimuth, VIEWS["iso"].elevation], atol=1e-12
    )
    assert normal @ view_direction(azimuth, elevation) >= ISO_MIN_FACING
    # the old default camera (azimuth -30, elevation 20 deg) saw the platform edge-on
    old = view_direction(math.radians(-30.0), math.radians(20.0))
    assert abs(normal @ old) < 0.05


def test_animation_is_framed_on_its_samples(viz: Visualizer) -> None:
    path = np.linspace(0.0, 1.0, 25)[:, None] * np.radians(DEMO_DEG)
    motion = viz.animate(path)
    viz.set_view("top")
    for k in (0, 12, 24):
        ndc = _project(viz, _link_points(viz, motion.q[k]), aspect=4.0 / 3.0)
        assert np.all(np.abs(ndc) <= 0.8 + TOL["camera"]), f"sample {k} leaves the view"


@pytest.mark.parametrize("view", ["diagonal", "ISO", None, 3])
def test_bad_view(viz: Visualizer, view: Any) -> None:
    match = rf"^view must be one of iso, top, front, side, got {re.escape(repr(view))}$"
    with pytest.raises(spm.InputError, match=match) as info:
        viz.set_view(view)
    assert info.value.argument == "view"
    with pytest.raises(spm.InputError, match=match):
        Visualizer(viz.robot, view=view)


def page_views(text: str) -> tuple[dict[str, Any], Any]:
    """The view settings (name -> [path, property, value]) of a saved page and the
    view it opens in."""
    views = re.search(r"var spm_views = (\{.*?\});\n", text, re.DOTALL)
    opened = re.search(r"var view = (.*?);\n", text)
    assert views is not None and opened is not None, "no views in the page"
    return json.loads(views.group(1)), json.loads(opened.group(1))


def page_eye(settings: list[list[Any]]) -> np.ndarray:
    """The camera position (z-up world) that a page's view settings set."""
    (position,) = [value for path, key, value in settings if key == "position"]
    assert settings[0][0] == ["Cameras", "default", "rotated", "<object>"]
    x3, y3, z3 = position
    return np.array([x3, -z3, y3])


def test_saved_page_has_the_key_and_the_views(robot: SPMRobot) -> None:
    viz = Visualizer(robot, view="side")
    viz.display(np.radians(DEMO_DEG))
    text = viz.static_html()
    key = re.search(r'<ul id="spm-key">(.*?)</ul>', text)
    assert key is not None
    legs = re.findall(r'<li class="spm-key-leg" data-leg="(\d)">(.*?)</li>', key.group(1))
    assert [leg for leg, _ in legs] == ["1", "2", "3"]
    for i, entry in legs:
        for link in (f"proximal_{i}", f"distal_{i}"):
            r, g, b = (round(255 * c) for c in LINK_COLORS[link][:3])
            assert f"background:#{r:02x}{g:02x}{b:02x}" in entry
    assert re.findall(r'data-axis="(\w+)"', key.group(1)) == []  # no arrows drawn
    assert 'class="spm-key-colliding"' in key.group(1)
    viz.set_overlays(joint_axes=True, platform_frame=True)
    axes = re.findall(r'data-axis="(\w+)"', viz.static_html())
    assert axes == ["u", "w", "v", "frame"]
    views, opened = page_views(text)
    assert list(views) == list(VIEWS) and opened == "side"
    assert re.findall(r'<button type="button" data-view="(\w+)"', text) == list(VIEWS)
    for name, settings in views.items():
        eye = page_eye(settings)
        preset = VIEWS[name]
        np.testing.assert_allclose(
            eye / np.linalg.norm(eye),
            view_direction(preset.azimuth, preset.elevation),
            atol=TOL["camera"],
        )
    # after set_camera the page opens in the camera as set
    viz.set_camera(azimuth=0.3, elevation=0.2)
    assert viz.view is None and page_views(viz.static_html())[1] is None


# ---------------------------------------------------------------------- animations
def _clips(viz: Visualizer) -> dict[str, list[dict[str, Any]]]:
    assert viz.scene.animation is not None
    command = decode(viz.scene.animation)
    return {item["path"]: item["clip"]["tracks"] for item in command["animations"]}


def test_animation_follows_the_path(viz: Visualizer) -> None:
    robot = viz.robot
    path = np.linspace(0.0, 1.0, 25)[:, None] * np.radians(DEMO_DEG)
    motion = viz.animate(path, dt=0.05)
    np.testing.assert_allclose(motion.times, 0.05 * np.arange(25), atol=1e-15)
    np.testing.assert_allclose(motion.q, robot.configuration(path), atol=TOL["transform"])
    assert motion.collisions == [[] for _ in range(25)] and motion.colliding_samples == []
    clips = _clips(viz)
    for name in LINK_NAMES:
        position, quaternion = clips[link_path(name)]
        assert [key["time"] for key in quaternion["keys"]] == pytest.approx(motion.times)
        for k, key in enumerate(quaternion["keys"]):
            x, y, z, w = key["value"]
            R = matrix_from_quaternion([w, x, y, z])
            expected = robot.placement(motion.q[k], name).rotation
            np.testing.assert_allclose(R, expected, atol=TOL["transform"])
        assert all(key["value"] == [0.0, 0.0, 0.0] for key in position["keys"])
        # consecutive keys on the same side of the quaternion double cover
        values = np.array([key["value"] for key in quaternion["keys"]])
        assert np.all(np.sum(values[1:] * values[:-1], axis=1) > 0)
    # the static scene shows the first sample
    np.testing.assert_allclose(
        viz.scene.transform(link_path("platform")),
        robot.placement(motion.q[0], "platform").homogeneous,
        atol=TOL["transform"],
    )


def test_animation_turns_colliding_links_black(viz: Visualizer) -> None:
    robot = viz.robot
    path = np.linspace(0.0, 1.0, 11)[:, None] * np.radians(HOME_COLLIDING_DEG)
    motion = viz.animate(path)
    assert motion.colliding_samples, "the path should end in a collision"
    assert motion.colliding_samples[-1] == 10 and 0 not in motion.colliding_samples
    clips = _clips(viz)
    for k, q in enumerate(motion.q):
        assert motion.collisions[k] == robot.collisions(q)
        black = {name for pair in motion.collisions[k] for name in pair}
        for name in LINK_NAMES:
            (free,) = clips[f"{link_path(name)}/free"]
            (colliding,) = clips[f"{link_path(name)}/colliding"]
            assert free["type"] == colliding["type"] == "boolean"
            assert free["keys"][k]["value"] is (name not in black)
            assert colliding["keys"][k]["value"] is (name in black)


def test_animation_of_configurations_and_display_ends_it(viz: Visualizer) -> None:
    robot = viz.robot
    qs = robot.configuration(np.radians([[0.0, 0.0, 0.0], [10.0, 20.0, 30.0], DEMO_DEG]))
    motion = viz.animate(qs, play=False, repetitions=3)
    np.testing.assert_array_equal(motion.q, qs)
    command = decode(viz.scene.animation or b"")
    assert command["options"] == {"play": False, "repetitions": 3}
    assert any(kind == "set_animation" for kind, _, _ in viz.scene.commands())
    viz.display(np.radians(DEMO_DEG))
    assert viz.scene.animation is None
    assert not any(c["type"] == "set_animation" for c in html_commands(viz.static_html()))


def test_animation_follows_another_assembly_mode(viz: Visualizer) -> None:
    theta = np.radians(STUDY_COLLIDING_DEG)
    modes = spm.forward_kinematics_all(theta)
    path = theta + np.radians(np.linspace(0.0, -10.0, 6))[:, None] * [0.0, 0.0, 1.0]
    motion = viz.animate(path, start=modes.R[0])
    np.testing.assert_allclose(
        viz.robot.placement(motion.q[0], "platform").rotation, modes.R[0], atol=TOL["analytic"]
    )
    step = np.abs(np.diff(motion.q, axis=0)).max()
    assert step < math.radians(10.0), "the followed mode jumps"


# ---------------------------------------------------------------------- HTML export
def test_static_html_is_self_contained(viz: Visualizer, tmp_path: Path) -> None:
    viz.display(np.radians(DEMO_DEG))
    path = viz.save_html(tmp_path / "scene.html", title="a <robot>")
    text = path.read_text(encoding="utf-8")
    assert text == viz.static_html("a <robot>")
    assert "<title>a &lt;robot&gt;</title>" in text
    assert not re.search(r"<(script|link|img|iframe)\b[^>]*\b(src|href)\s*=", text, re.IGNORECASE)
    assert "MeshCat.Viewer" in text and "window.spm_scene_ready = true" in text
    commands = html_commands(text)
    assert commands == [decode(data) for _, _, data in viz.scene.commands()]
    assert 0.9e6 < len(text) < 3e6  # the viewer (0.85 MB) and the robot


def test_replay_order_puts_objects_before_their_properties(viz: Visualizer) -> None:
    seen_objects: set[str] = set()
    for kind, path, _ in viz.scene.commands():
        if kind == "set_object":
            seen_objects.add(path)
        elif kind == "set_property" and path.startswith(ROOT):
            assert path in seen_objects or viz.scene.object(path) is None


# ---------------------------------------------------------------------- bad input
BAD_DISPLAY: dict[str, tuple[Any, dict[str, Any], type[Exception]]] = {
    "empty": ([], {}, spm.InputError),
    "two numbers": ([0.0, 0.0], {}, spm.InputError),
    "batch of theta": ([[0.0, 0.0, 0.0]], {}, spm.InputError),
    "text": ("abc", {}, spm.InputError),
    "NaN theta": ([math.nan, 0.0, 0.0], {}, spm.InputError),
    "inf q": ([math.inf] + [0.0] * 8, {}, spm.InputError),
    "mode with q": ([0.0] * 9, {"mode": "+++/-"}, spm.InputError),
    "bad mode": ([0.0, 0.0, 0.0], {"mode": "sideways"}, spm.InputError),
    "no home mode": (np.radians(STUDY_COLLIDING_DEG), {"mode": "home"}, spm.UnreachableError),
    "absent label": (np.radians(STUDY_COLLIDING_DEG), {"mode": "+++/-"}, spm.UnreachableError),
}


@pytest.mark.parametrize("case", BAD_DISPLAY, ids=list(BAD_DISPLAY))
def test_bad_display(viz: Visualizer, case: str) -> None:
    x, kwargs, error = BAD_DISPLAY[case]
    before = viz.scene.commands()
    # the argument (or, when unreachable, the input) and what is wrong with it
    match = (
        r"^(x|q|theta) must|^mode (must be 'home', 'nearest' or|applies to)|has no assembly in mode"
    )
    with pytest.raises(error, match=match) as info:
        viz.display(x, **kwargs)
    assert isinstance(info.value, spm.SPMError)
    assert viz.scene.commands() == before, "a failed display changed the scene"


BAD_ANIMATE: dict[str, tuple[Any, dict[str, Any], type[Exception], str]] = {
    "one theta": ([0.0, 0.0, 0.0], {}, spm.InputError, "path"),
    "no samples": (np.zeros((0, 3)), {}, spm.InputError, "path"),
    "four columns": (np.zeros((2, 4)), {}, spm.InputError, "path"),
    "NaN": ([[0.0, 0.0, 0.0], [math.nan, 0.0, 0.0]], {}, spm.InputError, "path"),
    "text": ("abc", {}, spm.InputError, "path"),
    "zero dt": (np.zeros((2, 3)), {"dt": 0.0}, spm.InputError, "dt"),
    "NaN dt": (np.zeros((2, 3)), {"dt": math.nan}, spm.InputError, "dt"),
    "zero repetitions": (np.zeros((2, 3)), {"repetitions": 0}, spm.InputError, "repetitions"),
    "fractional repetitions": (
        np.zeros((2, 3)),
        {"repetitions": 1.5},
        spm.InputError,
        "repetitions",
    ),
    "start with q": (np.zeros((2, 9)), {"start": np.eye(3)}, spm.InputError, "start"),
}


@pytest.mark.parametrize("case", BAD_ANIMATE, ids=list(BAD_ANIMATE))
def test_bad_animate(viz: Visualizer, case: str) -> None:
    path, kwargs, error, argument = BAD_ANIMATE[case]
    with pytest.raises(error, match=rf"^{argument} (must|applies to)") as info:
        viz.animate(path, **kwargs)
    assert isinstance(info.value, spm.SPMError)
    if argument:
        assert getattr(info.value, "argument", None) == argument
        assert argument in str(info.value)
    assert viz.scene.animation is None


#: A design with inputs that have no assembly at all, and one such input [deg].
NO_ASSEMBLY_DESIGN = spm.SPMDesign.coaxial(50.0, 75.0, 100.0)
NO_ASSEMBLY_DEG = [81.3, -148.4, -37.8]


def test_animation_that_leaves_the_workspace() -> None:
    assert spm.forward_kinematics_all(np.radians(NO_ASSEMBLY_DEG), NO_ASSEMBLY_DESIGN).count == 0
    viz = Visualizer(spm.build_robot(NO_ASSEMBLY_DESIGN))
    path = np.linspace(0.0, 1.0, 10)[:, None] * np.radians(NO_ASSEMBLY_DEG)
    with pytest.raises(spm.UnreachableError, match="sample 9"):
        viz.animate(path)
    assert viz.scene.animation is None


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"azimuth": math.nan}, "azimuth"),
        ({"elevation": math.pi / 2}, "elevation"),
        ({"elevation": "up"}, "elevation"),
        ({"fill": 0.0}, "fill"),
        ({"fill": 1.5}, "fill"),
    ],
)
def test_bad_camera(viz: Visualizer, kwargs: dict[str, Any], argument: str) -> None:
    allowed = {
        "azimuth": "must be a finite number",
        "elevation": r"must (be a finite number|lie in \(-pi/2, pi/2\) \[rad\])",
        "fill": r"must lie in \(0, 1\]",
    }[argument]
    with pytest.raises(spm.InputError, match=f"^{argument} {allowed}") as info:
        viz.set_camera(**kwargs)
    assert info.value.argument == argument


@pytest.mark.parametrize(
    ("kwargs", "argument"),
    [
        ({"robot": spm.SPMDesign.prototype()}, "robot"),
        ({"collision_margin": -0.001}, "collision_margin"),
        ({"collision_margin": math.inf}, "collision_margin"),
    ],
)
def test_bad_visualizer(kwargs: dict[str, Any], argument: str) -> None:
    allowed = {
        "robot": r"must be an SPMRobot \(spm\.build_robot\(design\)\)",
        "collision_margin": r"must be a finite distance >= 0 \[m\]",
    }[argument]
    with pytest.raises(spm.InputError, match=f"^{argument} {allowed}") as info:
        Visualizer(**kwargs)
    assert info.value.argument == argument


def test_url_without_server(viz: Visualizer) -> None:
    assert not viz.running and viz.server is None
    with pytest.raises(ViewerError, match="start"):
        _ = viz.url


# -------------------------------------------------------------------------- server
def _gone(pid: int) -> bool:
    """The process has exited (a zombie not yet reaped by its new parent counts)."""
    try:
        with open(f"/proc/{pid}/stat", encoding="ascii") as stat:
            return stat.read().rsplit(")", 1)[1].split()[0] == "Z"
    except FileNotFoundError:
        return True


def _listening(port: int) -> bool:
    with socket.socket() as probe:
        probe.settimeout(1.0)
        return probe.connect_ex(("127.0.0.1", port)) == 0


def _assert_released(pid: int, ports: tuple[int, ...]) -> None:
    # A process shows as a zombie as soon as its main thread exits; its sockets close
    # when its last thread has exited: wait for both.
    for _ in range(round(VANISH_S / 0.05)):  # a bounded number of looks, no clock
        if _gone(pid) and not any(_listening(port) for port in ports):
            break
        time.sleep(0.05)
    assert _gone(pid), f"the meshcat server {pid} is still running"
    for port in ports:
        assert not _listening(port), f"port {port} is still open"
        with socket.socket() as again:  # a new server could take it (as meshcat binds)
            again.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            again.bind(("127.0.0.1", port))


def test_server_start_serve_stop() -> None:
    server = MeshcatServer()
    assert not server.running and repr(server) == "MeshcatServer(stopped)"
    with server:
        assert server.running
        pid, ports = server.pid, server.ports
        assert server.url == f"http://127.0.0.1:{ports[1]}/static/"
        assert server.zmq_url == f"tcp://127.0.0.1:{ports[0]}"
        assert all(_listening(port) for port in ports)
        with urllib.request.urlopen(server.url, timeout=10) as page:
            assert b"MeshCat.Viewer" in page.read()
        assert server.start() is server  # already running: nothing new
        assert server.pid == pid
    assert not server.running
    _assert_released(pid, ports)
    server.stop()  # idempotent
    with pytest.raises(ViewerError, match="not running"):
        server.send("set_property", "/Axes", b"")
    with pytest.raises(ViewerError, match="not running"):
        _ = server.url


def test_server_stops_when_the_block_raises() -> None:
    with pytest.raises(KeyError, match="boom"), MeshcatServer() as server:
        pid, ports = server.pid, server.ports
        raise KeyError("boom")
    _assert_released(pid, ports)


def test_server_stops_when_garbage_collected() -> None:
    server = MeshcatServer().start()
    pid, ports = server.pid, server.ports
    del server
    gc.collect()
    _assert_released(pid, ports)


_ORPHAN_SCRIPT = """
import sys, time
from spm_pin.viz import MeshcatServer
server = MeshcatServer().start()
print(server.pid, *server.ports, flush=True)
if sys.argv[1] == "exit":
    sys.exit(0)  # without stop()
time.sleep(600)
"""


@pytest.mark.parametrize("ending", ["exit", "SIGKILL", "SIGTERM"])
def test_server_never_outlives_its_parent(ending: str) -> None:
    parent = subprocess.Popen(
        [sys.executable, "-c", _ORPHAN_SCRIPT, ending],
        stdout=subprocess.PIPE,
        text=True,
        env=_env(),
    )
    try:
        assert parent.stdout is not None
        pid, *ports = (int(word) for word in parent.stdout.readline().split())
        if ending != "exit":
            parent.send_signal(getattr(signal, ending))
        parent.wait(timeout=30)
    finally:
        if parent.poll() is None:
            parent.kill()
            parent.wait()
        if parent.stdout is not None:
            parent.stdout.close()
    _assert_released(pid, tuple(ports))


def test_server_keeps_answering_after_many_connections() -> None:
    """The server logs every websocket to stderr: undrained, it blocks after a few hundred."""
    import asyncio

    from tornado.websocket import websocket_connect

    async def connect_many(url: str, count: int) -> None:
        for _ in range(count):
            connection = await websocket_connect(url)
            connection.close()

    async def first_message(url: str) -> bytes | str | None:
        """A new viewer connection: the server replays its scene tree to it."""
        connection = await websocket_connect(url)
        try:
            return await asyncio.wait_for(connection.read_message(), timeout=10.0)
        finally:
            connection.close()

    with MeshcatServer(timeout=10.0) as server:
        url = f"ws://127.0.0.1:{server.ports[1]}/"
        asyncio.run(connect_many(url, 600))
        for _ in range(3):
            server.send("set_property", "/Axes", umsgpack.packb(_axes_visible(True)))
        assert server.running
        # It still serves: a viewer that connects now receives the property just set.
        message = asyncio.run(first_message(url))
        assert isinstance(message, bytes)
        assert umsgpack.unpackb(message) == _axes_visible(True)


def _axes_visible(value: bool) -> dict[str, Any]:
    return {"type": "set_property", "path": "/Axes", "property": "visible", "value": value}


def test_server_that_fails_to_start_leaves_nothing() -> None:
    before = set(_children(os.getpid()))
    with pytest.raises(ViewerError, match="did not start within"):
        MeshcatServer(timeout=0.001).start()
    assert set(_children(os.getpid())) <= before


def test_server_refuses_bad_timeouts() -> None:
    for timeout in (0, -1.0, math.nan, "10", True):
        with pytest.raises(spm.InputError, match=r"^timeout must be a positive number of seconds"):
            MeshcatServer(timeout=timeout)  # type: ignore[arg-type]


def test_visualizer_serves_its_scene(robot: SPMRobot) -> None:
    viz = Visualizer(robot)
    with viz:
        assert viz.running and viz.url == viz.server.url  # type: ignore[union-attr]
        server = viz.server
        assert server is not None
        pid, ports = server.pid, server.ports
        assert viz.start() == viz.url  # no second server
        assert viz.display(np.radians(DEMO_DEG)) == []  # commands reach the server
        assert "url=" in repr(viz)
    assert not viz.running and viz.server is None
    _assert_released(pid, ports)
    # the scene outlives the server, and a new server gets all of it
    assert viz.scene.transform(link_path("platform")) is not None
    url = viz.start()
    try:
        assert url.startswith("http://127.0.0.1:")
    finally:
        viz.stop()


# ------------------------------------------------------------------------------ CLI
def run(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, str, str]:
    status = main(list(argv))
    out, err = capsys.readouterr()
    return status, out, err


def test_cli_show_html(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    target = tmp_path / "demo.html"
    status, out, err = run(capsys, "show", *map(str, DEMO_DEG), "--html", str(target), "--json")
    assert status == 0, err
    record = json.loads(out)
    assert record["theta_deg"] == DEMO_DEG and record["colliding"] == []
    assert record["html"] == str(target)
    commands = html_commands(target.read_text(encoding="utf-8"))
    robot = spm.build_robot()
    q = robot.configuration(np.radians(DEMO_DEG))
    (platform,) = (
        c for c in commands if c["type"] == "set_transform" and c["path"] == link_path("platform")
    )
    shown = np.array(platform["matrix"]).reshape(4, 4).T
    np.testing.assert_allclose(shown, robot.placement(q, "platform").homogeneous, atol=1e-12)
    status, out, _ = run(capsys, "show", "0", "0", "0", "--html", str(target), "--axes")
    assert status == 0 and str(target) in out
    visible = {
        c["path"]: c["value"]
        for c in html_commands(target.read_text(encoding="utf-8"))
        if c["type"] == "set_property" and c["property"] == "visible"
    }
    assert visible[f"{ROOT}/overlays/joint_axes"] is True
    assert visible[f"{ROOT}/overlays/platform_frame"] is False


def test_cli_show_colliding(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    robot = spm.build_robot()
    theta = np.radians(STUDY_COLLIDING_DEG)
    label = spm.forward_kinematics_all(theta).labels[0]
    target = tmp_path / "colliding.html"
    argv = ["show", *map(str, STUDY_COLLIDING_DEG), "--mode", label, "--html", str(target)]
    status, out, err = run(capsys, *argv, "--json")
    assert status == 0, err
    expected = robot.collisions(robot.configuration(theta, label))
    assert json.loads(out)["colliding"] == [list(pair) for pair in expected]
    status, out, err = run(capsys, *argv)
    assert status == 0 and "proximal_2" in out
    # a label that starts with a minus is a value, not an option
    label = next(m for m in spm.forward_kinematics_all(theta).labels if m.startswith("-"))
    argv = ["show", *map(str, STUDY_COLLIDING_DEG), "--mode", label, "--html", str(target)]
    status, out, err = run(capsys, *argv, "--json")
    assert status == 0, err
    assert json.loads(out)["mode"] == label


def test_cli_show_study_colliding_input_by_the_rule(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    """`spm show 60 90 220 --html out.html`: the real mode nearest to home, named in the
    output and on the page, its colliding links black (as `spm collide` reports)."""
    target = tmp_path / "out.html"
    argv = ["show", *map(str, STUDY_COLLIDING_DEG), "--html", str(target)]
    status, out, err = run(capsys, *argv, "--json")
    assert status == 0, err
    record = json.loads(out)
    report = check_input(np.radians(STUDY_COLLIDING_DEG))
    assert record["mode"] == report.mode == spm.select_assembly(np.radians([60, 90, 220])).label
    assert record["home"] is False and report.mode is not None
    assert record["colliding"] == [list(pair) for pair in report.pairs]
    assert ["proximal_2", "proximal_3"] in record["colliding"]
    page = target.read_text(encoding="utf-8")
    caption = page.split('<div id="spm-caption">', 1)[1].split("</div>", 1)[0]
    assert f"assembly mode {report.mode}" in html.unescape(caption)
    assert "proximal_2-proximal_3" in caption
    colliding = {
        c["path"]: c["value"]
        for c in html_commands(page)
        if c["type"] == "set_property" and c["property"] == "visible"
    }
    for name in ("proximal_2", "proximal_3", "distal_2", "distal_3"):
        assert colliding[f"{link_path(name)}/colliding"] is True
        assert colliding[f"{link_path(name)}/free"] is False
    assert colliding[f"{link_path('proximal_1')}/colliding"] is False
    status, out, err = run(capsys, *argv)
    assert status == 0 and report.mode in out


def test_display_follows_the_assembly_rule(viz: Visualizer) -> None:
    theta = np.radians(STUDY_COLLIDING_DEG)
    chosen = spm.select_assembly(theta)
    viz.display(theta)
    assert viz.mode == chosen.label and viz.home is False
    platform = viz.scene.transform(link_path("platform"))
    assert platform is not None
    np.testing.assert_allclose(platform[:3, :3], chosen.R, atol=TOL["analytic"])
    viz.display(np.radians(DEMO_DEG))
    assert viz.mode == "+++/-" and viz.home is True
    viz.display(viz.robot.configuration(np.radians(DEMO_DEG)))
    assert viz.mode is None
    motion = viz.animate(np.radians([STUDY_COLLIDING_DEG, [60.0, 90.0, 210.0]]))
    assert motion.modes[0] == chosen.label


def test_cli_animate(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    target = tmp_path / "motion.html"
    argv = ["animate", "--to", *map(str, HOME_COLLIDING_DEG), "--samples", "5", "--html"]
    status, out, err = run(capsys, *argv, str(target), "--json", "--duration", "1")
    assert status == 0, err
    record = json.loads(out)
    assert record["samples"] == 5 and record["from_deg"] == [0.0, 0.0, 0.0]
    assert record["colliding_samples"] == [4]
    (animation,) = (
        c for c in html_commands(target.read_text(encoding="utf-8")) if c["type"] == "set_animation"
    )
    platform = next(a for a in animation["animations"] if a["path"] == link_path("platform"))
    times = [key["time"] for key in platform["clip"]["tracks"][1]["keys"]]
    assert times == pytest.approx([0.0, 0.25, 0.5, 0.75, 1.0])
    demo = ["--to", *map(str, DEMO_DEG), "--html", str(target)]
    status, out, _ = run(capsys, "animate", "--from", "0", "0", "0", *demo)
    assert status == 0 and "25" in out


@pytest.mark.parametrize(
    "argv",
    [
        ["show", "60", "90", "220", "--mode", "home", "--html", "x.html"],  # no home mode
        ["show", *map(str, NO_ASSEMBLY_DEG), "--design", "d.toml", "--html", "x.html"],
        ["show", "0", "0", "0", "--mode", "sideways", "--html", "x.html"],
        ["show", "0", "0", "--html", "x.html"],
        ["animate", "--to", "60", "90", "120"],  # no --html
        ["animate", "--html", "x.html"],  # no --to
        ["animate", "--to", "60", "90", "120", "--samples", "1", "--html", "x.html"],
        ["animate", "--to", "60", "90", "120", "--duration", "0", "--html", "x.html"],
        ["animate", "--to", *map(str, NO_ASSEMBLY_DEG), "--design", "d.toml", "--html", "x.html"],
        ["show", "0", "0", "0", "--html", "no/such/dir/x.html"],
    ],
)
def test_cli_bad_arguments(
    capsys: pytest.CaptureFixture[str],
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    argv: list[str],
) -> None:
    monkeypatch.chdir(tmp_path)
    NO_ASSEMBLY_DESIGN.save(tmp_path / "d.toml")
    status, _, err = run(capsys, *argv)
    assert status == 2
    assert err.startswith("spm: error: ") and err.count("\n") == 1
    assert not (tmp_path / "x.html").exists()


@pytest.mark.parametrize("stop_signal", ["SIGINT", "SIGTERM"])
def test_cli_show_live_stops_cleanly(tmp_path: Path, stop_signal: str) -> None:
    process = subprocess.Popen(
        [sys.executable, "-m", "spm_pin", "show", "0", "0", "0", "--json"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        cwd=tmp_path,
        env=_env(),
    )
    try:
        assert process.stdout is not None
        lines = []
        while not lines or lines[-1] != "}":
            line = process.stdout.readline()
            assert line, "spm show ended before printing its url"
            lines.append(line.rstrip("\n"))
        record = json.loads("\n".join(lines))
        with urllib.request.urlopen(record["url"], timeout=10) as page:
            assert b"MeshCat.Viewer" in page.read()
        port = int(record["url"].split(":")[2].split("/")[0])
        children = _children(process.pid)
        assert len(children) == 1, "spm show should run exactly one server"
        process.send_signal(getattr(signal, stop_signal))
        _, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
            process.communicate()
    assert process.returncode == 0, err
    _assert_released(children[0], (port,))


def _children(pid: int) -> list[int]:
    """Process ids of the children of ``pid`` (from /proc)."""
    children = []
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text(encoding="ascii")
            except OSError:  # it ended meanwhile
                continue
            if int(stat.rsplit(")", 1)[1].split()[1]) == pid:
                children.append(int(entry.name))
    return children


# ------------------------------------------------------------------------ contacts
def _surface_distance(robot: SPMRobot, q: np.ndarray, link: str, point: np.ndarray) -> float:
    """Distance from a world point to a link's triangle mesh (coal, a BVH of the drawn
    mesh, not the collision layer's convex pieces) [m]."""
    import coal

    mesh = link_meshes(robot.design)[link]
    model = coal.BVHModelOBBRSS()
    model.beginModel(len(mesh.faces), len(mesh.vertices))
    model.addVertices(np.ascontiguousarray(mesh.vertices, dtype=np.float64))
    model.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
    model.endModel()
    placement = robot.placements(q)[link]
    at = coal.Transform3s(np.eye(3), np.asarray(point, dtype=float))
    return float(
        coal.distance(
            model,
            coal.Transform3s(placement.rotation, placement.translation),
            coal.Sphere(1e-9),
            at,
            coal.DistanceRequest(),
            coal.DistanceResult(),
        )
    )


def test_contact_markers_of_the_study_colliding_input(viz: Visualizer) -> None:
    """[60, 90, 220] deg (nearest real mode): one marker per colliding pair, at points
    on both links, with the collision layer's depths; the page lists them."""
    from spm_pin.viz.contacts import CONTACTS_PATH, contact_path, shown_contacts

    robot = viz.robot
    pairs = viz.display(np.radians(STUDY_COLLIDING_DEG))
    q = viz.q
    truth = robot.collisions(q)
    assert pairs == truth and len(truth) >= 2
    assert [c.pair for c in viz.contacts] == truth
    assert sorted(shown_contacts(viz.scene)) == sorted(f"{a}-{b}" for a, b in truth)
    distances = robot.distances(q)
    for contact in viz.contacts:
        assert contact.distance == pytest.approx(distances[contact.pair], abs=1e-9)
        assert contact.depth > 0
        assert contact.depth == pytest.approx(-distances[contact.pair], abs=1e-9)
        assert np.linalg.norm(contact.p2 - contact.p1) == pytest.approx(contact.depth, abs=1e-6)
        for point in (contact.p1, contact.p2):
            for link in contact.pair:
                assert _surface_distance(robot, q, link, point) <= contact.depth + 1e-4
        path = contact_path(contact.pair)
        assert viz.scene.children(path) == ["segment", "p1", "p2"]
        for name, point in (("p1", contact.p1), ("p2", contact.p2)):
            transform = viz.scene.transform(f"{path}/{name}")
            assert transform is not None
            assert np.allclose(transform[:3, 3], point, atol=1e-12)
    page = viz.static_html()
    overlay = page.split('<ul id="spm-contacts"', 1)[1].split("</ul>", 1)[0]
    for contact in viz.contacts:
        assert f"{contact.name}: {1000 * contact.depth:.1f} mm deep" in overlay
    # a safe pose hides every marker and says so
    assert viz.display(np.radians(DEMO_DEG)) == [] == viz.contacts
    assert shown_contacts(viz.scene) == []
    assert set(viz.scene.children(CONTACTS_PATH)) == {f"{a}-{b}" for a, b in truth}
    overlay = viz.static_html().split('<ul id="spm-contacts"', 1)[1].split("</ul>", 1)[0]
    assert "no collision" in overlay and "mm deep" not in overlay


def test_colliding_links_are_shaded_dark(viz: Visualizer) -> None:
    material = viz.scene.object(f"{link_path('proximal_2')}/colliding")["materials"][0]
    assert material["type"] == "MeshPhongMaterial"
    assert max(COLLIDING_COLOR[:3]) <= 0.15 and min(COLLIDING_COLOR[:3]) > 0.0
    assert material["shininess"] > 0 and material["specular"] > 0


@pytest.mark.parametrize("theta_deg", [DEMO_DEG, STUDY_COLLIDING_DEG])
def test_clearance_on_request(viz: Visualizer, theta_deg: list[float]) -> None:
    from spm_pin.viz.contacts import CONTACTS_PATH, shown_contacts

    viz.display(np.radians(theta_deg))
    assert viz.clearance is None and "clearance" not in shown_contacts(viz.scene)
    viz.display(np.radians(theta_deg), clearance=True)
    robot, q = viz.robot, viz.q
    free = {pair: d for pair, d in robot.distances(q).items() if d > 0}
    nearest = min(free.values())
    if not robot.collisions(q):
        assert nearest == pytest.approx(robot.min_clearance(q), abs=1e-12)
    found = viz.clearance
    assert found is not None and free[found.pair] == nearest
    assert np.linalg.norm(found.p2 - found.p1) == pytest.approx(nearest, abs=1e-6)
    assert "clearance" in shown_contacts(viz.scene)
    segment = viz.scene.transform(f"{CONTACTS_PATH}/clearance/segment")
    assert segment is not None
    assert np.allclose(segment[:3, 3], 0.5 * (found.p1 + found.p2), atol=1e-12)
    overlay = viz.static_html().split('<ul id="spm-contacts"', 1)[1].split("</ul>", 1)[0]
    assert f"{found.name}, {1000 * nearest:.2f} mm clear" in overlay
    viz.display(np.radians(theta_deg))
    assert "clearance" not in shown_contacts(viz.scene)


def test_cli_show_clearance(capsys: pytest.CaptureFixture[str], tmp_path: Path) -> None:
    target = tmp_path / "out.html"
    argv = ["show", *map(str, STUDY_COLLIDING_DEG), "--html", str(target), "--json"]
    status, out, err = run(capsys, *argv, "--clearance")
    assert status == 0, err
    record = json.loads(out)
    robot = spm.build_robot()
    viz = Visualizer(robot)
    viz.display(np.radians(STUDY_COLLIDING_DEG))
    distances = robot.distances(viz.q)
    assert record["depth_mm"] == {
        f"{a}-{b}": pytest.approx(-1000 * distances[(a, b)], abs=1e-3)
        for a, b in robot.collisions(viz.q)
    }
    free = {pair: d for pair, d in distances.items() if d > 0}
    assert record["clearance"]["mm"] == pytest.approx(1000 * min(free.values()), abs=1e-3)
    page = target.read_text(encoding="utf-8")
    assert 'class="spm-clearance"' in page and "mm deep" in page
    status, out, err = run(capsys, *argv[:-1], "--json")
    assert status == 0 and "clearance" not in json.loads(out)
