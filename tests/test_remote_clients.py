"""The clients of the remote interface that are not Python, run as users run them.

Each client talks to a real server (uvicorn in a thread, on a free loopback port)
and what it reports is checked against the library run in this process (forward and
inverse kinematics, the robot's collision checks, the safety guard) and against
what the server's backend holds:

- curl: the ``bash`` blocks of docs/remote.md between ``<!-- curl-session: begin -->``
  and ``<!-- curl-session: end -->`` are run command by command with the server's
  address in place of ``http://127.0.0.1:8750``; each command's documented output
  (the ``#`` lines under it) must match the real answer.
- GNU Octave (standing in for MATLAB): examples/remote_matlab/study_remote.m.
- Chromium (Playwright): examples/remote_client.html, served from another origin,
  with the server's opt-in CORS.
- ROS 2 (documented only): its snippet compiles and is not run by the docs test.

Locally a missing curl, Octave, Chromium or Playwright skips its tests; under CI
(``CI=true``) they fail instead.
"""

from __future__ import annotations

import contextlib
import functools
import http.server
import json
import os
import re
import shlex
import shutil
import socket
import subprocess
import threading
import time
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pytest

pytest.importorskip("fastapi")
pytest.importorskip("uvicorn")
httpx = pytest.importorskip("httpx")

import uvicorn  # noqa: E402
from _remote_truth import SAFE_DEG, STUDY_COLLISION_DEG, STUDY_COLLISION_PAIRS, TOL  # noqa: E402
from conftest import missing_dependency  # noqa: E402

import spm_pin as spm  # noqa: E402
from spm_pin.errors import InputError  # noqa: E402
from spm_pin.hardware.guard import SafetyGuard  # noqa: E402
from spm_pin.remote import BackgroundServer, KinematicBackend, create_app  # noqa: E402
from spm_pin.rotations import matrix_from_rpy, rpy_from_matrix  # noqa: E402

ROOT = Path(__file__).resolve().parent.parent
DOC = ROOT / "docs" / "remote.md"
EXAMPLES = ROOT / "examples"
MATLAB_DIR = EXAMPLES / "remote_matlab"
DOCUMENTED_URL = "http://127.0.0.1:8750"
TOKEN = "test-token-0123456789abcdef"
#: Seconds: a server to start, one request, one client program (curl, Octave).
STARTUP_TIMEOUT = 90.0
REQUEST_TIMEOUT = 30.0
PROGRAM_TIMEOUT = 120.0
#: Milliseconds for the page to show a change (a loaded 2-core machine).
PAGE_TIMEOUT_MS = 30_000
#: Tolerances beyond _remote_truth.TOL, by what is compared.
PRINTED = {
    "octave_deg": 1e-8,  # angles Octave prints with 9 decimals [deg]
    "page_deg": 0.005 + 1e-9,  # angles the page shows with 2 decimals [deg]
}
#: An orientation goal of the docs [deg].
DOC_RPY_DEG = [10.0, -5.0, 30.0]


# ----------------------------------------------------------------------- servers
class _Serving:
    """uvicorn serving ``app`` in a thread, on a socket bound here to a free port
    (for applications that BackgroundServer does not build, e.g. with CORS)."""

    def __init__(self, app: Any) -> None:
        self.socket = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.socket.bind(("127.0.0.1", 0))
        self.url = f"http://127.0.0.1:{self.socket.getsockname()[1]}"
        self.server = uvicorn.Server(uvicorn.Config(app, log_level="warning"))
        self.thread = threading.Thread(
            target=self.server.run, kwargs={"sockets": [self.socket]}, daemon=True
        )

    def __enter__(self) -> _Serving:
        self.thread.start()
        deadline = time.monotonic() + STARTUP_TIMEOUT
        while not self.server.started:
            assert self.thread.is_alive() and time.monotonic() < deadline, "no server"
            time.sleep(0.01)
        return self

    def __exit__(self, *exc: object) -> None:
        self.server.should_exit = True
        self.thread.join(REQUEST_TIMEOUT)
        self.socket.close()


@pytest.fixture(scope="module")
def robot() -> spm.SPMRobot:
    """The prototype, built in this process: the independent truth (and shared by the
    backends, so each test gets a fresh twin at home quickly)."""
    return spm.build_robot()


@pytest.fixture()
def backend(robot: spm.SPMRobot) -> KinematicBackend:
    return KinematicBackend(robot=robot)


@pytest.fixture()
def server(backend: KinematicBackend) -> Iterator[BackgroundServer]:
    """A fresh twin at home, served on a free loopback port."""
    with BackgroundServer(backend, timeout=STARTUP_TIMEOUT) as running:
        yield running


def _no_nan(constant: str) -> Any:
    raise AssertionError(f"the server sent {constant}, which is not JSON")


def _json(text: str) -> Any:
    return json.loads(text, parse_constant=_no_nan)


def _needs(program: str) -> str:
    path = shutil.which(program)
    if path is None:
        missing_dependency(f"no {program} on the PATH (Debian: apt install {program})")
    return path


# ------------------------------------------------- documented outputs, matched loosely
class _Printed(float):
    """A number as the docs print it: matches within half a unit of its last digit."""

    places: int

    def __new__(cls, text: str) -> _Printed:
        number = super().__new__(cls, text)
        mantissa = text.lower().split("e")[0]
        number.places = len(mantissa.split(".")[1]) if "." in mantissa else 0
        return number


_ANY = "\x00any"  # `"key":...`: any value
_MORE = "\x00more"  # `..., ...]` or `{..., ...}`: more items or keys


def _loose_json(text: str) -> Any:
    """A documented output: JSON in which ``...`` stands for more items or keys (in a
    list or object) or for any value (after a colon); numbers keep their printed
    precision; inside a string, ``...`` stands for any text."""
    out: list[str] = []
    stack: list[str] = []
    last = ""  # the last significant character outside strings
    more = 0
    i = 0
    while i < len(text):
        char = text[i]
        if char == '"':
            end = i + 1
            while text[end] != '"':
                end += 2 if text[end] == "\\" else 1
            out.append(text[i : end + 1])
            last, i = '"', end + 1
            continue
        if text.startswith("...", i):
            if last == ":":
                out.append(json.dumps(_ANY))
            elif stack and stack[-1] == "{":
                more += 1
                out.append(f"{json.dumps(_MORE + str(more))}: null")
            else:
                out.append(json.dumps(_MORE))
            last, i = '"', i + 3
            continue
        if char in "[{":
            stack.append(char)
        elif char in "]}":
            stack.pop()
        if not char.isspace():
            last = char
        out.append(char)
        i += 1
    return json.loads("".join(out), parse_float=_Printed, parse_int=_Printed)


def _mismatches(doc: Any, real: Any, where: str = "") -> list[str]:
    """How a real answer differs from its documented output (empty: it matches)."""
    if isinstance(doc, str) and doc == _ANY:
        return []
    if isinstance(doc, dict):
        if not isinstance(real, dict):
            return [f"{where}: documented an object, got {real!r}"]
        keys = [key for key in doc if not key.startswith(_MORE)]
        found = []
        if len(keys) == len(doc) and set(real) != set(keys):
            found.append(f"{where}: keys {sorted(real)}, documented {sorted(keys)}")
        for key in keys:
            if key not in real:
                found.append(f"{where}: no key {key!r}")
            else:
                found += _mismatches(doc[key], real[key], f"{where}.{key}")
        return found
    if isinstance(doc, list):
        items = [item for item in doc if not (isinstance(item, str) and item == _MORE)]
        if not isinstance(real, list):
            return [f"{where}: documented a list, got {real!r}"]
        if len(real) < len(items) or (len(items) == len(doc) and len(real) != len(items)):
            return [f"{where}: {len(real)} items, documented {len(doc)}"]
        found = []
        for k, item in enumerate(items):
            found += _mismatches(item, real[k], f"{where}[{k}]")
        return found
    if isinstance(doc, _Printed):
        if isinstance(real, bool) or not isinstance(real, int | float):
            return [f"{where}: documented {doc}, got {real!r}"]
        if abs(real - doc) > 0.5 * 10.0**-doc.places * (1 + 1e-9) + 1e-12:
            return [f"{where}: documented {doc}, got {real!r}"]
        return []
    if isinstance(doc, str) and "..." in doc:
        pattern = ".*".join(re.escape(piece) for piece in doc.split("..."))
        if not isinstance(real, str) or not re.fullmatch(pattern, real, re.DOTALL):
            return [f"{where}: documented {doc!r}, got {real!r}"]
        return []
    if doc != real or type(doc) is not type(real):
        return [f"{where}: documented {doc!r}, got {real!r}"]
    return []


def test_documented_outputs_are_matched_strictly_enough() -> None:
    """The matcher of documented outputs rejects what differs (so the docs test can fail)."""
    doc = _loose_json('{"a":[60.0,0.000998],"b":"x ... y","c":...,"d":[1, ...], ...}')
    real = {"a": [59.99999999999999, 0.0009978], "b": "x and y", "c": [1], "d": [1, 2], "e": 0}
    assert _mismatches(doc, real) == []
    for change in (
        {"a": [60.06, 0.0009978]},  # beyond the printed precision
        {"a": [60.0, 0.0009988]},
        {"b": "x and z"},
        {"d": [2, 2]},
        {"a": [60.0]},
    ):
        assert _mismatches(doc, {**real, **change}), change
    assert _mismatches(_loose_json('{"a":1}'), {"a": 1, "b": 2})  # no `...`: exact keys
    assert _mismatches(_loose_json("[true, null]"), [1, None])


# ------------------------------------------------------------------ curl, from the docs
@dataclass
class _Command:
    text: str  # the shell command, as documented
    output: list[str]  # its documented output, the `#` lines under it


def _curl_session() -> list[_Command]:
    """The commands of the marked curl session of docs/remote.md, in order."""
    page = DOC.read_text(encoding="utf-8")
    match = re.search(
        r"<!-- curl-session: begin -->(.*?)<!-- curl-session: end -->", page, re.DOTALL
    )
    assert match, "docs/remote.md has no marked curl session"
    commands: list[_Command] = []
    for block in re.findall(r"```bash\n(.*?)```", match.group(1), re.DOTALL):
        lines = block.splitlines()
        k = 0
        while k < len(lines):
            line = lines[k]
            if line.startswith("#"):
                assert commands, f"an output before any command: {line}"
                commands[-1].output.append(line[1:])
            elif line.strip():
                text = line
                while text.endswith("\\"):
                    k += 1
                    text += "\n" + lines[k]
                commands.append(_Command(text, []))
            k += 1
    return commands


def _request_of(command: str) -> tuple[str, str, Any]:
    """(method, resource, JSON body or None) of a documented curl command."""
    words = shlex.split(command.replace("\\\n", " "))
    assert words[0] == "curl", command
    method = words[words.index("-X") + 1] if "-X" in words else "GET"
    url = next(word for word in words if word.startswith(DOCUMENTED_URL))
    body = _json(words[words.index("-d") + 1]) if "-d" in words else None
    return method, url[len(DOCUMENTED_URL) :], body


def test_the_curl_session_of_the_docs(
    server: BackgroundServer, backend: KinematicBackend, robot: spm.SPMRobot
) -> None:
    _needs("curl")
    commands = _curl_session()
    assert len(commands) >= 8
    expected_deg = np.zeros(3)  # where the twin must be, from the answers so far
    seen: list[tuple[str, str, Any, int]] = []
    for command in commands:
        method, resource, body = _request_of(command.text)
        run = subprocess.run(
            ["bash", "-euo", "pipefail", "-c", command.text.replace(DOCUMENTED_URL, server.url)],
            capture_output=True,
            text=True,
            timeout=PROGRAM_TIMEOUT,
            check=False,
        )
        assert run.returncode == 0 and not run.stderr, (command.text, run.stderr)
        answer_text, status = run.stdout, 200
        documented = list(command.output)
        if documented and re.fullmatch(r"\s*HTTP \d{3}\s*", documented[-1]):
            answer_text, _, status_line = run.stdout.rstrip("\n").rpartition("\n")
            assert status_line.strip() == documented.pop().strip(), (command.text, run.stdout)
            status = int(status_line.split()[1])
        answer = _json(answer_text)
        assert documented, f"no documented output under {command.text!r}"
        differences = _mismatches(_loose_json("".join(documented)), answer)
        assert not differences, (command.text, differences, answer)
        seen.append((method, resource, body, status))

        # The answer against the library, and the twin against what the answers said.
        if method == "PUT" and resource == "/joints" and status == 200:
            expected_deg = np.asarray(body["theta_deg"], dtype=float)
        if method == "PUT" and resource == "/orientation":
            assert status == 200
            truth = spm.inverse_kinematics(matrix_from_rpy(np.radians(body["rpy_deg"]))).theta
            np.testing.assert_allclose(answer["rpy_deg"], body["rpy_deg"], atol=TOL["angles_deg"])
            np.testing.assert_allclose(
                np.radians(answer["theta_deg"]), truth, atol=TOL["orientation"]
            )
            expected_deg = np.asarray(answer["theta_deg"], dtype=float)
        if resource == "/check":
            theta = np.radians(body["theta_deg"])
            assert answer["safe"] is SafetyGuard(robot).check(theta).safe is False
            assert {tuple(pair) for pair in answer["pairs"]} == STUDY_COLLISION_PAIRS
        if status == 409:
            failed = {check["check"]: check["reason"] for check in answer["failed"]}
            assert {"reachable", "collision"} <= set(failed)
            for a, b in STUDY_COLLISION_PAIRS:
                assert f"{a}-{b}" in failed["collision"]
        if "theta_deg" in answer and resource != "/check":
            np.testing.assert_allclose(answer["theta_deg"], expected_deg, atol=TOL["angles_deg"])
        if "R" in answer:
            fk = spm.forward_kinematics(np.radians(answer["theta_deg"]))
            np.testing.assert_allclose(answer["R"], fk.R, atol=TOL["same_numbers"])
            np.testing.assert_allclose(
                answer["rpy_deg"], np.degrees(rpy_from_matrix(fk.R)), atol=TOL["angles_deg"]
            )
            collisions = robot.collisions(np.radians(answer["theta_deg"]))
            assert answer["pairs"] == [list(pair) for pair in collisions]
        np.testing.assert_allclose(
            backend.joints(), np.radians(expected_deg), atol=TOL["orientation"]
        )

    # The session does what the study did: read, set, read back, check, be refused.
    requests = [(method, resource, status) for method, resource, _, status in seen]
    for needed in [("GET", "/state", 200), ("GET", "/collisions", 200), ("POST", "/check", 200)]:
        assert needed in requests, needed
    moves = [
        (body["theta_deg"], status) for m, r, body, status in seen if (m, r) == ("PUT", "/joints")
    ]
    assert (SAFE_DEG, 200) in [([float(x) for x in theta], s) for theta, s in moves]
    refused = requests.index(("PUT", "/joints", 409))
    assert ("GET", "/joints", 200) in requests[refused + 1 :], "no read-back after the refusal"
    assert [[float(x) for x in m[0]] for m in moves if m[1] == 409] == [STUDY_COLLISION_DEG]


# -------------------------------------------------------------- GNU Octave (for MATLAB)
def _octave(code: str, cwd: Path, env: dict[str, str] | None = None) -> dict[str, str]:
    """Run Octave code with the MATLAB helpers on the path; its `name: value` lines."""
    octave = _needs("octave")
    _needs("curl")
    run = subprocess.run(
        [octave, "--no-gui", "--norc", "--quiet", "--path", str(MATLAB_DIR), "--eval", code],
        capture_output=True,
        text=True,
        timeout=PROGRAM_TIMEOUT,
        cwd=cwd,
        env={**os.environ, **(env or {})},
        check=False,
    )
    assert run.returncode == 0, (run.stdout, run.stderr)
    return dict(line.split(": ", 1) for line in run.stdout.splitlines() if ": " in line)


def _numbers(text: str) -> list[float]:
    return [float(word) for word in text.split()]


def test_octave_runs_the_study(
    server: BackgroundServer, backend: KinematicBackend, robot: spm.SPMRobot, tmp_path: Path
) -> None:
    printed = _octave(f"base_url = '{server.url}'; study_remote", tmp_path)
    atol = PRINTED["octave_deg"]
    np.testing.assert_allclose(_numbers(printed["joints_deg"]), [0, 0, 0], atol=atol)
    assert printed["set_status"] == "200"
    np.testing.assert_allclose(_numbers(printed["state_theta_deg"]), SAFE_DEG, atol=atol)
    fk = spm.forward_kinematics(np.radians(SAFE_DEG))
    np.testing.assert_allclose(
        _numbers(printed["state_rpy_deg"]), np.degrees(rpy_from_matrix(fk.R)), atol=atol
    )
    assert printed["state_reachable"] == "1"
    safe_pairs = robot.collisions(np.radians(SAFE_DEG))
    assert printed["state_pairs"] == ("none" if not safe_pairs else "?")
    assert printed["collision"] == "0"
    assert printed["check_status"] == "200"
    assert printed["check_safe"] == "0"
    pairs = {tuple(pair.split("-")) for pair in printed["check_pairs"].split(", ")}
    assert pairs == STUDY_COLLISION_PAIRS
    assert printed["refused_status"] == "409"
    with httpx.Client(base_url=server.url, timeout=REQUEST_TIMEOUT) as http:
        verdict = http.post("/check", json={"theta_deg": STUDY_COLLISION_DEG}).json()
    failed = [check["check"] for check in verdict["checks"] if check["passed"] is False]
    assert printed["refused_checks"].split() == failed and "collision" in failed
    np.testing.assert_allclose(_numbers(printed["joints_after_deg"]), SAFE_DEG, atol=atol)
    np.testing.assert_allclose(backend.joints(), np.radians(SAFE_DEG), atol=TOL["orientation"])

    # The output shown in the docs is this output.
    page = DOC.read_text(encoding="utf-8")
    block = re.search(r"```text\n(joints_deg: .*?)```", page, re.DOTALL)
    assert block, "docs/remote.md shows no output of study_remote"
    documented = dict(line.split(": ", 1) for line in block.group(1).splitlines())
    assert documented.keys() == printed.keys()
    for name, text in documented.items():
        if re.fullmatch(r"[-\d. ]+", text):
            np.testing.assert_allclose(_numbers(printed[name]), _numbers(text), atol=atol)
        else:
            assert printed[name] == text, name


def test_octave_helpers_send_the_token(tmp_path: Path, robot: spm.SPMRobot) -> None:
    code = (
        "base_url = '{url}'; joints = spm_get(base_url, '/joints'); "
        "printf('joints_deg: %.9f %.9f %.9f\\n', joints.theta_deg); "
        "[state, status] = spm_put(base_url, '/joints', struct('theta_deg', [10 20 30])); "
        "printf('status: %d\\n', status); "
        "printf('theta_deg: %.9f %.9f %.9f\\n', state.theta_deg);"
    )
    backend = KinematicBackend(robot=robot)
    with BackgroundServer(backend, token=TOKEN, timeout=STARTUP_TIMEOUT) as running:
        printed = _octave(code.format(url=running.url), tmp_path, {"SPM_TOKEN": TOKEN})
        assert printed["status"] == "200"
        np.testing.assert_allclose(_numbers(printed["theta_deg"]), [10, 20, 30], atol=1e-8)
        np.testing.assert_allclose(backend.joints(), np.radians([10, 20, 30]), atol=1e-12)
        without = subprocess.run(
            [
                *(_needs("octave"), "--no-gui", "--norc", "--quiet", "--path", str(MATLAB_DIR)),
                *("--eval", f"spm_get('{running.url}', '/joints')"),
            ],
            capture_output=True,
            text=True,
            timeout=PROGRAM_TIMEOUT,
            cwd=tmp_path,
            env={k: v for k, v in os.environ.items() if k != "SPM_TOKEN"},
            check=False,
        )
        assert without.returncode != 0  # 401: webread raises


# -------------------------------------------------------------------------------- CORS
ORIGIN = "http://127.0.0.1:8000"


@pytest.fixture(scope="module")
def cors_url(robot: spm.SPMRobot) -> Iterator[str]:
    app = create_app(KinematicBackend(robot=robot), token=TOKEN, cors_origins=[ORIGIN])
    with _Serving(app) as running:
        yield running.url


def _preflight(url: str, origin: str) -> Any:
    return httpx.options(
        url + "/joints",
        headers={
            "Origin": origin,
            "Access-Control-Request-Method": "PUT",
            "Access-Control-Request-Headers": "authorization,content-type",
        },
        timeout=REQUEST_TIMEOUT,
    )


def test_cors_allows_the_listed_origin_only(cors_url: str) -> None:
    allowed = _preflight(cors_url, ORIGIN)  # no token: browsers send none here
    assert allowed.status_code == 200, allowed.text
    assert allowed.headers["access-control-allow-origin"] == ORIGIN
    assert "PUT" in allowed.headers["access-control-allow-methods"]
    assert "authorization" in allowed.headers["access-control-allow-headers"].lower()
    assert "access-control-allow-credentials" not in allowed.headers
    other = _preflight(cors_url, "http://127.0.0.1:9999")
    assert other.status_code == 400
    assert "access-control-allow-origin" not in other.headers

    auth = {"Authorization": f"Bearer {TOKEN}"}
    get = httpx.get(cors_url + "/joints", headers={"Origin": ORIGIN, **auth})
    assert get.status_code == 200 and get.headers["access-control-allow-origin"] == ORIGIN
    get = httpx.get(cors_url + "/joints", headers={"Origin": "http://evil.example", **auth})
    assert get.status_code == 200 and "access-control-allow-origin" not in get.headers
    # The request itself still needs the token; the page can read why it failed.
    no_token = httpx.get(cors_url + "/joints", headers={"Origin": ORIGIN})
    assert no_token.status_code == 401
    assert no_token.headers["access-control-allow-origin"] == ORIGIN


def test_cors_is_off_by_default(server: BackgroundServer) -> None:
    assert _preflight(server.url, ORIGIN).headers.get("access-control-allow-origin") is None
    get = httpx.get(server.url + "/joints", headers={"Origin": ORIGIN})
    assert get.status_code == 200 and "access-control-allow-origin" not in get.headers


@pytest.mark.parametrize(
    "origins",
    ["http://127.0.0.1:8000", ["*"], ["http://127.0.0.1:8000/"], ["null"], ["127.0.0.1:8000"]],
)
def test_cors_origins_are_checked(origins: Any) -> None:
    with pytest.raises(InputError, match="cors_origins"):
        create_app(None, cors_origins=origins)  # refused before a twin is built


# ---------------------------------------------------------------- the browser page
@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """One headless Chromium (Debian's, never a download), as the viewer tests run it."""
    from spm_pin.viz.browser import CHROMIUM_ARGS, find_chromium

    executable = find_chromium()
    if executable is None:
        missing_dependency("no Chromium on the PATH (Debian: apt install chromium)")
    try:
        from playwright.sync_api import sync_playwright
    except ImportError:
        missing_dependency("Playwright for Python is not installed (pip install playwright)")
    with sync_playwright() as playwright:
        launched = playwright.chromium.launch(executable_path=executable, args=list(CHROMIUM_ARGS))
        yield launched
        launched.close()


class _Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, format: str, *args: Any) -> None:
        pass


@contextlib.contextmanager
def _static_site() -> Iterator[str]:
    """examples/ served over HTTP on a free loopback port; yields its origin."""
    handler = functools.partial(_Quiet, directory=str(EXAMPLES))
    site = http.server.ThreadingHTTPServer(("127.0.0.1", 0), handler)
    thread = threading.Thread(target=site.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{site.server_address[1]}"
    finally:
        site.shutdown()
        site.server_close()
        thread.join(REQUEST_TIMEOUT)


def _text_is(page: Any, element: str, text: str) -> None:
    page.wait_for_function(
        "([id, text]) => document.getElementById(id).textContent === text",
        arg=[element, text],
        timeout=PAGE_TIMEOUT_MS,
    )


def _move_from_page(page: Any, theta_deg: list[float]) -> str:
    """Type a goal into the page, press Move, and answer the result it shows."""
    page.evaluate("() => { document.getElementById('result').textContent = ''; }")
    for element, value in zip(("#t1", "#t2", "#t3"), theta_deg, strict=True):
        page.fill(element, f"{value:g}")
    page.click("#move")
    page.wait_for_function(
        "() => /^(moved|refused|no answer|error)/.test("
        "document.getElementById('result').textContent)",
        timeout=PAGE_TIMEOUT_MS,
    )
    return str(page.text_content("#result"))


@pytest.mark.browser
def test_the_page_shows_and_moves_the_twin(browser: Any, robot: spm.SPMRobot) -> None:
    backend = KinematicBackend(robot=robot)
    with _static_site() as origin, _Serving(create_app(backend, cors_origins=[origin])) as api:
        page = browser.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda error: errors.append(str(error)))
        try:
            page.goto(f"{origin}/remote_client.html?server={api.url}")
            _text_is(page, "status", "connected")
            _text_is(page, "theta", "0.00, 0.00, 0.00")  # the state, pushed over WS
            _text_is(page, "pairs", "none")

            result = _move_from_page(page, SAFE_DEG)
            assert result == "moved to 60.00, 90.00, 120.00 deg", result
            np.testing.assert_allclose(
                backend.joints(), np.radians(SAFE_DEG), atol=TOL["orientation"]
            )
            with httpx.Client(base_url=api.url, timeout=REQUEST_TIMEOUT) as http:
                joints = http.get("/joints").json()["theta_deg"]
            np.testing.assert_allclose(joints, SAFE_DEG, atol=TOL["angles_deg"])
            _text_is(page, "theta", "60.00, 90.00, 120.00")  # the stream follows
            rpy_truth = np.degrees(rpy_from_matrix(spm.forward_kinematics(np.radians(SAFE_DEG)).R))
            shown = [float(x) for x in str(page.text_content("#rpy")).split(",")]
            np.testing.assert_allclose(shown, rpy_truth, atol=PRINTED["page_deg"])

            result = _move_from_page(page, STUDY_COLLISION_DEG)
            assert result.startswith("refused, nothing moved: "), result
            assert "reachable: " in result and "collision: links collide" in result
            for a, b in STUDY_COLLISION_PAIRS:
                assert f"{a}-{b}" in result
            assert page.is_visible("#result.refused")
            np.testing.assert_allclose(
                backend.joints(), np.radians(SAFE_DEG), atol=TOL["orientation"]
            )
            _text_is(page, "theta", "60.00, 90.00, 120.00")
        finally:
            page.close()
    assert errors == []


@pytest.mark.browser
def test_a_page_of_another_origin_cannot_move_the_twin(
    browser: Any, server: BackgroundServer, backend: KinematicBackend
) -> None:
    """Without the page's origin among ``cors_origins`` (the default), the browser
    does not send the PUT at all (its preflight gets no CORS answer)."""
    with _static_site() as origin:
        page = browser.new_page()
        try:
            page.goto(f"{origin}/remote_client.html?server={server.url}")
            result = _move_from_page(page, [10.0, 20.0, 30.0])
        finally:
            page.close()
    assert result.startswith(f"no answer from {server.url}"), result
    np.testing.assert_allclose(backend.joints(), [0, 0, 0], atol=TOL["orientation"])


# ---------------------------------------------------------------------------- ROS 2
def test_the_ros2_example_compiles_and_is_not_run() -> None:
    """ROS 2 does not install from PyPI: its node is documented, compiled here, not run
    (the docs test runs only ```python blocks; this one is ```py)."""
    page = DOC.read_text(encoding="utf-8")
    snippets = re.findall(r"```py\n(.*?)```", page, re.DOTALL)
    ros = [code for code in snippets if "import rclpy" in code]
    assert len(ros) == 1
    compile(ros[0], "remote.md[ROS 2 node]", "exec")
    assert "PUT" in ros[0] and "/orientation" in ros[0] and "quaternion_wxyz" in ros[0]
    assert not any("rclpy" in code for code in re.findall(r"```python\n(.*?)```", page, re.DOTALL))
