r"""The SPM in meshcat: poses, colliding links in black, joint axes, animations, HTML.

Scene layout (meshcat paths; the world frame is z-up, O at the origin):

* ``/meshcat/spm/links/<link>``: one node per link (:data:`LINK_NAMES`), its
  transform the link's world placement from Pinocchio. Each has two children with
  the link mesh: ``free`` in the link's colour and ``colliding`` in black; exactly
  one of them is visible.
* ``/meshcat/spm/overlays/joint_axes/<u_i|w_i|v_i>``: arrows from O along the
  joint axes u_i, w_i, v_i (hidden unless asked for; :mod:`spm_pin.viz.arrows`).
* ``/meshcat/spm/overlays/platform_frame``: the platform frame's x, y, z axes
  (red, green, blue; hidden unless asked for).
* ``/meshcat/spm/contacts``: red markers where links collide and, on request, the
  nearest clearance (:mod:`spm_pin.viz.contacts`).

The camera looks at O from a view of :mod:`spm_pin.viz.views` (default ``iso``:
the three legs and the platform's face) and is framed so the robot fills most of the
view; it orbits about O. meshcat 0.3.2's camera helpers are broken, so the camera is
set through its ``position``, ``zoom`` and ``view`` (a vertical lens shift that
centres the robot, whose base reaches far below O) properties. A saved page frames
the pose it shows, has buttons for the preset views and a key of the colours
(:mod:`spm_pin.viz.key`).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from types import TracebackType

import meshcat.geometry as mg
import numpy as np
import numpy.typing as npt

from ..collision import build_robot, checker_of
from ..errors import InputError
from ..model.geometry import LINK_NAMES, link_meshes
from ..model.robot import SPMRobot
from ._clips import transform_clip, visibility_clip
from ._scene import Scene
from .arrows import OVERLAYS_PATH, draw_arrows, overlay_arrows, overlay_transforms
from .caption import pose_caption
from .contacts import Contact, contacts, contacts_html, draw_contacts, nearest_clearance
from .key import (
    COLLIDING_COLOR,
    COLLIDING_SHINE,
    JOINT_AXIS_COLORS,
    LINK_COLORS,
    key_html,
    material,
)
from .poses import configuration, path_configurations
from .server import MeshcatServer, ViewerError
from .views import (
    CAMERA_PATH,
    DEFAULT_VIEW,
    VIEWS,
    CameraFit,
    check_camera,
    check_view,
    fit_camera,
    is_real,
    view_direction,
)

__all__ = [
    "COLLIDING_COLOR",
    "DEFAULT_AZIMUTH",
    "DEFAULT_ELEVATION",
    "JOINT_AXIS_COLORS",
    "LINK_COLORS",
    "ROOT",
    "RobotAnimation",
    "Visualizer",
    "link_path",
]

FloatArray = npt.NDArray[np.float64]
LinkPair = tuple[str, str]

#: Scene path of the robot.
ROOT = "/meshcat/spm"

#: Default camera direction seen from O (the ``iso`` view of :data:`VIEWS`): azimuth
#: from +x towards +y and elevation above the xy plane [rad].
DEFAULT_AZIMUTH = VIEWS[DEFAULT_VIEW].azimuth
DEFAULT_ELEVATION = VIEWS[DEFAULT_VIEW].elevation
_FILL = 0.8  # default share of the view the robot takes
_EXTENT_SAMPLES = 13  # poses of an animation the camera frames

_GRID_SCALE = 0.05  # meshcat's 20 m grid with 0.5 m cells -> 1 m with 25 mm cells


def link_path(link: str) -> str:
    """Scene path of a link's node, ``/meshcat/spm/links/<link>``."""
    return f"{ROOT}/links/{link}"


@dataclasses.dataclass(frozen=True)
class RobotAnimation:
    """What :meth:`Visualizer.animate` put into the scene.

    Attributes:
        q: Joint configurations, one per sample, shape (N, 9).
        times: Time of each sample in the animation [s], shape (N,).
        collisions: Colliding link pairs at each sample (empty lists when collision
            checking is off).
        modes: Assembly-mode label of each sample (labels of
            :func:`~spm_pin.forward_kinematics_all`; None for configurations q).
    """

    q: FloatArray
    times: FloatArray
    collisions: list[list[LinkPair]]
    modes: list[str | None] = dataclasses.field(default_factory=list)

    @property
    def colliding_samples(self) -> list[int]:
        """Indices of the samples where some links collide."""
        return [k for k, pairs in enumerate(self.collisions) if pairs]


class Visualizer:
    """The SPM drawn with meshcat, live in a browser or as a static HTML file.

    Building a visualizer starts nothing: the scene is kept in Python, so
    :meth:`save_html` works without any server. :meth:`start` (or a ``with`` block)
    starts a meshcat server, shows the scene so far and sends every later change;
    :meth:`stop` (or leaving the block) stops the server and frees its ports.

    Example:
        >>> import numpy as np
        >>> from spm_pin.viz import Visualizer
        >>> viz = Visualizer()
        >>> viz.display(np.radians([60, 90, 120]))
        []
        >>> html = viz.static_html()

    Args:
        robot: The robot (default: ``spm.build_robot()``, the prototype).
        joint_axes: Show arrows along the joint axes u_i, w_i, v_i.
        platform_frame: Show the platform frame (x red, y green, z blue).
        check_collisions: Turn colliding links black on every :meth:`display` and in
            animations (``robot.collisions``).
        collision_margin: Links nearer than this count as colliding [m].
        view: The camera's view, a name of :data:`~spm_pin.viz.views.VIEWS`
            (``iso``, ``top``, ``front``, ``side``).

    Attributes:
        robot: The robot drawn.
        scene: The scene so far (what a browser that connects now receives).
        check_collisions: As given; may be changed.
        collision_margin: As given; may be changed [m].
    """

    def __init__(
        self,
        robot: SPMRobot | None = None,
        *,
        joint_axes: bool = False,
        platform_frame: bool = False,
        check_collisions: bool = True,
        collision_margin: float = 0.0,
        view: str = DEFAULT_VIEW,
    ) -> None:
        check_view(view)
        if robot is None:
            robot = build_robot()
        if not isinstance(robot, SPMRobot):
            raise InputError(
                f"robot must be an SPMRobot (spm.build_robot(design)), got {type(robot).__name__}",
                argument="robot",
                value=robot,
            )
        if not is_real(collision_margin) or collision_margin < 0:
            raise InputError(
                f"collision_margin must be a finite distance >= 0 [m], got {collision_margin!r}",
                argument="collision_margin",
                value=collision_margin,
            )
        self.robot = robot
        self.check_collisions = bool(check_collisions)
        self.collision_margin = float(collision_margin)
        self.scene = Scene()
        self._server: MeshcatServer | None = None
        self._colliding: frozenset[str] = frozenset()
        self._animated = False
        self._mode: str | None = None
        self._home = False
        self._caption: str | None = None
        self._contacts: list[Contact] = []
        self._clearance: Contact | None = None
        meshes = link_meshes(robot.design)
        # vertices split along sharp edges, so the viewer shades flat faces flat
        self._meshes = {name: mesh.smooth_shaded for name, mesh in meshes.items()}
        moving = [mesh.vertices for name, mesh in self._meshes.items() if name != "base"]
        self._arrows = overlay_arrows(robot.design, moving)
        self._overlays_shown = {"joint_axes": False, "platform_frame": False}
        self._build()
        self._q = np.zeros(robot.model.nq)
        self._extent_qs: list[FloatArray] = [self._q]
        self._view: str | None = view
        self._camera = (VIEWS[view].azimuth, VIEWS[view].elevation, _FILL)
        self.set_overlays(joint_axes=joint_axes, platform_frame=platform_frame)
        self.display(self._q)
        self.set_view(view)

    def __repr__(self) -> str:
        server = self._server
        state = f"url={server.url!r}" if server is not None and server.running else "not serving"
        return f"Visualizer(design={self.robot.design.name!r}, {state})"

    # ------------------------------------------------------------------- the scene
    def _build(self) -> None:
        scene = self.scene
        scene.set_property("/Background", "top_color", [1.0, 1.0, 1.0])
        scene.set_property("/Background", "bottom_color", [0.78, 0.82, 0.88])
        scene.set_property("/Axes", "visible", False)
        floor = float(self._meshes["base"].vertices[:, 2].min()) - 0.001
        grid = np.diag([_GRID_SCALE, _GRID_SCALE, _GRID_SCALE, 1.0])
        grid[2, 3] = floor
        scene.set_transform("/Grid", grid)
        for name in LINK_NAMES:
            mesh = self._meshes[name]
            for child, color in (("free", LINK_COLORS[name]), ("colliding", COLLIDING_COLOR)):
                geometry = mg.TriangularMeshGeometry(mesh.vertices, mesh.faces)
                extra = COLLIDING_SHINE if child == "colliding" else {}
                mesh_material = material(color, **extra)
                scene.set_object(f"{link_path(name)}/{child}", mg.Mesh(geometry, mesh_material))
            scene.set_property(f"{link_path(name)}/free", "visible", True)
            scene.set_property(f"{link_path(name)}/colliding", "visible", False)
        draw_arrows(scene, self._arrows)

    def set_overlays(
        self, *, joint_axes: bool | None = None, platform_frame: bool | None = None
    ) -> None:
        """Show or hide the overlays (None leaves one as it is).

        Args:
            joint_axes: Arrows from O along u_i (base), w_i (proximal-distal joints)
                and v_i (distal-platform joints), each moving with its link.
            platform_frame: The platform frame's axes x (red), y (green), z (blue).
        """
        for name, value in (("joint_axes", joint_axes), ("platform_frame", platform_frame)):
            if value is not None:
                self.scene.set_property(f"{OVERLAYS_PATH}/{name}", "visible", bool(value))
                self._overlays_shown[name] = bool(value)

    def _extent_points(self) -> FloatArray:
        """Points that the camera must see: the link meshes and the overlays shown, in
        the pose shown (in an animation: in some of its samples, the ends included)."""
        points = []
        for q in self._extent_qs:
            transforms = self._pose_transforms(q)
            for name in LINK_NAMES:
                T = transforms[link_path(name)]
                points.append(self._meshes[name].vertices @ T[:3, :3].T + T[:3, 3])
            for arrow in self._arrows:
                if self._overlays_shown[arrow.overlay]:
                    T = transforms.get(arrow.node, np.eye(4))
                    points.append((T[:3, :3] @ (arrow.length * arrow.direction) + T[:3, 3])[None])
        return np.concatenate(points)

    def _fit(self, azimuth: float, elevation: float, fill: float) -> CameraFit:
        return fit_camera(self._extent_points(), view_direction(azimuth, elevation), fill)

    def set_view(self, view: str = DEFAULT_VIEW, *, fill: float = _FILL) -> None:
        """Look at O from a preset view, framed on the robot as displayed.

        Args:
            view: A name of :data:`~spm_pin.viz.views.VIEWS`: ``iso`` (the default:
                the three legs and the platform's face), ``top``, ``front``, ``side``.
            fill: Fraction of the view height (and width) the robot takes, in (0, 1].

        Raises:
            InputError: an unknown view (the message lists the names) or a bad fill.
        """
        preset = check_view(view)
        self.set_camera(preset.azimuth, preset.elevation, fill=fill)
        self._view = view

    @property
    def view(self) -> str | None:
        """The preset view of the camera (None after :meth:`set_camera`)."""
        return self._view

    def set_camera(
        self,
        azimuth: float = DEFAULT_AZIMUTH,
        elevation: float = DEFAULT_ELEVATION,
        *,
        fill: float = _FILL,
    ) -> None:
        """Look at O from a direction, framed so the robot as displayed fills the view.

        The camera stands where the robot's bounding sphere about O fits in the field
        of view (:func:`~spm_pin.viz.views.fit_camera`), zooms and shifts its lens so
        the robot fills ``fill`` of the view, and orbits about O when dragged. The fit
        assumes a view at least 4:3 (width:height), as browser windows are.

        Args:
            azimuth: Direction of the camera seen from O, from +x towards +y [rad].
            elevation: Height of the camera above the xy plane, seen from O [rad],
                in (-pi/2, pi/2).
            fill: Fraction of the view height (and width) the robot takes, in (0, 1].

        Raises:
            InputError: an argument out of range.
        """
        self._camera = check_camera(azimuth, elevation, fill)
        self._view = None
        for key, value in self._fit(*self._camera).properties():
            self.scene.set_property(CAMERA_PATH, key, value)

    # ------------------------------------------------------------------------ poses
    def _pose_transforms(self, q: FloatArray) -> dict[str, FloatArray]:
        """Scene path -> transform (4, 4) of every moving node at q."""
        placements = {name: se3.homogeneous for name, se3 in self.robot.placements(q).items()}
        transforms = {link_path(name): placements[name] for name in LINK_NAMES}
        return transforms | overlay_transforms(placements)

    def _collisions(self, q: FloatArray) -> list[LinkPair]:
        if not self.check_collisions:
            return []
        return checker_of(self.robot).collisions(q, margin=self.collision_margin)

    def _show_colliding(self, links: frozenset[str]) -> None:
        for name in LINK_NAMES:
            if (name in links) != (name in self._colliding):
                self.scene.set_property(f"{link_path(name)}/free", "visible", name not in links)
                self.scene.set_property(f"{link_path(name)}/colliding", "visible", name in links)
        self._colliding = links

    def _show(self, q: FloatArray) -> list[LinkPair]:
        for path, matrix in self._pose_transforms(q).items():
            self.scene.set_transform(path, matrix)
        pairs = self._collisions(q)
        self._show_colliding(frozenset(name for pair in pairs for name in pair))
        self._q = q.copy()  # q may be the caller's array (or a row of an animation's)
        return pairs

    def display(
        self, x: npt.ArrayLike, *, mode: str = "nearest", clearance: bool = False
    ) -> list[LinkPair]:
        """Show the robot at input angles theta or at a joint configuration q.

        Links that collide turn black, and back to their colour when free; red
        markers show each colliding pair's contact (:attr:`contacts`). Stops an
        animation if one is loaded. :attr:`mode` names the assembly mode shown, and
        the saved page (:meth:`save_html`) says it in its caption.

        Args:
            x: Input angles theta [rad], shape (3,), or a joint configuration q [rad],
                shape (9,) (joint order of :data:`~spm_pin.model.robot.JOINT_NAMES`).
            mode: Assembly mode for theta: ``"nearest"`` (the library's rule,
                :func:`~spm_pin.select_assembly`: the home mode where it exists, else
                the real mode nearest to it), ``"home"``, or a label of
                :func:`~spm_pin.forward_kinematics_all` such as ``"+-+/+"``.
            clearance: Also join the closest points of the nearest non-colliding
                link pair (:attr:`clearance`; :mod:`spm_pin.viz.contacts`).

        Returns:
            The colliding link pairs (``robot.collisions``), empty when none collide
            or collision checking is off.

        Raises:
            InputError: x is neither (3,) nor (9,), not finite, or a bad mode.
            UnreachableError: no assembly of theta in that mode.
        """
        q, label, home = configuration(self.robot, x, mode)
        if self._animated:
            self.scene.set_animation([], play=False, repetitions=1)
            self._animated = False
        pairs = self._show(q)
        self._contacts = contacts(self.robot, q, pairs) if pairs else []
        self._clearance = nearest_clearance(self.robot, q) if clearance else None
        draw_contacts(self.scene, self._contacts, self._clearance)
        self._extent_qs = [self._q]
        self._mode, self._home = label, home
        self._caption = None if label is None else pose_caption(self.robot, q, label, home, pairs)
        return pairs

    @property
    def mode(self) -> str | None:
        """Label of the assembly mode shown (None when a configuration q was given or
        an animation is loaded)."""
        return self._mode

    @property
    def home(self) -> bool:
        """The assembly mode shown (:attr:`mode`) is the home assembly mode."""
        return self._home

    @property
    def q(self) -> FloatArray:
        """The configuration shown (9,) [rad] (a copy)."""
        q: FloatArray = self._q.copy()
        return q

    @property
    def contacts(self) -> list[Contact]:
        """Witness points and depth of each colliding pair of the pose shown."""
        return list(self._contacts)

    @property
    def clearance(self) -> Contact | None:
        """The nearest non-colliding pair, when :meth:`display` was asked for it."""
        return self._clearance

    @property
    def colliding_links(self) -> frozenset[str]:
        """Names of the links drawn black."""
        return self._colliding

    # ------------------------------------------------------------------- animations
    def animate(
        self,
        path: npt.ArrayLike,
        *,
        dt: float = 0.04,
        start: npt.ArrayLike | None = None,
        play: bool = True,
        repetitions: int = 1,
    ) -> RobotAnimation:
        """Load a motion as a meshcat animation (play, pause and scrub it in the page).

        A path of input angles is followed continuously in one assembly mode
        (:func:`~spm_pin.track`), starting from the mode of the library's rule at the
        first sample (:func:`~spm_pin.select_assembly`: the home mode where it exists,
        else the real mode nearest to it) or from ``start``.
        Colliding links turn black in the frames where they collide. The static
        scene shows the first sample; :meth:`display` ends the animation.

        Args:
            path: Input angles [rad], shape (N, 3), or joint configurations [rad],
                shape (N, 9).
            dt: Time between samples [s].
            start: Platform rotation (3, 3) near the assembly mode to follow at the
                first sample (input-angle paths only).
            play: Start playing when the page loads.
            repetitions: How many times it plays.

        Returns:
            The configurations, times and collisions of the samples.

        Raises:
            InputError: bad shapes or values.
            UnreachableError: the path leaves the workspace of the followed mode.
        """
        if not is_real(dt) or dt <= 0:
            raise InputError(f"dt must be a positive time [s], got {dt!r}", argument="dt", value=dt)
        if isinstance(repetitions, bool) or not isinstance(repetitions, int) or repetitions < 1:
            raise InputError(
                f"repetitions must be an integer >= 1, got {repetitions!r}",
                argument="repetitions",
                value=repetitions,
            )
        qs, modes = path_configurations(self.robot, path, start)
        times: FloatArray = float(dt) * np.arange(qs.shape[0], dtype=float)
        poses = [self._pose_transforms(q) for q in qs]
        collisions = [self._collisions(q) for q in qs]
        animations = [
            transform_clip(node, times, [pose[node] for pose in poses]) for node in poses[0]
        ]
        if self.check_collisions:
            for name in LINK_NAMES:
                black = [any(name in pair for pair in pairs) for pairs in collisions]
                free = [not b for b in black]
                animations.append(visibility_clip(f"{link_path(name)}/free", times, free))
                animations.append(visibility_clip(f"{link_path(name)}/colliding", times, black))
        self._show(qs[0])
        picked = np.unique(np.linspace(0, qs.shape[0] - 1, _EXTENT_SAMPLES).round().astype(int))
        self._extent_qs = [qs[k] for k in picked]
        self.scene.set_animation(animations, play=bool(play), repetitions=repetitions)
        self._animated = True
        self._mode, self._home = None, False
        self._caption = None
        self._contacts, self._clearance = [], None
        draw_contacts(self.scene, [], None)
        return RobotAnimation(q=qs, times=times, collisions=collisions, modes=modes)

    # ------------------------------------------------------------------ the server
    def start(self, *, timeout: float = 10.0) -> str:
        """Start a meshcat server showing the scene (no-op when one runs).

        Args:
            timeout: How long to wait for the server to start and to take each
                command [s].

        Returns:
            The URL of the viewer page.

        Raises:
            ViewerError: the server could not start.
        """
        if self._server is not None and self._server.running:
            return self._server.url
        self.stop()
        server = MeshcatServer(timeout=timeout).start()
        try:
            self.scene.attach(server)
        except BaseException:
            self.scene.attach(None)
            server.stop()
            raise
        self._server = server
        return server.url

    def stop(self) -> None:
        """Stop the meshcat server, if one runs (the scene is kept)."""
        server, self._server = self._server, None
        self.scene.attach(None)
        if server is not None:
            server.stop()

    @property
    def running(self) -> bool:
        """True while a meshcat server shows the scene."""
        return self._server is not None and self._server.running

    @property
    def server(self) -> MeshcatServer | None:
        """The running server, if any."""
        return self._server

    @property
    def url(self) -> str:
        """The viewer page of the running server.

        Raises:
            ViewerError: no server runs (call :meth:`start`).
        """
        if self._server is None:
            raise ViewerError("no meshcat server runs; call start() or use 'with'")
        return self._server.url

    def __enter__(self) -> Visualizer:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        traceback: TracebackType | None,
    ) -> None:
        self.stop()

    # ------------------------------------------------------------------- HTML export
    def static_html(self, title: str | None = None, caption: str | None = None) -> str:
        """The scene (and its animation) as one self-contained HTML page.

        The page inlines meshcat's viewer, needs no server and no network. It opens
        in the camera's view (:attr:`view`) framed on the pose shown (for an
        animation, on its samples), has a button per preset view (``#spm-views``)
        and a key of the legs' colours and of the arrows drawn (``#spm-key``).

        Args:
            title: Page title (default: ``spm-pin: <design name>``).
            caption: A line of text shown on the page (default: after
                :meth:`display` of input angles, the angles, the assembly mode shown
                and the colliding links; none otherwise).
        """
        fill = self._camera[2]
        views = {
            name: [(CAMERA_PATH, key, value) for key, value in fit.properties()]
            for name, preset in VIEWS.items()
            for fit in [self._fit(preset.azimuth, preset.elevation, fill)]
        }
        return self.scene.static_html(
            title or f"spm-pin: {self.robot.design.name}",
            caption if caption is not None else self._caption,
            key=key_html(**self._overlays_shown) + self._contacts_html(),
            views=views,
            view=self._view,
        )

    def _contacts_html(self) -> str:
        checked = self.check_collisions and not self._animated
        return contacts_html(self._contacts, self._clearance, checked)

    def save_html(
        self, path: str | Path, title: str | None = None, caption: str | None = None
    ) -> Path:
        """Write :meth:`static_html` to a file.

        Args:
            path: The HTML file to write.
            title: Page title (default: ``spm-pin: <design name>``).
            caption: As for :meth:`static_html`.

        Returns:
            The path written.
        """
        target = Path(path)
        target.write_text(self.static_html(title, caption), encoding="utf-8")
        return target
