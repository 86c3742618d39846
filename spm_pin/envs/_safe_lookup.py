"""Certified cells of the gap plane as arrays: which of a batch of input angles a
saved cover proves safe, without a check (:class:`SafeLookup`).

A :class:`~spm_pin.planning.cover.SafeCover` certifies cells of the gap plane
(D12, D23) safe at every point: each corner passes the safe set's checks with the
singularity margin, the dexterity and the clearance margin (plus the yaw tolerance)
raised by their Lipschitz bounds times the cell's radius. Input angles whose gaps lie
in such a cell are safe for the safe set, whatever the turn about the axis. The
lookup maps N input angles to their gaps, the gaps to the indices of the cell that
holds them at each level, and the indices to the covered cells: a root cell by
indexing a boolean mask, a finer cell by a binary search in the sorted keys of the
covered cells of its level (numpy), or by a bit of its root cell's bitmap (the
compiled lookup, :meth:`SafeLookup.arrays`). A point on a grid line lies in the
cells on both sides; the one below it is taken (both are closed, so either certifies
it).

The joint limits are not a property of the gaps: the caller checks them first.
"""

from __future__ import annotations

import os
from typing import Any

import numpy as np
import numpy.typing as npt

from ..errors import InputError
from ..planning import SafeCover, SafeSet
from . import _kinematic_kernel as K
from ._kinematic_kernel import Cover

__all__ = ["BITMAP_DEPTH", "SafeLookup"]

FloatArray = npt.NDArray[np.float64]
BoolArray = npt.NDArray[np.bool_]
IntArray = npt.NDArray[np.int64]

#: The deepest level of a cover that the compiled lookup holds as bitmaps (a root's
#: 4**5 bits: 128 bytes); deeper levels are searched in their sorted keys.
BITMAP_DEPTH = 5


class SafeLookup:
    """The covered cells of ``cover``, looked up for many input angles at once.

    Args:
        cover: A cover of the safe set (filled or loaded); its cells covered now are
            taken (later changes to it are not seen).

    Attributes:
        safe_set: The cover's safe set.
    """

    def __init__(self, cover: SafeCover) -> None:
        self.safe_set: SafeSet = cover.safe
        self.root_step_deg = cover.root
        roots, cells = cover.covered_cells()
        self._roots = roots
        n = roots.shape[0]
        # Per level with covered cells: (side [deg], lattice size, sorted keys i * size + j).
        self._levels: list[tuple[float, int, npt.NDArray[np.int64]]] = []
        for level in np.unique(cells[:, 0]).tolist():
            rows = cells[cells[:, 0] == level]
            size = n * 2**level
            keys = np.sort(rows[:, 1] * size + rows[:, 2])
            self._levels.append((self.root_step_deg / 2**level, size, keys))
        self._asked = 0
        self._settled = 0
        #: Counters (2,) (asked, settled) that compiled steps add to (:meth:`track`).
        self._tracked: list[npt.NDArray[np.int64]] = []
        #: Look up with the compiled kernel where numba is installed (the same
        #: answers as numpy); False: numpy always.
        self.compiled = True
        self._kernel: Any = None
        self._arrays: Any = None

    def track(self, counts: npt.NDArray[np.int64]) -> None:
        """Count the lookups that a compiled step adds to ``counts`` (2,) (asked,
        settled; never reset) in :attr:`asked` and :attr:`settled` from now on (what
        they hold now is counted already)."""
        self._asked -= int(counts[0])
        self._settled -= int(counts[1])
        self._tracked.append(counts)

    @property
    def asked(self) -> int:
        """Input angles looked up so far."""
        return self._asked + sum(int(counts[0]) for counts in self._tracked)

    @asked.setter
    def asked(self, value: int) -> None:
        self._asked = value - sum(int(counts[0]) for counts in self._tracked)

    @property
    def settled(self) -> int:
        """Of :attr:`asked`, how many lay in a covered cell."""
        return self._settled + sum(int(counts[1]) for counts in self._tracked)

    @settled.setter
    def settled(self, value: int) -> None:
        self._settled = value - sum(int(counts[1]) for counts in self._tracked)

    @classmethod
    def from_file(cls, safe_set: SafeSet, path: str | os.PathLike[str]) -> SafeLookup:
        """The lookup of the cover saved at ``path`` (:meth:`SafeCover.save`) for
        ``safe_set``'s design, settings and continuity bounds.

        Raises:
            InputError: ``path`` is not a saved cover, or one of another design,
                other settings or other bounds.
        """
        cover = SafeCover(safe_set)
        try:
            cover.load(path, prepare=False)  # the cells alone: no collision check
        except InputError as exc:
            raise InputError(
                f"cover: {exc} (make it for this design and these limits: SafeCover("
                "safe_set_of(settings.the_design, settings.plan_settings)), fill, save)",
                argument="cover",
                value=os.fspath(path),
            ) from exc
        return cls(cover)

    def arrays(self, depth: int = BITMAP_DEPTH) -> Cover:
        """The cover as the array of :func:`spm_pin.envs._kinematic_kernel.covered`:
        the header (eta_2 - eta_1, eta_3 - eta_2 [deg], root side [deg], 2**d, ...),
        the roots' index, their bitmaps of the cells at level d (the deepest level with
        covered cells, at most ``depth``), and per deeper level its side [deg], lattice
        size and the span of its sorted keys, then the keys."""
        n = self._roots.shape[0]
        levels = [((entry[1] // n).bit_length() - 1, entry) for entry in self._levels]
        shallow = [(lv, entry[2]) for lv, entry in levels if lv <= depth]
        deep = [entry for lv, entry in levels if lv > depth]
        d = max((lv for lv, keys in shallow if keys.size), default=0)
        for side, size, _ in deep:  # a key i * size + j in a float: exact below 2^53
            if float(size) ** 2 > 2.0**53:
                raise InputError(
                    f"cover: its cells of side {side:g} deg are too fine for the compiled "
                    f"lookup (a lattice of {size} cells per side); fill it to a coarser level",
                    argument="cover",
                    value=size,
                )
        eta = np.degrees(np.asarray(self.safe_set.design.eta, dtype=float))
        index, words = self._bitmaps(shallow, d)
        at_words = K.HEADER + n * n
        at_table = at_words + words.size
        at_keys = at_table + K.TABLE_ROW * len(deep)
        header = np.zeros(K.HEADER)
        header[[K.GAP12, K.GAP23, K.ROOT_SIDE, K.CELLS, K.ROOTS]] = (
            eta[1] - eta[0],
            eta[2] - eta[1],
            self.root_step_deg,
            2.0**d,
            n,
        )
        header[[K.WORDS, K.LEVELS, K.TABLE]] = at_words, len(deep), at_table
        table = np.zeros((len(deep), K.TABLE_ROW))
        start = at_keys
        for row, (side, size, keys) in enumerate(deep):
            table[row] = side, size, start, start + keys.size
            start += keys.size
        parts = [header, index.reshape(-1), words, table.reshape(-1)]
        parts += [keys.astype(np.float64) for _, _, keys in deep]
        return np.concatenate(parts).astype(np.float64)

    def _bitmaps(self, levels: list[tuple[int, IntArray]], d: int) -> tuple[FloatArray, FloatArray]:
        """(index, words) of :func:`~spm_pin.envs._kinematic_kernel.covered` for the
        covered cells of ``levels`` ((level, sorted keys) each, none deeper than d), as
        floats: the index (n, n), the words (:data:`~spm_pin.envs._kinematic_kernel.
        WORD_BITS` bits each)."""
        n = self._roots.shape[0]
        index = np.full((n, n), K.ROOT_EMPTY, dtype=np.int64)
        cells = 2**d
        per_root = -(-(cells * cells) // K.WORD_BITS)  # words per root
        found = [(lv, keys // (n * 2**lv), keys % (n * 2**lv)) for lv, keys in levels]
        flat = np.unique(np.concatenate([np.zeros(0, np.int64)] + [
            (i >> lv) * n + (j >> lv) for lv, i, j in found
        ]))  # fmt: skip
        index.reshape(-1)[flat] = np.arange(flat.size, dtype=np.int64) * per_root
        index[self._roots] = K.ROOT_COVERED
        words = np.zeros(flat.size * per_root, dtype=np.uint64)
        for lv, i, j in found:
            if i.size == 0:
                continue
            first = index.reshape(-1)[(i >> lv) * n + (j >> lv)]
            keep = first >= 0  # not under a covered root
            span = 2 ** (d - lv)  # the bitmap's cells per side of this level's cell
            row = (i - ((i >> lv) << lv)) * span
            column = (j - ((j >> lv) << lv)) * span
            for di in range(span):
                for dj in range(span):
                    bit = (row + di) * cells + column + dj
                    np.bitwise_or.at(
                        words,
                        (first + (bit >> K.WORD_SHIFT))[keep],
                        (np.uint64(1) << (bit & (K.WORD_BITS - 1)).astype(np.uint64))[keep],
                    )
        return index.astype(np.float64), words.astype(np.float64)

    @property
    def covered_root_cells(self) -> int:
        """How many root cells are covered."""
        return int(np.count_nonzero(self._roots))

    @property
    def covered_finer_cells(self) -> int:
        """How many finer cells are covered (every level)."""
        return sum(int(keys.size) for _, _, keys in self._levels)

    def covered(self, theta: FloatArray) -> BoolArray:
        """Whether each of the input angles (n, 3) [rad] has its gaps in a covered
        cell (so it passes the safe set's checks), (n,)."""
        kernel = self._covered_kernel()
        if kernel is not None:
            angles = np.ascontiguousarray(theta, dtype=np.float64).reshape(-1, 3)
            found = np.empty(angles.shape[0], dtype=bool)
            kernel(angles, self._arrays, found)
            self._asked += int(found.size)
            self._settled += int(np.count_nonzero(found))
            return found
        return self._covered_numpy(theta)

    def _covered_kernel(self) -> Any:
        """The compiled :func:`~spm_pin.envs._kinematic_kernel.covered_rows`, or None."""
        if not self.compiled:
            return None
        if self._kernel is None:
            from .. import _jit
            from . import _kinematic_kernel

            if not _jit.available():
                self.compiled = False
                return None
            self._arrays = self.arrays()
            self._kernel = _jit.kernels(_kinematic_kernel.KERNELS)["covered_rows"]
        return self._kernel

    def _covered_numpy(self, theta: FloatArray) -> BoolArray:
        """:meth:`covered` in numpy."""
        d12, d23, _ = self.safe_set.gaps_of(theta)
        n = self._roots.shape[0]
        step = self.root_step_deg
        i, j = np.floor(d12 / step), np.floor(d23 / step)
        inside = (i >= 0.0) & (i < n) & (j >= 0.0) & (j < n)  # NaN: outside
        result = np.zeros(d12.shape[0], dtype=bool)
        rows = np.flatnonzero(inside)
        result[rows] = self._roots[i[rows].astype(np.intp), j[rows].astype(np.intp)]
        for side, size, keys in self._levels:
            rows = rows[~result[rows]]
            if rows.size == 0:
                break
            key = np.floor(d12[rows] / side).astype(np.int64) * size + np.floor(
                d23[rows] / side
            ).astype(np.int64)
            at = np.minimum(np.searchsorted(keys, key), keys.size - 1)
            result[rows[keys[at] == key]] = True
        self._asked += int(result.size)
        self._settled += int(np.count_nonzero(result))
        return result
