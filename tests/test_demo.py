"""``spm demo``: the report's files, its numbers against independent computations, and
the run without the optional dependencies.

One real default run (``spm demo --out DIR --json``, as a user runs it) is shared by
most tests; the run without MuJoCo, matplotlib and meshcat uses the quick settings.
"""

from __future__ import annotations

import contextlib
import html.parser
import io
import json
import math
import os
import re
import struct
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import spm_pin as spm
from spm_pin.cli import main
from spm_pin.collision import check_input
from spm_pin.demo import (
    DEMO_SECTIONS,
    INSTALL_DEMO,
    MUJOCO_SETTLE_STEPS,
    DemoContext,
    mujoco_platform_axes,
)
from spm_pin.errors import InputError
from spm_pin.workspace import WorkspaceMap, gaps_from_theta

#: Tolerances, by what they compare. The cross-check tolerances restate the demo's
#: stated ones (spm_pin.demo: PROJECTION_TOLERANCE, MUJOCO_TOLERANCE["gravity"] and
#: ["no_gravity"], STUDY_AGREEMENT) so that loosening them there fails here.
TOL = {
    "json": 1e-12,  # a value in the record against the library's own value
    # Newton projection against the analytic axes: both solve the loops to 1e-12
    "projection": 1e-10,
    # MuJoCo upright against the analytic axes: the soft welds yield under the
    # platform's weight (about 1e-5 at the default settings)
    "mujoco": 1e-4,
    "mujoco_no_gravity": 1e-9,  # MuJoCo without load: the welds close to rounding
    "study": 4e-4,  # the study's agreement of computed and simulated axes (the paper)
    "torque": 1e-9,  # the record's torques against inverse dynamics recomputed [N m]
    "rotation": 1e-9,  # R R^T = I for MuJoCo's body orientations
}
#: The study's figures.
THETA_DEG = [60.0, 90.0, 120.0]
COLLIDING_DEG = [60.0, 90.0, 220.0]
SAMPLES = 25

SECTION_KEYS = [
    "design",
    "forward_kinematics",
    "assembly_modes",
    "velocity",
    "inverse",
    "motion",
    "colliding_input",
    "workspace",
    "torques",
]
RECORD_KEYS = [
    "spm_pin_version",
    "theta_deg",
    "colliding_theta_deg",
    *SECTION_KEYS,
    "skipped",
    "failed_checks",
    "timing_s",
    "runtime_s",
    "report",
]
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
URL = re.compile(r"https?://[^\s\"'<>)]*")
#: URLs allowed in a scene: XML namespace names in the inlined viewer, never fetched.
NAMESPACES = {"http://www.w3.org/1999/xhtml"}


# ------------------------------------------------------------------------ runs
@pytest.fixture(scope="module")
def default_run(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """``spm demo --out DIR --json``, the default settings, run once (in this process)."""
    out = tmp_path_factory.mktemp("demo") / "report"
    stdout, stderr = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(stdout), contextlib.redirect_stderr(stderr):
        status = main(["demo", "--out", str(out), "--json"])
    assert status == 0, stderr.getvalue()

    def no_constants(name: str) -> None:
        raise AssertionError(f"JSON output contains {name}")

    record = json.loads(stdout.getvalue(), parse_constant=no_constants)
    return {"out": out, "record": record, "stderr": stderr.getvalue()}


@pytest.fixture(scope="module")
def record(default_run: dict[str, Any]) -> dict[str, Any]:
    result: dict[str, Any] = default_run["record"]
    return result


@pytest.fixture(scope="module")
def out(default_run: dict[str, Any]) -> Path:
    path: Path = default_run["out"]
    return path


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    return spm.build_robot()


# ------------------------------------------------------------------ the record
def test_default_run_is_complete(default_run: dict[str, Any]) -> None:
    """Every section ran and reported; how long it took is the benchmarks' business
    (docs/demo.md: about 15 s), so the record's times are checked for form only."""
    record = default_run["record"]
    assert list(record) == RECORD_KEYS
    assert list(record["timing_s"]) == [*SECTION_KEYS, "pictures"]
    times = [*record["timing_s"].values(), record["runtime_s"]]
    assert all(isinstance(t, float) and math.isfinite(t) for t in times)
    assert min(times) >= 0.0 and sum(record["timing_s"].values()) <= record["runtime_s"]
    assert record["skipped"] == []  # the test extra brings every optional dependency
    assert record["failed_checks"] == []
    assert record["theta_deg"] == THETA_DEG
    assert record["colliding_theta_deg"] == COLLIDING_DEG
    assert record["design"]["name"] == "prototype"
    # progress went to stderr, one line per section, and stdout is the JSON alone
    progress = default_run["stderr"].splitlines()
    assert len([line for line in progress if line.startswith("spm demo [")]) == len(DEMO_SECTIONS)


def test_demo_json_file_is_the_record(out: Path, record: dict[str, Any]) -> None:
    assert json.loads((out / "demo.json").read_text()) == record
    assert record["report"]["index_html"] == str(out / "index.html")


def test_forward_kinematics_three_ways(record: dict[str, Any], robot: spm.SPMRobot) -> None:
    fk_data = record["forward_kinematics"]
    theta = np.radians(THETA_DEG)
    fk = spm.forward_kinematics(theta)
    methods = fk_data["methods"]
    assert set(methods) == {"analytic", "projection", "mujoco", "mujoco_no_gravity"}
    np.testing.assert_allclose(methods["analytic"]["v"], fk.v, atol=TOL["json"])
    np.testing.assert_allclose(fk_data["R"], fk.R, atol=TOL["json"])
    assert fk_data["mode"] == "+++/-"
    # Newton projection, recomputed here from home with the public API
    projection = spm.ClosedLoop.from_robot(robot).project(theta)
    R = np.array(robot.placement(projection.q, "platform").rotation)
    v_projection = np.einsum("jk,ik->ij", R, robot.design.v0)
    np.testing.assert_allclose(methods["projection"]["v"], v_projection, atol=TOL["json"])
    np.testing.assert_allclose(methods["projection"]["v"], fk.v, atol=TOL["projection"])
    assert methods["projection"]["residual"] <= 1e-12
    # MuJoCo: within its stated tolerance; its soft welds yield under gravity only
    np.testing.assert_allclose(methods["mujoco"]["v"], fk.v, atol=TOL["mujoco"])
    np.testing.assert_allclose(
        methods["mujoco_no_gravity"]["v"], fk.v, atol=TOL["mujoco_no_gravity"]
    )
    upright = methods["mujoco"]["deviation_from_analytic"]
    unloaded = methods["mujoco_no_gravity"]["deviation_from_analytic"]
    assert unloaded < 1e-3 * upright < TOL["study"]
    assert (
        methods["mujoco"]["weld_opening_rad"]
        > 1e3 * methods["mujoco_no_gravity"]["weld_opening_rad"]
    )
    for key in ("projection", "mujoco", "mujoco_no_gravity"):
        deviation = np.abs(np.array(methods[key]["v"]) - fk.v).max()
        assert methods[key]["deviation_from_analytic"] == pytest.approx(deviation, abs=1e-15)
    assert fk_data["within_tolerance"] == {
        "projection": True,
        "mujoco": True,
        "mujoco_no_gravity": True,
    }
    assert fk_data["study_agreement"] == TOL["study"]


def test_motion_25_samples(record: dict[str, Any], robot: spm.SPMRobot) -> None:
    motion = record["motion"]
    assert motion["samples"] == len(motion["path"]) == SAMPLES
    assert motion["all_home"] is True and motion["lost"] is False
    path = np.linspace(0.0, 1.0, SAMPLES)[:, None] * np.radians(THETA_DEG)
    theta_deg = np.array([sample["theta_deg"] for sample in motion["path"]])
    np.testing.assert_allclose(theta_deg, np.degrees(path), atol=TOL["json"])
    fk = spm.forward_kinematics(path)  # each sample solved on its own
    v = np.array([sample["v"] for sample in motion["path"]])
    v_projection = np.array([sample["v_projection"] for sample in motion["path"]])
    v_mujoco = np.array([sample["v_mujoco"] for sample in motion["path"]])
    np.testing.assert_allclose(v, fk.v, atol=1e-9)
    np.testing.assert_allclose(v_projection, fk.v, atol=TOL["projection"])
    np.testing.assert_allclose(v_mujoco, fk.v, atol=TOL["mujoco"])
    np.testing.assert_allclose(v[0], robot.design.v0, atol=TOL["json"])
    # the motion's last sample is the demonstration input of the first section
    np.testing.assert_allclose(
        v_mujoco[-1], record["forward_kinematics"]["methods"]["mujoco"]["v"], atol=TOL["json"]
    )
    assert motion["max_deviation_projection"] <= TOL["projection"]
    assert motion["within_tolerance"] == {"projection": True, "mujoco": True}
    assert motion["plot"] == "motion_axes.png"
    assert motion["scene"] == "scenes/motion.html"


def test_colliding_input(record: dict[str, Any], robot: spm.SPMRobot) -> None:
    data = record["colliding_input"]
    theta = np.radians(COLLIDING_DEG)
    assert data["theta_deg"] == COLLIDING_DEG
    assert data["home_mode_exists"] is False
    report = check_input(theta, robot)
    assert data["mode"] == report.mode == "++-/-"
    assert "++-/-" in data["checked"]
    q = robot.configuration(theta, mode=data["mode"])
    pairs = [list(pair) for pair in robot.collisions(q)]
    assert data["pairs"] == pairs and pairs
    assert ["proximal_2", "proximal_3"] in pairs
    links = sorted({name for pair in pairs for name in pair})
    assert data["links"] == links
    assert data["drawn_black"] == links
    assert data["collision"] is True
    assert data["min_distance_m"] < 0.0
    np.testing.assert_allclose(data["gaps_deg"], gaps_from_theta(theta), atol=TOL["json"])


def test_safe_workspace(record: dict[str, Any], out: Path, robot: spm.SPMRobot) -> None:
    data = record["workspace"]
    assert data["step_deg"] == 2.0
    assert 0.0 < data["safe_fraction"] < data["reachable_fraction"] < 1.0
    saved = WorkspaceMap.load(out / "workspace")
    assert len(saved) == data["points"]
    assert saved.summary()["safe_fraction"] == data["safe_fraction"]
    # the demonstration input, checked directly, and on the map
    theta = np.radians(THETA_DEG)
    jac = spm.jacobian(theta)
    assert robot.collisions(theta) == []
    assert data["demo_input"]["safe"] is (float(jac.dexterity) >= 0.2)
    assert data["demo_input"]["safe"] is True
    d12, d23, _ = gaps_from_theta(theta)
    nearest = np.argmin(np.hypot(saved["d12_deg"] - d12, saved["d23_deg"] - d23))
    assert bool(saved["safe"][nearest])
    assert data["motion_safe_samples"] == SAMPLES


def test_torques_against_inverse_dynamics(record: dict[str, Any]) -> None:
    data = record["torques"]
    motion = spm.Trajectory.minimum_jerk(np.zeros(3), np.radians(THETA_DEG), 1.0, 500.0)
    result = spm.inverse_dynamics(None, motion)
    check = spm.check_servo(result.torque, result.theta_dot, time=motion.time)
    assert data["trajectory"]["samples"] == motion.time.shape[0]
    np.testing.assert_allclose(data["peak_torque_nm"], check.peak_torque, atol=TOL["torque"])
    np.testing.assert_allclose(data["rms_torque_nm"], check.rms_torque, atol=TOL["torque"])
    assert data["within_limits"] is check.within_limits is True
    assert data["verdict"] == check.message
    assert data["verdict"].startswith("OK")
    assert data["plot"] == "torques.png"


# ------------------------------------------------------------------------ files
#: HTML elements without an end tag.
VOID_ELEMENTS = frozenset({"meta", "img", "br", "hr", "link", "input", "source"})


class _Checker(html.parser.HTMLParser):
    """Checks that every element is closed in order and collects references."""

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.errors: list[str] = []
        self.images: list[str] = []
        self.frames: list[str] = []
        self.links: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        values = dict(attrs)
        if tag == "img":
            self.images.append(str(values["src"]))
        elif tag == "iframe":
            self.frames.append(str(values["src"]))
        elif tag == "a":
            self.links.append(str(values["href"]))
        if tag not in VOID_ELEMENTS:
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if not self.stack or self.stack[-1] != tag:
            self.errors.append(f"</{tag}> closes {self.stack[-1:] or 'nothing'}")
        else:
            self.stack.pop()


def _parse(path: Path) -> _Checker:
    checker = _Checker()
    checker.feed(path.read_text(encoding="utf-8"))
    checker.close()
    assert checker.errors == [] and checker.stack == [], (checker.errors, checker.stack)
    return checker


def _png_size(path: Path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == PNG_SIGNATURE, f"{path} is not a PNG"
    assert data[12:16] == b"IHDR"
    width, height = struct.unpack(">II", data[16:24])
    return width, height


def test_report_files(out: Path, record: dict[str, Any]) -> None:
    index = _parse(out / "index.html")
    text = (out / "index.html").read_text(encoding="utf-8")
    assert URL.findall(text) == []  # nothing to fetch
    assert index.frames == [
        "scenes/demo_input.html",
        "scenes/motion.html",
        "scenes/colliding_input.html",
    ]
    assert set(index.images) >= {
        "motion_axes.png",
        "safe_workspace.png",
        "workspace/gap_map.png",
        "workspace/orientation.png",
        "torques.png",
    }
    for image in index.images:
        width, height = _png_size(out / image)
        assert width > 300 and height > 300
    for link in index.links:
        if not link.startswith("#"):
            assert (out / link).is_file(), link
    for name in record["report"]["files"]:
        assert (out / name).is_file(), name


class _Tables(html.parser.HTMLParser):
    """The report's tables by class (rows of cell texts) and its preformatted blocks."""

    def __init__(self) -> None:
        super().__init__()
        self.tables: dict[str, list[list[str]]] = {}
        self.pre: list[str] = []
        self._table: list[list[str]] | None = None
        self._cell: list[str] | None = None
        self._in_pre = False

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        if tag == "table":
            self._table = self.tables.setdefault(str(dict(attrs).get("class")), [])
        elif tag == "tr" and self._table is not None:
            self._table.append([])
        elif tag in ("td", "th"):
            self._cell = []
        elif tag == "pre":
            self._in_pre = True
            self.pre.append("")

    def handle_endtag(self, tag: str) -> None:
        if tag in ("td", "th") and self._cell is not None and self._table:
            self._table[-1].append("".join(self._cell).strip())
            self._cell = None
        elif tag == "table":
            self._table = None
        elif tag == "pre":
            self._in_pre = False

    def handle_data(self, data: str) -> None:
        if self._cell is not None:
            self._cell.append(data)
        if self._in_pre:
            self.pre[-1] += data


def test_report_tables(out: Path, record: dict[str, Any]) -> None:
    """The report is tables, not text dumps: the assembly modes one row each under
    unique labels, the motion's samples, the torque verdict once with what limits it."""
    text = (out / "index.html").read_text(encoding="utf-8")
    report = _Tables()
    report.feed(text)
    assert all(len(block.splitlines()) <= 10 for block in report.pre), report.pre
    assert report.pre == []
    # every real assembly mode, one row each (after two heading rows), labels unique
    modes = [row[0] for row in report.tables["modes"][2:]]
    assert modes == [mode["label"] for mode in record["assembly_modes"]["modes"]]
    assert len(set(modes)) == len(modes) == record["assembly_modes"]["count"] == 8
    # the forward kinematics: one row per method, no repeat of the table as text
    fk = [row[0] for row in report.tables["fk"][2:]]
    assert fk == ["analytic (closed form)", "Newton projection", "MuJoCo (upright)",
                  "MuJoCo (no gravity)"]  # fmt: skip
    assert "max |v - v_analytic|" not in text
    # v_1 x of the analytic axes: in the rows of the methods that agree to 1e-6 only
    methods = record["forward_kinematics"]["methods"].values()
    agree = sum(f"{m['v'][0][0]:.6f}" == "-0.862372" for m in methods)
    assert text.count("-0.862372") == agree == 3
    # the motion: the shown samples in a table whose last row is the input
    samples = report.tables["samples"][2:]
    assert [row[0] for row in samples] == ["0", "6", "12", "18", "24"]
    assert samples[-1][1] == "60, 90, 120"
    # the torques: the verdict once, the limit named
    torques = record["torques"]
    assert text.count(html.escape(torques["verdict"])) == 1
    load = f"{100.0 * torques['max_utilisation']:.1f}%"
    assert load == "70.5%" and text.count(load) == 1
    assert torques["limiting_factor"] == "speed"
    assert "set by speed, not torque" in text
    joints = {row[0]: row[1:] for row in report.tables["joints"]}
    np.testing.assert_allclose(
        [float(x) for x in joints["peak |speed| [rpm]"]], torques["peak_speed_rpm"], atol=5e-3
    )
    pairs = report.tables["pairs"][1:]
    assert pairs == record["colliding_input"]["pairs"]


def test_report_figures(out: Path, record: dict[str, Any]) -> None:
    """The safe-workspace map's legend lists only what the map shows, and the captions
    name the colours the figures use."""
    pytest.importorskip("matplotlib")
    from matplotlib.patches import Patch

    from spm_pin.study.context import DemoContext as Context
    from spm_pin.study.plots import SAFE_CATEGORIES, plot_safe_workspace

    saved = WorkspaceMap.load(out / "workspace")
    gaps = np.array([sample["theta_deg"] for sample in record["motion"]["path"]])
    gaps = gaps_from_theta(np.radians(gaps))
    figure = plot_safe_workspace(
        None, saved, gaps, gaps_from_theta(np.radians(COLLIDING_DEG)), Context()
    )
    (axis,) = figure.axes
    legend = axis.get_legend()
    patches = [h.get_label() for h in legend.legend_handles if isinstance(h, Patch)]
    f = saved.fields
    present = {
        "no home-mode assembly": bool(np.any(~f["reachable"])),
        "links collide": bool(np.any(f["reachable"] & f["collision"])),
        "dexterity too low": bool(np.any(f["reachable"] & ~f["collision"] & ~f["safe"])),
        "safe": bool(np.any(f["safe"])),
    }
    assert patches == [label for _, _, label in SAFE_CATEGORIES if present[label]]
    assert "dexterity too low" not in patches  # no such point at the prototype's settings
    for handle, label in zip(*axis.get_legend_handles_labels(), strict=True):
        assert np.isfinite(np.atleast_1d(handle.get_xdata())).any(), label
    motion = [line for line in axis.get_lines() if line.get_label() == "the motion from home"]
    assert motion[0].get_color() == "k"
    text = (out / "index.html").read_text(encoding="utf-8")
    assert "the motion from home (black dots on a white line)" in text
    assert "motion (white)" not in text


def test_scenes_are_self_contained(out: Path) -> None:
    sizes = set()
    for frame in ("demo_input", "motion", "colliding_input"):
        path = out / "scenes" / f"{frame}.html"
        _parse(path)
        text = path.read_text(encoding="utf-8")
        assert set(URL.findall(text)) <= NAMESPACES, path
        assert re.search(r"""(src|href)\s*=\s*["']?\s*(https?:)?//""", text) is None
        assert "spm_scene_ready" in text
        sizes.add(len(text))
    assert len(sizes) >= 2  # not one scene three times


# -------------------------------------------------------------- the browser
def _on_ci() -> bool:
    return os.environ.get("CI", "").strip().lower() in {"1", "true", "yes"}


@pytest.mark.browser
def test_report_offline_in_chromium(out: Path, record: dict[str, Any]) -> None:
    """index.html in a real browser, every request outside the report refused: the three
    scenes build, and the colliding scene shows exactly the colliding links in black."""
    from spm_pin.viz.browser import find_chromium

    if find_chromium() is None:
        if _on_ci():
            pytest.fail("no Chromium; under CI the browser tests must run")
        pytest.skip("no Chromium on the PATH")
    try:
        import playwright  # noqa: F401
    except ImportError:
        if _on_ci():
            pytest.fail("no Playwright; under CI the browser tests must run")
        pytest.skip("Playwright is not installed")
    from spm_pin.viz.browser import chromium

    folder = out.resolve().as_uri() + "/"
    refused: list[str] = []

    def route(request_route: Any) -> None:
        if request_route.request.url.startswith(folder):
            request_route.continue_()
        else:
            refused.append(request_route.request.url)
            request_route.abort()

    with chromium() as browser:
        page = browser.new_page(viewport={"width": 1000, "height": 800})
        errors: list[str] = []
        page.on("pageerror", lambda error: errors.append(str(error)))
        page.route("**/*", route)
        page.goto(folder + "index.html")
        for frame in page.locator("iframe").all():
            frame.scroll_into_view_if_needed()
        frames = {Path(f.url).stem: f for f in page.frames if f != page.main_frame}
        assert set(frames) == {"demo_input", "motion", "colliding_input"}
        for frame in frames.values():
            frame.wait_for_function("() => window.spm_scene_ready === true", timeout=60_000)
        black = frames["colliding_input"].evaluate(
            """() => {
                const links = viewer.scene_tree.children["meshcat"].children["spm"]
                    .children["links"].children;
                return Object.keys(links).filter(
                    (name) => links[name].children["colliding"].object.visible);
            }"""
        )
        page.close()
    assert sorted(black) == record["colliding_input"]["drawn_black"]
    assert refused == []
    assert errors == []


#: The scenes of the report and the pictures beside them.
PICTURES = {
    f"scenes/{name}.html": f"scenes/{name}.png"
    for name in ("demo_input", "motion", "colliding_input")
}
#: What the pictures are checked for: their size [px]; the share of pixels that differ
#: by more than ``background_step`` (0-255) from their row's median (the background's
#: vertical gradient and grid); the share of near-black pixels (every channel below
#: ``dark``) inside the middle of the picture, away from the key and captions.
PICTURE = {
    "size": (960, 720),
    "background_step": 40,
    "drawn_share": 0.05,
    "dark": 50,
    "dark_share_colliding": 0.01,
    "dark_ratio": 20.0,
}


def _rgb(path: Path) -> np.ndarray:
    from PIL import Image

    with Image.open(path) as image:
        assert image.size == PICTURE["size"], path
        return np.asarray(image.convert("RGB"), dtype=np.int16)


def _dark_share(pixels: np.ndarray) -> float:
    height, width, _ = pixels.shape
    middle = pixels[height // 5 : 6 * height // 7, width // 5 : 4 * width // 5]
    return float((middle.max(axis=-1) < PICTURE["dark"]).mean())


def test_scene_pictures(out: Path, record: dict[str, Any]) -> None:
    """A picture of each 3-D scene beside it and in the report, linking to the scene:
    not blank, and the colliding input's picture shows its near-black links."""
    report = record["report"]
    if not report["pictures"]:
        if _on_ci():
            pytest.fail(f"no pictures under CI: {report['pictures_note']}")
        pytest.skip(f"no pictures: {report['pictures_note']}")
    assert report["pictures"] == PICTURES
    assert report["pictures_note"] is None
    assert set(PICTURES.values()) <= set(report["files"])
    assert 0.0 < record["timing_s"]["pictures"] < record["runtime_s"]
    pixels = {}
    for scene, picture in PICTURES.items():
        pixels[scene] = _rgb(out / picture)
        median = np.median(pixels[scene], axis=1, keepdims=True)
        drawn = np.abs(pixels[scene] - median).max(axis=-1) > PICTURE["background_step"]
        assert drawn.mean() > PICTURE["drawn_share"], (picture, drawn.mean())
    assert len({p.tobytes() for p in pixels.values()}) == len(PICTURES)
    colliding = _dark_share(pixels["scenes/colliding_input.html"])
    safe = _dark_share(pixels["scenes/demo_input.html"])
    assert colliding > PICTURE["dark_share_colliding"], colliding
    assert colliding > PICTURE["dark_ratio"] * safe, (colliding, safe)
    # in the report: each picture in a link to its scene, with alt text and a caption
    text = (out / "index.html").read_text(encoding="utf-8")
    for scene, picture in PICTURES.items():
        match = re.search(
            rf'<figure><div class="pair"><a href="{scene}"><img src="{picture}" '
            r'width="960" height="720" alt="Picture of the 3-D scene: ([^"]+)"></a>'
            rf'<iframe src="{scene}" [^>]*></iframe></div><figcaption>([^<]+)',
            text,
        )
        assert match is not None, picture
        alt, caption = match.groups()
        assert caption.startswith(alt), (alt, caption)
    assert text.count("First a picture of the scene (it reads without WebGL)") == len(PICTURES)
    assert "No pictures" not in text
    motion = record["motion"]["path"][(SAMPLES - 1) // 2]["theta_deg"]
    np.testing.assert_allclose(motion, [30.0, 45.0, 60.0], atol=TOL["json"])
    assert "The picture shows sample 12, theta = [30, 45, 60] deg." in text


def test_pictures_turned_off_or_without_a_browser(tmp_path: Path) -> None:
    """No picture when turned off or without a Chromium: one line says why, nothing
    fails (the demo run without a browser is tests/test_cli.py::test_demo_text)."""
    from spm_pin.study import DemoSection, ReportItem
    from spm_pin.study.pictures import INSTALL_PICTURES, take_pictures
    from spm_pin.study.report import report_html

    scene = tmp_path / "scenes" / "one.html"
    scene.parent.mkdir()
    scene.write_text("<!DOCTYPE html><html></html>", encoding="utf-8")
    section = DemoSection("one", "One", {}, scenes=(ReportItem("scenes/one.html", "One."),))
    off = take_pictures(DemoContext(out=tmp_path, pictures=False), [section])
    assert off.files == {} and off.note == "No pictures of the 3-D scenes: turned off."
    missing = tmp_path / "no-chromium"
    absent = take_pictures(DemoContext(out=tmp_path, chromium=missing), [section])
    assert absent.files == {}
    assert absent.note is not None and absent.note.startswith("No pictures of the 3-D scenes: ")
    assert absent.note.endswith(f"They need Playwright and a Chromium: {INSTALL_PICTURES}.")
    assert take_pictures(DemoContext(pictures=False), [section]).note is None  # no folder
    page = report_html(DemoContext(out=tmp_path), [section], [], 1.0, absent)
    assert page.count(html.escape(absent.note)) == 1
    assert "<img" not in page and '<iframe src="scenes/one.html"' in page
    assert not list(tmp_path.rglob("*.png"))
    with pytest.raises(InputError, match=r"pictures must be True or False, got 'no'"):
        DemoContext(pictures="no")  # type: ignore[arg-type]


# ------------------------------------------------- without optional dependencies
def test_without_optional_dependencies(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    for module in ("mujoco", "matplotlib", "meshcat"):
        monkeypatch.setitem(sys.modules, module, None)  # import fails as if not installed
    out = tmp_path / "report"
    status = main(["demo", "--quick", "--quiet", "--out", str(out)])
    text, err = capsys.readouterr()
    assert status == 0
    assert err == ""  # --quiet
    data = json.loads((out / "demo.json").read_text())
    missing = {item["missing"] for item in data["skipped"]}
    assert missing == {"mujoco", "matplotlib", "meshcat"}
    assert all(INSTALL_DEMO in item["install"] for item in data["skipped"])
    assert f"install them with: {INSTALL_DEMO}" in text
    # everything else ran
    methods = data["forward_kinematics"]["methods"]
    assert methods["mujoco"] is None and methods["mujoco_no_gravity"] is None
    fk = spm.forward_kinematics(np.radians(THETA_DEG))
    np.testing.assert_allclose(methods["projection"]["v"], fk.v, atol=TOL["projection"])
    assert data["motion"]["samples"] == SAMPLES and data["motion"]["plot"] is None
    assert data["colliding_input"]["pairs"] and data["colliding_input"]["scene"] is None
    assert data["workspace"]["step_deg"] == 10.0 and data["workspace"]["plots"] == []
    assert data["torques"]["within_limits"] is True and data["torques"]["plot"] is None
    # the report says what was skipped and references no missing file
    index = _parse(out / "index.html")
    assert index.frames == [] and index.images == []
    assert "Skipped" in (out / "index.html").read_text(encoding="utf-8")
    assert not list(out.glob("*.png")) and not (out / "scenes").exists()


# ----------------------------------------------------------------- MuJoCo helper
def test_mujoco_platform_axes(robot: spm.SPMRobot) -> None:
    path = np.linspace(0.0, 1.0, 4)[:, None] * np.radians([20.0, -10.0, 5.0])
    fk = spm.forward_kinematics(path)
    free = mujoco_platform_axes(path, robot, gravity=(0.0, 0.0, 0.0))
    upright = mujoco_platform_axes(path, robot)
    np.testing.assert_allclose(free.v, fk.v, atol=TOL["mujoco_no_gravity"])
    np.testing.assert_allclose(upright.v, fk.v, atol=TOL["mujoco"])
    assert np.abs(upright.v - fk.v).max() > 1e3 * np.abs(free.v - fk.v).max()
    assert free.steps == upright.steps == 4 * MUJOCO_SETTLE_STEPS
    np.testing.assert_allclose(
        free.R @ np.swapaxes(free.R, -1, -2),
        np.broadcast_to(np.eye(3), (4, 3, 3)),
        atol=TOL["rotation"],
    )


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"path": np.zeros((2, 2))}, r"path must be .* shape \(N, 3\) .* got shape \(2, 2\)"),
        ({"path": [[0.0, np.nan, 0.0]]}, r"path must be finite input angles"),
        ({"settle_steps": 1}, r"settle_steps must be an integer >= 2, got 1"),
        ({"timestep": 0.0}, r"timestep must be positive \[s\], got 0\.0"),
        ({"gravity": (0.0, 9.81)}, r"gravity must be 3 finite numbers"),
        ({"mjcf": "no/such/file.xml"}, r"MJCF file 'no/such/file\.xml' does not exist"),
    ],
    ids=["shape", "nan", "settle_steps", "timestep", "gravity", "mjcf"],
)
def test_mujoco_platform_axes_bad_input(
    robot: spm.SPMRobot, kwargs: dict[str, Any], message: str
) -> None:
    arguments: dict[str, Any] = {"path": np.zeros((1, 3)), **kwargs}
    with pytest.raises(InputError, match=message):
        mujoco_platform_axes(robot=robot, **arguments)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"samples": 1}, r"samples must be an integer >= 2, got 1"),
        ({"workspace_step_deg": 0.0}, r"workspace_step_deg must be a positive number, got 0\.0"),
        ({"theta_deg": (0.0, 1.0)}, r"theta_deg must be three finite angles \[deg\]"),
    ],
    ids=["samples", "step", "theta"],
)
def test_bad_context(changes: dict[str, Any], message: str) -> None:
    with pytest.raises(InputError, match=message):
        DemoContext(**changes)


def test_failed_cross_check_exits_1(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    """A tolerance no solver can meet: the demo still reports, and exits with status 1."""
    import spm_pin.study.sections

    for module in ("mujoco", "matplotlib", "meshcat"):  # keep this run short
        monkeypatch.setitem(sys.modules, module, None)
    # the sections read the tolerance (spm_pin.study.context defines it)
    monkeypatch.setattr(spm_pin.study.sections, "PROJECTION_TOLERANCE", 0.0)
    status = main(["demo", "--quick", "--quiet", "--out", str(tmp_path)])
    text, err = capsys.readouterr()
    assert status == 1
    failed = ["forward_kinematics: projection", "motion: projection"]
    assert json.loads((tmp_path / "demo.json").read_text())["failed_checks"] == failed
    assert re.search(r"^Newton projection: .*; OUTSIDE the tolerance 0$", text, re.MULTILINE)
    assert err == f"spm: warning: cross-checks outside their tolerance: {', '.join(failed)}\n"
