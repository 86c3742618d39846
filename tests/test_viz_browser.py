"""The meshcat scene in a real headless Chromium (driven by Playwright).

The live viewer and the exported HTML are opened in one shared browser and read back
through the page's global ``viewer`` (three.js scene, meshcat scene tree, canvas
pixels). Locally these tests skip when Chromium or Playwright is missing; under CI
(``CI=true``) they fail instead.
"""

from __future__ import annotations

import base64
import io
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.model.geometry import LINK_NAMES
from spm_pin.model.robot import SPMRobot
from spm_pin.viz import COLLIDING_COLOR, LINK_COLORS, ROOT, Visualizer, link_path
from spm_pin.viz.browser import CHROMIUM_ARGS, find_chromium, screenshot

pytestmark = pytest.mark.browser

#: Tolerances, by what they compare.
TOL = {
    "matrix": 1e-6,  # a node's world matrix in the page (float32) against Pinocchio
    "color": 1.0 / 255.0,  # a material colour in the page against LINK_COLORS
    "same_pixels": 0.995,  # share of pixels within 8 levels in two renders of one scene
    "robot_pixels": 0.03,  # share of the view the robot covers, at least
}
VIEWPORT = {"width": 640, "height": 480}
WAIT_S = 10.0  # for the live page to show a change
POLL_S = 0.02  # between two looks at the page
DARK = 40  # a pixel whose channels are all below this is black

DEMO_DEG = [60.0, 90.0, 120.0]
STUDY_COLLIDING_DEG = [60.0, 90.0, 220.0]
HOME_COLLIDING_DEG = [0.0, 0.0, 80.0]

# ------------------------------------------------------------------ page helpers
#: The node at a meshcat path (a list of names), without creating missing nodes.
_FIND = """(path) => {
    let node = viewer.scene_tree;
    for (const name of path) {
        node = node.children[name];
        if (node === undefined) return null;
    }
    return node;
}"""
#: World matrix of a node (three.js, y-up) and of the scene root (z-up to y-up).
_MATRIX = f"""(path) => {{
    const node = ({_FIND})(path);
    if (node === null) return null;
    viewer.scene.updateMatrixWorld(true);
    return [Array.from(node.object.matrixWorld.elements),
            Array.from(viewer.scene.matrixWorld.elements)];
}}"""
#: Per link: is the coloured / black mesh visible, and the colour of each.
_LINK_STATE = f"""(names) => {{
    const out = {{}};
    for (const name of names) {{
        const link = ({_FIND})(["meshcat", "spm", "links", name]);
        const part = (child) => {{
            const node = link.children[child];
            const mesh = node.children["<object>"].object;
            return {{visible: node.object.visible, color: mesh.material.color.toArray(),
                     isMesh: mesh.isMesh,
                     vertices: mesh.geometry.attributes.position.count}};
        }};
        out[name] = {{free: part("free"), colliding: part("colliding")}};
    }}
    return out;
}}"""
#: World position (z-up) of vertex 0 of a link's mesh.
_VERTEX = f"""(name) => {{
    const link = ({_FIND})(["meshcat", "spm", "links", name, "free", "<object>"]);
    const mesh = link.object;
    const a = mesh.geometry.attributes.position;
    const p = new MeshCat.THREE.Vector3(a.getX(0), a.getY(0), a.getZ(0));
    viewer.scene.updateMatrixWorld(true);
    p.applyMatrix4(mesh.matrixWorld);
    p.applyMatrix4(new MeshCat.THREE.Matrix4().copy(viewer.scene.matrixWorld).invert());
    return [[a.getX(0), a.getY(0), a.getZ(0)], [p.x, p.y, p.z]];
}}"""
_SEEK = """(t) => {
    const animator = viewer.animator;
    animator.play();
    animator.pause();
    animator.seek(t);
    return animator.actions.length;
}"""


def _on_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


def _unavailable(reason: str) -> None:
    if _on_ci():
        pytest.fail(f"{reason}; under CI the browser tests must run, not skip")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """One headless Chromium for this module (Debian's, never a download); closed at
    its end, so later modules can start Playwright's sync API again."""
    executable = find_chromium()
    if executable is None:
        _unavailable("no Chromium on the PATH (Debian: apt install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        _unavailable("Playwright for Python is not installed (pip install playwright)")
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=executable, args=list(CHROMIUM_ARGS))
        yield launched
        launched.close()


@pytest.fixture(scope="module")
def robot() -> SPMRobot:
    return spm.build_robot()


@pytest.fixture(scope="module")
def live(browser: Any, robot: SPMRobot) -> Iterator[tuple[Visualizer, Any]]:
    """A served visualizer and a page connected to it."""
    with Visualizer(robot) as viz:
        page = browser.new_page(viewport=VIEWPORT)
        errors: list[str] = []
        page.on("pageerror", lambda error: errors.append(str(error)))
        page.goto(viz.url)
        page.wait_for_function(
            "typeof viewer !== 'undefined' && viewer.connection !== undefined"
            " && viewer.connection.readyState === 1"
        )
        names = list(LINK_NAMES)
        page.wait_for_function(
            f"(names) => names.every((n) => {{ const node = ({_FIND})("
            "['meshcat', 'spm', 'links', n, 'colliding', '<object>']);"
            " return node !== null && node.object.isMesh; })",
            arg=names,
        )
        yield viz, page
        assert errors == [], errors
        page.close()


def open_offline(browser: Any, path: Path) -> tuple[Any, list[str]]:
    """A page showing a saved scene with every network request blocked (and listed)."""
    page = browser.new_page(viewport=VIEWPORT)
    url = path.resolve().as_uri()
    blocked: list[str] = []

    def route(request_route: Any) -> None:
        if request_route.request.url == url:
            request_route.continue_()
        else:
            blocked.append(request_route.request.url)
            request_route.abort()

    page.route("**/*", route)
    page.goto(url)
    page.wait_for_function("window.spm_scene_ready === true")
    return page, blocked


def capture(page: Any) -> np.ndarray:
    """The canvas as an RGB array (height, width, 3)."""
    from PIL import Image

    data_url = page.evaluate("viewer.capture_image()")
    image = Image.open(io.BytesIO(base64.b64decode(data_url.split(",", 1)[1])))
    return np.asarray(image.convert("RGB"), dtype=np.int16)


def dark_pixels(image: np.ndarray) -> int:
    return int(np.sum(np.all(image < DARK, axis=-1)))


def node_matrix(page: Any, path: str) -> np.ndarray:
    """A node's transform in the z-up world (the scene root's rotation taken out)."""
    result = page.evaluate(_MATRIX, [part for part in path.split("/") if part])
    assert result is not None, f"no node {path}"
    world, scene = (np.array(m, dtype=float).reshape(4, 4).T for m in result)
    return np.linalg.solve(scene, world)


def wait_until(condition: Callable[[], bool], what: str) -> None:
    """Poll ``condition`` up to WAIT_S / POLL_S times (a bound on the wait, not a
    timing assertion: a slow machine only polls longer in wall time)."""
    for _ in range(round(WAIT_S / POLL_S)):
        if condition():
            return
        time.sleep(POLL_S)
    assert condition(), f"the page did not show {what} after {round(WAIT_S / POLL_S)} polls"


def show(viz: Visualizer, page: Any, x: Any, **kwargs: Any) -> list[tuple[str, str]]:
    """Display x and wait until the page shows it (links and colours)."""
    pairs = viz.display(x, **kwargs)
    expected = {name: viz.robot.placement(viz.q, name).homogeneous for name in LINK_NAMES}
    black = {name for pair in pairs for name in pair}

    def shown() -> bool:
        state = page.evaluate(_LINK_STATE, list(LINK_NAMES))
        if {n for n in LINK_NAMES if state[n]["colliding"]["visible"]} != black:
            return False
        return all(
            np.allclose(node_matrix(page, link_path(n)), expected[n], atol=TOL["matrix"])
            for n in LINK_NAMES
        )

    wait_until(shown, f"the pose {x}")
    return pairs


def colliding_q(robot: SPMRobot) -> np.ndarray:
    theta = np.radians(STUDY_COLLIDING_DEG)
    return robot.configuration(theta, spm.forward_kinematics_all(theta).labels[0])


# -------------------------------------------------------------------------- tests
def test_one_scene_node_per_link(live: tuple[Visualizer, Any]) -> None:
    viz, page = live
    names = page.evaluate(f"Object.keys(({_FIND})(['meshcat', 'spm', 'links']).children)")
    assert names == list(LINK_NAMES)
    state = page.evaluate(_LINK_STATE, list(LINK_NAMES))
    for name in LINK_NAMES:
        free, colliding = state[name]["free"], state[name]["colliding"]
        assert free["isMesh"] and colliding["isMesh"]
        assert free["visible"] and not colliding["visible"]
        np.testing.assert_allclose(free["color"], LINK_COLORS[name][:3], atol=TOL["color"])
        np.testing.assert_allclose(colliding["color"], COLLIDING_COLOR[:3], atol=TOL["color"])
        obj = viz.scene.object(f"{link_path(name)}/free")
        assert obj is not None
        geometry = obj["geometries"][0]["data"]
        sent = len(geometry["attributes"]["position"]["array"].data) // 12
        assert free["vertices"] == colliding["vertices"] == sent


def test_robot_is_visible(live: tuple[Visualizer, Any]) -> None:
    _, page = live
    shown = capture(page)
    hide = f"(v) => {{ ({_FIND})(['meshcat', 'spm']).object.visible = v; viewer.set_dirty(); }}"
    page.evaluate(hide, False)
    try:
        hidden = capture(page)
    finally:
        page.evaluate(hide, True)
    changed = np.any(np.abs(shown - hidden) > 8, axis=-1)
    assert changed.mean() > TOL["robot_pixels"], f"the robot covers {changed.mean():.1%}"
    # the robot is in the middle of the view, not cut by its edges
    rows, cols = np.nonzero(changed)
    height, width = changed.shape
    assert rows.min() > 0 and rows.max() < height - 1 and cols.min() > 0 and cols.max() < width - 1
    assert abs(0.5 * (rows.min() + rows.max()) - height / 2) < 0.1 * height


def test_display_moves_link_nodes_to_pinocchio_placements(live: tuple[Visualizer, Any]) -> None:
    viz, page = live
    show(viz, page, np.radians(DEMO_DEG))  # waits for every link's matrix to match
    q = viz.robot.configuration(np.radians(DEMO_DEG))
    for name in LINK_NAMES:
        expected = viz.robot.placement(q, name)
        np.testing.assert_allclose(
            node_matrix(page, link_path(name)), expected.homogeneous, atol=TOL["matrix"]
        )
        local, world = page.evaluate(_VERTEX, name)
        np.testing.assert_allclose(world, expected.act(np.array(local)), atol=TOL["matrix"])
        assert np.linalg.norm(local) > 0.03  # a point away from O: rotation errors show
    platform = node_matrix(page, f"{ROOT}/overlays/platform_frame")
    fk = spm.forward_kinematics(np.radians(DEMO_DEG))
    np.testing.assert_allclose(platform[:3, :3], fk.R, atol=TOL["matrix"])


def test_colliding_links_are_black(live: tuple[Visualizer, Any]) -> None:
    viz, page = live
    q = colliding_q(viz.robot)
    pairs = show(viz, page, q)
    black = {name for pair in pairs for name in pair}
    assert {"proximal_2", "proximal_3"} <= black
    state = page.evaluate(_LINK_STATE, list(LINK_NAMES))
    for name in LINK_NAMES:
        visible = state[name]["colliding" if name in black else "free"]
        hidden = state[name]["free" if name in black else "colliding"]
        assert visible["visible"] and not hidden["visible"]
    colliding_image = capture(page)
    show(viz, page, np.radians(DEMO_DEG))
    safe_image = capture(page)
    state = page.evaluate(_LINK_STATE, list(LINK_NAMES))
    assert not any(state[name]["colliding"]["visible"] for name in LINK_NAMES)
    assert dark_pixels(colliding_image) > 500
    assert dark_pixels(safe_image) < 20
    # in the home mode, too
    pairs = show(viz, page, np.radians(HOME_COLLIDING_DEG))
    assert ("proximal_2", "proximal_3") in pairs
    show(viz, page, np.radians(DEMO_DEG))


def test_exported_html_renders_the_same_offline(
    live: tuple[Visualizer, Any], browser: Any, tmp_path: Path
) -> None:
    viz, page = live
    show(viz, page, colliding_q(viz.robot))
    viz.set_view("iso")  # a saved page opens framed on its pose: frame the live one too
    camera = viz.scene.property("/Cameras/default/rotated/<object>", "position")
    wait_until(
        lambda: np.allclose(
            page.evaluate("viewer.camera.position.toArray()"), camera, atol=TOL["matrix"]
        ),
        "the framed view",
    )
    served = capture(page)
    offline, blocked = open_offline(browser, viz.save_html(tmp_path / "scene.html"))
    try:
        saved = capture(offline)
        for name in LINK_NAMES:
            np.testing.assert_allclose(
                node_matrix(offline, link_path(name)),
                node_matrix(page, link_path(name)),
                atol=TOL["matrix"],
            )
    finally:
        offline.close()
        show(viz, page, np.radians(DEMO_DEG))
    assert blocked == [], f"the saved page asked the network for {blocked}"
    same = np.all(np.abs(served - saved) <= 8, axis=-1).mean()
    assert same >= TOL["same_pixels"], f"only {same:.2%} of the pixels agree"
    assert dark_pixels(saved) > 500  # the black links are in the file, too


def test_animation_seeks_to_the_right_pose(browser: Any, robot: SPMRobot, tmp_path: Path) -> None:
    viz = Visualizer(robot)
    path = np.linspace(0.0, 1.0, 11)[:, None] * np.radians(HOME_COLLIDING_DEG)
    motion = viz.animate(path, dt=0.1)
    assert motion.colliding_samples, "the motion should end in a collision"
    page, blocked = open_offline(browser, viz.save_html(tmp_path / "motion.html"))
    try:
        for k in (0, 4, 7, 10):
            assert page.evaluate(_SEEK, float(motion.times[k])) > 0
            for name in LINK_NAMES:
                np.testing.assert_allclose(
                    node_matrix(page, link_path(name)),
                    robot.placement(motion.q[k], name).homogeneous,
                    atol=TOL["matrix"],
                    err_msg=f"{name} at sample {k}",
                )
            state = page.evaluate(_LINK_STATE, list(LINK_NAMES))
            black = {name for pair in motion.collisions[k] for name in pair}
            assert {n for n in LINK_NAMES if state[n]["colliding"]["visible"]} == black
            assert {n for n in LINK_NAMES if not state[n]["free"]["visible"]} == black
        # half way between two samples, the platform is between their poses
        page.evaluate(_SEEK, float(0.5 * (motion.times[3] + motion.times[4])))
        middle = node_matrix(page, link_path("proximal_3"))[:3, :3]
        before, after = (robot.placement(motion.q[k], "proximal_3").rotation for k in (3, 4))
        gap = np.linalg.norm(before - after)
        assert np.linalg.norm(middle - before) < gap and np.linalg.norm(middle - after) < gap
    finally:
        page.close()
    assert blocked == []


def test_screenshot_of_a_saved_scene(browser: Any, robot: SPMRobot, tmp_path: Path) -> None:
    from PIL import Image

    viz = Visualizer(robot)
    viz.display(np.radians(DEMO_DEG))
    html = viz.save_html(tmp_path / "demo.html")
    png = screenshot(html, tmp_path / "demo.png", size=(320, 240), browser=browser)
    with Image.open(png) as image:
        assert image.size == (320, 240)
        pixels = np.asarray(image.convert("RGB"), dtype=np.int16)
    # some pixels have about the colour of leg 2's proximal link (orange)
    orange = np.all(np.abs(pixels - 255 * np.array(LINK_COLORS["proximal_2"][:3])) < 60, axis=-1)
    assert orange.sum() > 50
    match = r"^size must be \(width, height\) in pixels, each 16\.\.8192, got \(0, 240\)"
    with pytest.raises(spm.InputError, match=match):
        screenshot(html, tmp_path / "bad.png", size=(0, 240), browser=browser)
    with pytest.raises(FileNotFoundError, match=r"no such HTML file: .*missing\.html"):
        screenshot(tmp_path / "missing.html", tmp_path / "bad.png", browser=browser)
    with pytest.raises(spm.InputError, match=r"^timeout_s must be a positive number \[s\]"):
        screenshot(html, tmp_path / "bad.png", browser=browser, timeout_s=0.0)
    # with the overlays: the key at the top left, the same size, the controls hidden
    page = screenshot(html, tmp_path / "page.png", size=(320, 240), browser=browser, overlays=True)
    with Image.open(page) as image:
        assert image.size == (320, 240)
        overlaid = np.asarray(image.convert("RGB"), dtype=np.int16)
    changed = np.any(np.abs(overlaid - pixels) > 8, axis=-1)
    assert changed[:60, :100].mean() > 0.2  # the key
    # meshcat's control panel (a black bar at the top right) and the view buttons hidden
    assert not np.any(overlaid[:20, 200:].max(axis=-1) < 40)
    assert not changed[-20:, -60:].any()


def test_chromium_that_is_not_there(tmp_path: Path) -> None:
    from spm_pin.viz import ViewerError
    from spm_pin.viz.browser import chromium

    with (
        pytest.raises(ViewerError, match=r"^no Chromium at '.*no-chromium'"),
        chromium(tmp_path / "no-chromium"),
    ):
        pass


# ----------------------------------------------------------------- views and the key
#: Hides (false) or shows (true) the node at a meshcat path and redraws.
_SET_VISIBLE = f"""([path, visible]) => {{
    ({_FIND})(path).object.visible = visible;
    viewer.set_dirty();
}}"""
#: Smallest share of the view each distal link shows (not hidden by the others).
DISTAL_SHARE = 0.002


def changed_when_hidden(page: Any, path: str) -> np.ndarray:
    """Pixels (height, width) that change when the node at ``path`` is hidden."""
    parts = [part for part in path.split("/") if part]
    shown = capture(page)
    page.evaluate(_SET_VISIBLE, [parts, False])
    try:
        hidden = capture(page)
    finally:
        page.evaluate(_SET_VISIBLE, [parts, True])
    return np.any(np.abs(shown - hidden) > 8, axis=-1)


def distal_shares(page: Any) -> dict[str, float]:
    """Share of the view where each distal link is seen."""
    return {
        f"distal_{i}": float(changed_when_hidden(page, link_path(f"distal_{i}")).mean())
        for i in (1, 2, 3)
    }


def test_study_input_shows_the_key_and_all_three_legs(
    browser: Any, robot: SPMRobot, tmp_path: Path
) -> None:
    viz = Visualizer(robot, joint_axes=True, platform_frame=True)  # as the demo's scene
    viz.display(np.radians(DEMO_DEG))
    page, blocked = open_offline(browser, viz.save_html(tmp_path / "study.html"))
    try:
        assert page.evaluate("window.spm_view") == "iso"
        legs = page.locator("#spm-key li.spm-key-leg")
        assert legs.count() == 3
        assert [legs.nth(k).get_attribute("data-leg") for k in range(3)] == ["1", "2", "3"]
        assert all(legs.nth(k).is_visible() for k in range(3))
        axes = page.locator("#spm-key li.spm-key-axis")
        assert [axes.nth(k).get_attribute("data-axis") for k in range(axes.count())] == [
            "u",
            "w",
            "v",
            "frame",
        ]
        box = page.locator("#spm-key").bounding_box()
        assert box is not None and box["x"] >= 0 and box["y"] >= 0
        assert box["x"] + box["width"] <= VIEWPORT["width"]
        iso = distal_shares(page)
        # every leg's distal link is seen, each in its own colour somewhere
        image = capture(page)
        for i in (1, 2, 3):
            assert iso[f"distal_{i}"] > DISTAL_SHARE, iso
            for link in (f"proximal_{i}", f"distal_{i}"):
                rgb = 255 * np.array(LINK_COLORS[link][:3])
                near = np.all(np.abs(image - rgb) < 40, axis=-1).sum()
                assert near > 50, f"{link}: {near} pixels of its colour"
    finally:
        page.close()
    assert blocked == []
    # the old default camera (azimuth -30, elevation 20 deg: the platform edge-on)
    # showed the worst-seen distal link less
    viz.set_camera(azimuth=np.radians(-30.0), elevation=np.radians(20.0))
    page, _ = open_offline(browser, viz.save_html(tmp_path / "edge_on.html"))
    try:
        assert page.evaluate("window.spm_view === undefined")
        old = distal_shares(page)
    finally:
        page.close()
    assert min(iso.values()) > 1.2 * min(old.values()), (iso, old)


@pytest.mark.parametrize("name", ["iso", "top", "front", "side"])
def test_every_view_frames_the_mechanism(
    browser: Any, robot: SPMRobot, tmp_path: Path, name: str
) -> None:
    viz = Visualizer(robot, joint_axes=True)
    viz.display(np.radians(DEMO_DEG))
    page, _ = open_offline(browser, viz.save_html(tmp_path / "views.html"))
    try:
        page.click(f'#spm-views button[data-view="{name}"]')  # the page's button
        assert page.evaluate("window.spm_view") == name
        robot_pixels = changed_when_hidden(page, ROOT)
    finally:
        page.close()
    assert robot_pixels.mean() > TOL["robot_pixels"], f"{name}: {robot_pixels.mean():.1%}"
    rows, cols = np.nonzero(robot_pixels)
    height, width = robot_pixels.shape
    assert rows.min() > 0 and rows.max() < height - 1, f"{name}: cut at the top or bottom"
    assert cols.min() > 0 and cols.max() < width - 1, f"{name}: cut at a side"
    assert abs(0.5 * (rows.min() + rows.max()) - height / 2) < 0.1 * height


# ------------------------------------------------------------------------- contacts
#: Names of the visible children of the contacts node and the overlay's entries.
_CONTACTS = f"""() => {{
    const node = ({_FIND})(["meshcat", "spm", "contacts"]);
    const shown = [];
    if (node !== null) {{
        for (const [name, child] of Object.entries(node.children)) {{
            if (child.object.visible) shown.push(name);
        }}
    }}
    const list = document.getElementById("spm-contacts");
    const items = list === null ? [] : Array.from(list.querySelectorAll("li"));
    return {{shown: shown, items: items.map((li) => [li.className, li.dataset.pair || null,
                                                   li.dataset.depthMm || null, li.textContent])}};
}}"""


@pytest.mark.parametrize("theta_deg", [STUDY_COLLIDING_DEG, DEMO_DEG])
def test_contact_markers_in_the_saved_page(
    browser: Any, robot: SPMRobot, tmp_path: Path, theta_deg: list[float]
) -> None:
    """The study's colliding input: one visible marker node per colliding pair and its
    depth in mm in ``#spm-contacts``; the safe input: no marker, "no collision"."""
    viz = Visualizer(robot)
    viz.display(np.radians(theta_deg))
    truth = robot.collisions(viz.q)
    depths = {f"{a}-{b}": -1000.0 * d for (a, b), d in robot.distances(viz.q).items()}
    page, blocked = open_offline(browser, viz.save_html(tmp_path / "contacts.html"))
    try:
        state = page.evaluate(_CONTACTS)
    finally:
        page.close()
    assert blocked == []
    expected = sorted(f"{a}-{b}" for a, b in truth)
    assert sorted(state["shown"]) == expected
    contacts = [item for item in state["items"] if item[0] == "spm-contact"]
    assert sorted(item[1] for item in contacts) == expected
    for _, pair, depth_mm, text in contacts:
        assert float(depth_mm) == pytest.approx(depths[pair], abs=1e-3)
        assert text == f"{pair}: {depths[pair]:.1f} mm deep"
    if not truth:
        assert [item[0] for item in state["items"]] == ["spm-no-contact"]
    else:
        assert len(expected) >= 2
