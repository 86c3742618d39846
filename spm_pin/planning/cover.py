"""A certified cover of the safe set: cells of the gap plane proven safe everywhere.

A square cell of side ``a`` of the gap plane is safe at every point when each of its
four corners is certified safe within ``a / sqrt(2)`` (every point of the square lies
that near one of its corners): the home mode assembles there, the singularity margin
and the dexterity exceed their thresholds by their Lipschitz bound times that radius,
and no two links come nearer than the clearance margin (plus the yaw tolerance) plus
the clearance bound times that radius: the continuity argument and the bounds of
:class:`~spm_pin.planning.safe_set.SafeSet`, applied to cells instead of the samples
of one path.

The cells form a quadtree: root cells of side :data:`ROOT_STEP_DEG` and, where a
cell is not covered, its four children, down to :data:`LEVELS` halvings. Nothing is
computed in advance: a cell's corners are checked the first time a path crosses it
and kept, so a cover grows with the paths asked of it and answers again in
microseconds per cell. A straight segment of the gap plane is certified when every
cell it crosses is covered (the segment is split exactly where it crosses the grid
lines). Where a cell of level :data:`SAMPLE_LEVEL` or finer is not covered and its
children are not decided yet (at the boundary of the safe set, or along a narrow
valley of small clearance inside it), the piece of the segment inside it is
certified by its own samples (:meth:`SafeSet.certify_samples`) instead of deciding
ever smaller cells: such a cell's side is about one check step, so its children's
corners cost several times the evaluations of the piece's samples (a segment that
runs along such a valley decided thousands of cells). Consecutive such pieces are
certified together, and each certified run is remembered.
"""

from __future__ import annotations

import collections
import dataclasses
import itertools
import json
import math
import os
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..kinematics import forward_kinematics, jacobian
from ._evaluation import YAW_TOLERANCE_M, Evaluation, sample_checks

if TYPE_CHECKING:
    from .safe_set import SafeSet

__all__ = ["LEVELS", "ROOT_STEP_DEG", "SAMPLE_LEVEL", "SafeCover"]

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

#: Side of the root cells [deg] (corner checks at about 7 mm of raised clearance for
#: the prototype: a fraction of a millisecond each).
ROOT_STEP_DEG = 0.5
#: Halvings of a root cell that is not covered, at most (finest side 0.5/32 deg).
LEVELS = 5
#: Vertices evaluated one by one on the float path (more: one numpy batch).
SCALAR_BATCH = 12
#: Undecided cells decided in one batch, at most.
BATCH = 32
#: Level from which a cell that is not covered, with children not decided yet, has
#: the piece of a segment inside it certified by samples rather than by its children
#: (side 0.5/8 deg: about one check step). ``LEVELS + 1``: always the children.
SAMPLE_LEVEL = 3
#: Open runs of a segment certified together once they are this long [deg], at most.
SAMPLE_RUN_DEG = 5.0
#: Runs certified by samples remembered (then forgotten all at once).
SAMPLE_MEMO = 4096
#: Root-cell states.
_UNKNOWN, _OPEN, _COVERED = -1, 0, 1


class SafeCover:
    """The quadtree of certified cells of a safe set (see the module).

    Args:
        safe: The safe set whose checks and Lipschitz bounds it applies.
        root_step_deg: Side of the root cells [deg].
        levels: Halvings of a root cell, at most.

    Attributes:
        stats: Counts: ``vertices`` evaluated, ``checks`` (collision checks),
            ``cells`` decided, ``dense`` runs certified by samples, ``samples``
            evaluated for them.
    """

    def __init__(
        self, safe: SafeSet, root_step_deg: float = ROOT_STEP_DEG, levels: int = LEVELS
    ) -> None:
        self.safe = safe
        self.root = float(root_step_deg)
        self.levels = int(levels)
        self._fine = self.root / 2**self.levels  # the finest lattice [deg]
        n = math.ceil(360.0 / self.root)
        self._roots = np.full((n, n), _UNKNOWN, dtype=np.int8)
        self._cells: dict[tuple[int, int, int], bool] = {}  # (level >= 1, i, j)
        # Per vertex (finest-lattice key): reachable, singularity margin, dexterity, q.
        self._vertices: dict[tuple[int, int], tuple[bool, float, float, FloatArray]] = {}
        self._passes: dict[tuple[int, int, int], bool] = {}  # (i, j, level)
        # Covered cells (level, i, j): the smallest singularity margin and dexterity
        # of their corners.
        self._minima: dict[tuple[int, int, int], tuple[float, float]] = {}
        self.stats = collections.Counter[str]()
        self._dense_evaluations: list[Evaluation] = []
        self._pending: list[tuple[float, float]] = []
        # Runs certified by samples: (ends rounded) -> (safe, evaluation).
        self._runs: dict[tuple[float, ...], tuple[bool, Evaluation]] = {}

    @property
    def known_cells(self) -> int:
        """How many cells are decided (covered or not), every level."""
        return int(np.count_nonzero(self._roots != _UNKNOWN)) + len(self._cells)

    def covered_cells(self) -> tuple[npt.NDArray[np.bool_], IntArray]:
        """The cells covered so far (every point of each is certified safe).

        Returns:
            (the covered root cells, a boolean (n, n) mask: root cell (i, j) spans
            D12 from i a to (i + 1) a and D23 from j a to (j + 1) a, a the root step
            in degrees; the covered finer cells, (m, 3) rows (level, i, j): the cell
            of side a / 2**level with lower corner (i, j) times that side).
        """
        roots = self._roots == _COVERED
        cells = np.array(
            [key for key, covered in self._cells.items() if covered], dtype=np.int64
        ).reshape(-1, 3)
        return roots, cells

    # ------------------------------------------------------------------ vertices
    def _radius(self, level: int) -> float:
        return float(self.root / 2**level / math.sqrt(2.0))

    def _margin(self, level: int) -> float:
        """The clearance margin [m] that certifies a cell of ``level`` from a corner."""
        s, lip = self.safe.settings, self.safe.lipschitz
        return s.margin + YAW_TOLERANCE_M + lip.clearance * self._radius(level)

    def prepare(self) -> None:
        """Make the collision checks of every level's margin and of the samples'
        ladder of margins (:meth:`SafeSet.prepare_samples`) now (about 70 ms each for
        the prototype), so that no plan pays for them later; :meth:`load` and
        :meth:`fill` call it."""
        for level in range(self.levels + 1):
            self.safe.checker.prepare(self._margin(level), include_fixed=False)
        self.safe.prepare_samples()

    def _ensure(self, keys: list[tuple[int, int]]) -> None:
        """Evaluate the vertices not seen yet (one batch of kinematics)."""
        todo = [k for k in dict.fromkeys(keys) if k not in self._vertices]
        if not todo:
            return
        self.stats["vertices"] += len(todo)
        if len(todo) <= SCALAR_BATCH:
            for key in todo:
                self._vertices[key] = self._one_vertex(key)
            return
        safe = self.safe
        points = np.array(todo, dtype=float) * self._fine
        d12, d23 = points[:, 0], points[:, 1]
        inside = (d12 > 0.0) & (d23 > 0.0) & (d12 + d23 < 360.0)
        theta = safe.theta_of(d12, d23, 0.0)
        fk = forward_kinematics(theta, safe.design)
        reachable = np.asarray(fk.reachable, dtype=bool) & inside
        R = np.where(reachable[:, None, None], fk.R, np.eye(3))
        jac = jacobian(theta, safe.design, R=R)
        q = np.zeros((theta.shape[0], safe.robot.model.nq))
        if np.any(reachable):
            q[reachable] = safe.robot._configuration_from_rotation(theta[reachable], R[reachable])
        for k, key in enumerate(todo):
            self._vertices[key] = (
                bool(reachable[k]),
                float(jac.singularity_margin[k]),
                float(jac.dexterity[k]),
                q[k],
            )

    def _one_vertex(self, key: tuple[int, int]) -> tuple[bool, float, float, FloatArray]:
        """One vertex on the single-input float path (:func:`._evaluation.
        sample_checks`: the batch values to rounding, 1e-13)."""
        safe = self.safe
        d12, d23 = key[0] * self._fine, key[1] * self._fine
        if not (d12 > 0.0 and d23 > 0.0 and d12 + d23 < 360.0):
            return False, math.nan, math.nan, np.zeros(safe.robot.model.nq)
        return sample_checks(safe.robot, safe.theta_of(d12, d23, 0.0).tolist())

    def _vertex_passes(self, key: tuple[int, int], level: int) -> bool:
        """The vertex is certified safe within the radius of a cell of ``level``."""
        cached = self._passes.get((key[0], key[1], level))
        if cached is not None:
            return cached
        # Monotone in the radius: passing a larger one passes, failing a smaller fails.
        for coarser in range(level):
            if self._passes.get((key[0], key[1], coarser)) is True:
                return True
        for finer in range(level + 1, self.levels + 1):
            if self._passes.get((key[0], key[1], finer)) is False:
                return False
        safe, s, lip = self.safe, self.safe.settings, self.safe.lipschitz
        reachable, sing, dex, q = self._vertices[key]
        rho = self._radius(level)
        ok = (
            reachable
            and sing >= s.min_singularity_margin + lip.singularity * rho
            and dex >= s.min_dexterity + lip.dexterity * rho
            and safe.checker.fixed_clearance >= s.margin
        )
        if ok:
            self.stats["checks"] += 1
            ok = not safe.checker.collisions(q, margin=self._margin(level), include_fixed=False)
        self._passes[(key[0], key[1], level)] = ok
        return ok

    def _corners(self, level: int, i: int, j: int) -> list[tuple[int, int]]:
        m = 2 ** (self.levels - level)
        return [
            (i * m, j * m),
            ((i + 1) * m, j * m),
            (i * m, (j + 1) * m),
            ((i + 1) * m, (j + 1) * m),
        ]

    def _decide(self, level: int, cells: list[tuple[int, int]]) -> list[bool]:
        corners = [self._corners(level, i, j) for i, j in cells]
        self._ensure([key for four in corners for key in four])
        self.stats["cells"] += len(cells)
        decided = []
        for (i, j), four in zip(cells, corners, strict=True):
            covered = all(self._vertex_passes(key, level) for key in four)
            if covered:
                values = [self._vertices[key] for key in four]
                self._minima[(level, i, j)] = (
                    min(v[1] for v in values),
                    min(v[2] for v in values),
                )
            decided.append(covered)
        return decided

    # ------------------------------------------------------------------ segments
    @staticmethod
    def _crossings(
        p: tuple[float, float], d: tuple[float, float], step: float, t0: float, t1: float
    ) -> list[tuple[float, float, int, int]]:
        """The pieces (t_a, t_b, i, j) of p + t d, t in [t0, t1], between the grid
        lines of ``step``, with the cell (i, j) each lies in."""
        ts = [t0, t1]
        for axis in (0, 1):
            if d[axis] == 0.0:
                continue
            a, b = p[axis] + t0 * d[axis], p[axis] + t1 * d[axis]
            low, high = (a, b) if a <= b else (b, a)
            for k in range(math.floor(low / step) + 1, math.ceil(high / step)):
                t = (k * step - p[axis]) / d[axis]
                if t0 < t < t1:
                    ts.append(t)
        ts.sort()
        pieces = []
        for a, b in itertools.pairwise(ts):
            if b - a <= 1e-15 and len(ts) > 2:
                continue
            m = 0.5 * (a + b)
            i = math.floor((p[0] + m * d[0]) / step)
            j = math.floor((p[1] + m * d[1]) / step)
            pieces.append((a, b, i, j))
        return pieces

    def _walk(
        self,
        p: tuple[float, float],
        d: tuple[float, float],
        t0: float,
        t1: float,
        level: int,
        cells: list[tuple[int, int, int]] | None,
    ) -> bool:
        """Every point of p + t d, t in [t0, t1], lies in a covered cell of ``level``
        or finer (those cells go into ``cells``) or in cells that are not covered
        (finest, or from :data:`SAMPLE_LEVEL` on with children not decided), along
        runs certified by their own samples; False at the first run or cell that
        fails. Cells are decided in the order the segment meets them."""
        pieces = self._crossings(p, d, self.root / 2**level, t0, t1)
        if level == 0:
            n = self._roots.shape[0]
            if any(not (0 <= i < n and 0 <= j < n) for _, _, i, j in pieces):
                return False
        for k, (a, b, i, j) in enumerate(pieces):
            covered = self._covered(level, pieces, k)
            if covered:
                if cells is not None:
                    cells.append((level, i, j))
                continue
            if level < self.levels and (
                level < SAMPLE_LEVEL or self._children_known(p, d, a, b, level)
            ):
                if not self._walk(p, d, a, b, level + 1, cells):
                    return False
            elif self._pending and self._pending[-1][1] == a:  # continues the last piece
                self._pending[-1] = (self._pending[-1][0], b)
            else:
                self._pending.append((a, b))
            if level == 0 and self._pending and not self._flush(p, d, b, cells):
                return False
        if level == 0 and self._pending:  # the open runs left at the segment's end
            pending, self._pending = self._pending, []
            return all(self._dense(p, d, u, v, cells) for u, v in pending)
        return True

    def _flush(
        self,
        p: tuple[float, float],
        d: tuple[float, float],
        b: float,
        cells: list[tuple[int, int, int]] | None,
    ) -> bool:
        """After the root piece ending at ``b``: certify the open runs by samples
        when the last has ended or the runs reach :data:`SAMPLE_RUN_DEG` (a run that
        continues into the next root cell waits for it); False if one fails."""
        length = math.hypot(d[0], d[1]) * sum(v - u for u, v in self._pending)
        if self._pending[-1][1] == b and length < SAMPLE_RUN_DEG:
            return True
        pending, self._pending = self._pending, []
        return all(self._dense(p, d, u, v, cells) for u, v in pending)

    def _children_known(
        self, p: tuple[float, float], d: tuple[float, float], a: float, b: float, level: int
    ) -> bool:
        """Whether the child (``level + 1``) of the cell of piece (a, b) in which the
        piece's middle lies is decided already."""
        step = self.root / 2 ** (level + 1)
        m = 0.5 * (a + b)
        i = math.floor((p[0] + m * d[0]) / step)
        j = math.floor((p[1] + m * d[1]) / step)
        return (level + 1, i, j) in self._cells

    def _covered(self, level: int, pieces: list[tuple[float, float, int, int]], k: int) -> bool:
        """Whether the cell of piece k is covered, deciding it (and up to
        :data:`BATCH` undecided cells after it, for one batch of kinematics)."""
        i, j = pieces[k][2], pieces[k][3]
        if level == 0:
            if self._roots[i, j] == _UNKNOWN:
                ahead = [(c[2], c[3]) for c in pieces[k:] if self._roots[c[2], c[3]] == _UNKNOWN]
                todo = list(dict.fromkeys(ahead))[:BATCH]
                for (a, b), covered in zip(todo, self._decide(0, todo), strict=True):
                    self._roots[a, b] = _COVERED if covered else _OPEN
            return bool(self._roots[i, j] == _COVERED)
        known = self._cells.get((level, i, j))
        if known is None:
            ahead = [(c[2], c[3]) for c in pieces[k:] if (level, c[2], c[3]) not in self._cells]
            todo = list(dict.fromkeys(ahead))[:BATCH]
            for cell, covered in zip(todo, self._decide(level, todo), strict=True):
                self._cells[(level, cell[0], cell[1])] = covered
            known = self._cells[(level, i, j)]
        return known

    def _dense(
        self,
        p: tuple[float, float],
        d: tuple[float, float],
        t0: float,
        t1: float,
        cells: list[tuple[int, int, int]] | None,
    ) -> bool:
        """A piece of a segment through finest cells that are not covered (at the
        boundary of the safe set): certified by its own samples
        (:meth:`SafeSet.certify_samples`); their evaluation joins the certificate."""
        d12 = (p[0] + t0 * d[0], p[0] + t1 * d[0])
        d23 = (p[1] + t0 * d[1], p[1] + t1 * d[1])
        key = tuple(round(x, 9) for x in (*d12, *d23))
        known = self._runs.get(key)
        if known is None:
            self.stats["dense"] += 1
            ends = self.safe.theta_of(np.array(d12), np.array(d23), 0.0)
            if t0 == t1:  # a point (:meth:`contains`): one sample
                ends = ends[:1]
            ok, _, evaluation = self.safe.certify_samples(ends)
            self.stats["samples"] += int(evaluation.safe.size)
            if len(self._runs) >= SAMPLE_MEMO:
                self._runs.clear()
            known = self._runs[key] = (ok, evaluation)
        ok, evaluation = known
        if ok and cells is not None:
            self._dense_evaluations.append(evaluation)
        return ok

    def covers_segment(self, p: npt.ArrayLike, q: npt.ArrayLike) -> bool:
        """Every point of the gap-plane segment p-q [deg] lies in a covered cell."""
        return self._segment(p, q, None)

    def _segment(
        self, p: npt.ArrayLike, q: npt.ArrayLike, cells: list[tuple[int, int, int]] | None
    ) -> bool:
        a = [float(x) for x in np.asarray(p, dtype=float).ravel()]
        b = [float(x) for x in np.asarray(q, dtype=float).ravel()]
        if not all(math.isfinite(x) for x in (*a, *b)):
            return False
        p, d = (a[0], a[1]), (b[0] - a[0], b[1] - a[1])
        self._pending = []  # pieces in finest open cells, checked per root cell
        return self._walk(p, d, 0.0, 1.0, 0, cells)

    def gap_segments(self, theta: npt.ArrayLike) -> list[tuple[FloatArray, FloatArray]]:
        """The gap-plane segments [deg] of a polyline of input angles (n, 3) [rad]:
        each straight piece in input space is one straight segment of gaps (the gaps
        are linear in the inputs), from the first vertex's gaps on, unwrapped."""
        path = np.asarray(theta, dtype=float).reshape(-1, 3)
        d12, d23, _ = self.safe.gaps_of(path[:1])
        start = np.array([float(d12[0]), float(d23[0])])
        deg = np.degrees(path - path[0])
        points = start[None] + np.stack([deg[:, 0] - deg[:, 1], deg[:, 1] - deg[:, 2]], axis=1)
        return [(points[k], points[k + 1]) for k in range(points.shape[0] - 1)]

    def covers(self, theta: npt.ArrayLike) -> bool:
        """A polyline of input angles (n, 3) [rad] lies in covered cells all along."""
        return all(self._segment(p, q, None) for p, q in self.gap_segments(theta))

    def contains(self, theta: npt.ArrayLike) -> bool:
        """Input angles (3,) [rad] lie in a covered cell (so they are safe)."""
        points = self.gap_segments(np.vstack([theta, theta]))
        return self._segment(points[0][0], points[0][1], None)

    def certificate(self, theta: npt.ArrayLike) -> Evaluation | None:
        """The certificate of a polyline of input angles (n, 3) [rad] that lies in
        covered cells all along, or None. One row per certified cell it crosses (the
        smallest singularity margin and dexterity of the cell's corners; ``radius``
        the radius its corners were certified within), then the samples of the
        pieces certified by their own samples (at the boundary of the safe set).
        """
        cells: list[tuple[int, int, int]] = []
        self._dense_evaluations = []
        if not all(self._segment(p, q, cells) for p, q in self.gap_segments(theta)):
            return None
        minima = [self._minima[cell] for cell in dict.fromkeys(cells)]
        n = len(minima)
        parts = [
            Evaluation(
                reachable=np.ones(n, dtype=bool),
                singularity_margin=np.array([m[0] for m in minima], dtype=float),
                dexterity=np.array([m[1] for m in minima], dtype=float),
                colliding=np.zeros(n, dtype=bool),
                safe=np.ones(n, dtype=bool),
                radius=np.array([self._radius(c[0]) for c in dict.fromkeys(cells)], dtype=float),
            ),
            *self._dense_evaluations,
        ]
        if len(parts) == 1:
            return parts[0]
        return Evaluation(
            *(
                np.concatenate([getattr(part, f.name) for part in parts])
                for f in dataclasses.fields(Evaluation)
            )
        )

    # ------------------------------------------------------------------ whole set
    def fill(self, max_level: int = 3, progress: Callable[[int, int], None] | None = None) -> None:
        """Decide every root cell near the safe set, and halve the ones not covered
        wherever a corner is safe, down to ``max_level``: the cover of the whole safe
        set at once, what paths would otherwise grow cell by cell (finer cells are
        still decided when a path needs them). The prototype to level 3: about a
        minute and 6 MB saved; each level more doubles both (level 5, the finest:
        about 3.5 minutes on a busy 2-core machine and 24 MB, and paths then need
        far fewer samples of their own). ``progress(level, max_level)`` is called
        after each level."""
        self.prepare()
        safe = self.safe
        n = self._roots.shape[0]
        step = self.root
        # Root cells around the safe grid vertices of the safe set (within one grid
        # step): a cell with no safe vertex nearby has no safe corner.
        h = safe.settings.grid_step_deg
        near = np.zeros((n, n), dtype=bool)
        reach = math.ceil(h / step)
        for i, j in np.argwhere(safe.safe):
            ci, cj = round(safe.d12[i] / step), round(safe.d23[j] / step)
            near[max(0, ci - reach) : ci + reach, max(0, cj - reach) : cj + reach] = True
        todo = [(int(i), int(j)) for i, j in np.argwhere(near & (self._roots == _UNKNOWN))]
        for start in range(0, len(todo), 4096):
            chunk = todo[start : start + 4096]
            for (i, j), covered in zip(chunk, self._decide(0, chunk), strict=True):
                self._roots[i, j] = _COVERED if covered else _OPEN
        max_level = min(int(max_level), self.levels)
        if progress is not None:
            progress(0, max_level)
        open_cells = [(0, int(i), int(j)) for i, j in np.argwhere(self._roots == _OPEN)]
        for level in range(1, max_level + 1):
            children = []
            for parent, i, j in open_cells:
                if not any(
                    self._vertex_passes(key, self.levels) for key in self._corners(parent, i, j)
                ):
                    continue  # no corner safe: nothing to halve for
                children += [(2 * i + a, 2 * j + b) for a in (0, 1) for b in (0, 1)]
            children = [
                c for c in dict.fromkeys(children) if (level, c[0], c[1]) not in self._cells
            ]
            for start in range(0, len(children), 4096):
                chunk = children[start : start + 4096]
                for cell, covered in zip(chunk, self._decide(level, chunk), strict=True):
                    self._cells[(level, cell[0], cell[1])] = covered
            open_cells = [
                (level, i, j)
                for (lv, i, j), covered in self._cells.items()
                if lv == level and not covered
            ]
            if progress is not None:
                progress(level, max_level)

    def _fingerprint(self) -> str:
        """What the cells depend on: the design, the settings, the bounds, the tree."""
        safe = self.safe
        return json.dumps(
            {
                "design": safe.design.to_dict(),
                "settings": dataclasses.asdict(safe.settings),
                "lipschitz": dataclasses.asdict(safe.lipschitz),
                "root_step_deg": self.root,
                "levels": self.levels,
                "format": 1,
            },
            sort_keys=True,
            default=str,
        )

    def save(self, path: str | os.PathLike[str]) -> None:
        """Write the decided cells to ``path`` (a compressed ``.npz``; the prototype's
        whole cover: a few MB)."""
        cells = np.array(
            [(lv, i, j, int(c)) for (lv, i, j), c in self._cells.items()], dtype=np.int64
        ).reshape(-1, 4)
        minima = np.array(
            [(lv, i, j, s, d) for (lv, i, j), (s, d) in self._minima.items()], dtype=float
        ).reshape(-1, 5)
        with open(path, "wb") as stream:
            np.savez_compressed(
                stream,
                fingerprint=np.array(self._fingerprint()),
                roots=self._roots,
                cells=cells,
                minima=minima,
            )

    def load(self, path: str | os.PathLike[str], *, prepare: bool = True) -> None:
        """Take the cells decided in a file written by :meth:`save` for the same
        design, settings and bounds, and :meth:`prepare` the collision checks
        (``prepare=False``: not now, for a reader of the cells alone, such as the
        environments' lookup).

        Raises:
            InputError: a file that is not such a cover, or one of another design,
                other settings or other bounds.
        """
        try:
            with np.load(path, allow_pickle=False) as data:
                fingerprint = str(data["fingerprint"])
                roots = np.asarray(data["roots"], dtype=np.int8)
                cells = np.asarray(data["cells"], dtype=np.int64)
                minima = np.asarray(data["minima"], dtype=float)
        except (OSError, ValueError, KeyError) as exc:
            raise InputError(
                f"{os.fspath(path)!s} is not a saved cover of the safe set: {exc}",
                argument="path",
            ) from exc
        if fingerprint != self._fingerprint():
            raise InputError(
                f"{os.fspath(path)!s} holds the cover of another design, other settings "
                "or other continuity bounds: build it again (SafeCover.fill, then save)",
                argument="path",
            )
        if roots.shape != self._roots.shape or cells.ndim != 2 or minima.ndim != 2:
            raise InputError(f"{os.fspath(path)!s} is malformed", argument="path")
        self._roots = roots.copy()
        self._cells.update({(int(a), int(b), int(c)): bool(d) for a, b, c, d in cells})
        self._minima.update(
            {(int(a), int(b), int(c)): (float(s), float(d)) for a, b, c, s, d in minima}
        )
        if prepare:
            self.prepare()
