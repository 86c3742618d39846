r"""Certified early detection of inputs without a home-mode assembly (coaxial designs).

For a coaxial design the kinematics depend only on the gaps between the inputs, so
whether an input has a home-mode assembly depends only on the point
(d_1, d_2) = (wrap(theta_1 - theta_2), wrap(theta_2 - theta_3)) of the gap torus
[-pi, pi)^2. :func:`unreachable_table` covers that torus with square cells and marks
the cells in which *no* input can have a home-mode assembly, proven by a
branch-and-bound over the cell and the two cone angles (phi_1, phi_2) of
:mod:`.fk`:

A home-mode assembly is a point (phi_1, phi_2) with cos phi_1 > 0, cos phi_2 > 0
(b_11, b_22 > 0) where

- F_1 = v_1 . v_2 - v_10 . v_20 = 0 (rigid platform),
- F_2 = w_3 . v_3 - cos a2 = 0 (leg 3 closes), v_3 = a v_1 + b v_2 + d v_1 x v_2,
- F_3 = b_33 = (u x w_3) . v_3 > 0,
- F_4 = s det A > 0 (s the sign of det A at home).

Every F_k is Lipschitz in (phi_1, phi_2, theta_1, theta_2, theta_3) with constants
that follow from unit vectors (each v_i moves by at most sin a2 |d phi_i| and by at
most |d theta_i|, w_3 by sin a1 |d theta_3|; |v_3| <= |a| + |b| + |d|). A box of
(phi_1, phi_2) over a cell is excluded when at its centre some |F_1|, |F_2| or
-F_3, -F_4 exceeds the Lipschitz bound over the box plus ``_TOL`` (1e-9, far above
the 1e-12 residual and the rounding with which :func:`.fk.forward_kinematics`
accepts a solution). A cell is certified when every box of
[-pi/2, pi/2]^2 is excluded: then the batch path cannot accept a home-mode solution
for any input in it. Boxes and cells are refined together (a child cell keeps only
the boxes its parent could not exclude); a cell whose centre the fast solver
reaches is not refined further. Cells near the reachability boundary stay
undecided and take the usual path, so the rule never changes an answer.

Non-coaxial designs have no such 2-D reduction; they take the usual path.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from ..design import SPMDesign
from ._common import BoolArray, FloatArray, cross, proximal_axes

#: Cells per side of the finest table level (2 pi / 512 = 0.70 deg).
TABLE_SIZE = 512
#: Cells per side of the coarsest level.
_COARSE = 16
#: Margin of every exclusion, far above the solver's acceptance (1e-12) and rounding.
_TOL = 1e-9
#: Largest |cone angle| of a home-mode solution (cos phi > 0), with a margin.
_PHI_LIMIT = 0.5 * math.pi + 1e-6
#: Relative inflation of a cell (inputs on a cell edge may round into either cell).
_CELL_INFLATE = 1e-6
#: Designs whose table is kept (each 256 kB).
_MAX_TABLES = 8


def gap_index(theta: FloatArray) -> tuple[np.ndarray, np.ndarray]:
    """Table cell (row, column) of inputs theta (n, 3) of a coaxial design."""
    d = np.stack([theta[:, 0] - theta[:, 1], theta[:, 1] - theta[:, 2]], axis=-1)
    d = np.mod(d + math.pi, 2 * math.pi)  # in [0, 2 pi)
    index = np.clip((d * (TABLE_SIZE / (2 * math.pi))).astype(np.intp), 0, TABLE_SIZE - 1)
    return index[:, 0], index[:, 1]


def _lipschitz(design: SPMDesign) -> FloatArray:
    """Bounds on |dF_k/dx| for x = (phi_1, phi_2, theta_1, theta_2, theta_3), (4, 5)."""
    a, b, d = (abs(x) for x in design.platform_combination)
    s1, s2 = math.sin(design.alpha1), math.sin(design.alpha2)
    k = a + b + d  # |v_3| <= k
    f1 = [s2, s2, 1.0, 1.0, 0.0]
    f2 = [s2 * (a + d), s2 * (b + d), a + d, b + d, s1 * k]
    f3 = [s1 * x for x in f2]
    # det A = a_1 . (a_2 x a_3) with |a_1|, |a_2| <= 1, |a_3| <= k.
    f4 = [
        s2 * k + s2 * (a + d),
        s2 * k + s2 * (b + d),
        2 * k + (a + d),
        2 * k + (b + d),
        s1 * k + s1 * k,
    ]
    return np.array([f1, f2, f3, f4])


def _values(theta: FloatArray, phi1: FloatArray, phi2: FloatArray, design: SPMDesign) -> FloatArray:
    """(F_1, F_2, F_3, F_4) at inputs theta (m, 3) and cone angles (m,), shape (m, 4)."""
    w = proximal_axes(theta, design)
    u = design.u
    c2, s2 = math.cos(design.alpha2), math.sin(design.alpha2)
    v = []
    for i, phi in ((0, phi1), (1, phi2)):
        p = cross(u[i], w[:, i]) / math.sin(design.alpha1)
        q = cross(w[:, i], p)
        v.append(c2 * w[:, i] + s2 * (np.cos(phi)[:, None] * p + np.sin(phi)[:, None] * q))
    v1, v2 = v
    pa, pb, pd = design.platform_combination
    v12 = cross(v1, v2)
    v3 = pa * v1 + pb * v2 + pd * v12
    w3 = w[:, 2]
    f1 = np.sum(v1 * v2, axis=-1) - float(design.v0[0] @ design.v0[1])
    f2 = np.sum(w3 * v3, axis=-1) - c2
    f3 = np.sum(cross(u[2], w3) * v3, axis=-1)
    a1, a2, a3 = cross(w[:, 0], v1), cross(w[:, 1], v2), cross(w3, v3)
    f4 = math.copysign(1.0, design.home_det_a) * np.sum(a1 * cross(a2, a3), axis=-1)
    return np.stack([f1, f2, f3, f4], axis=-1)


def _cell_theta(d1: FloatArray, d2: FloatArray) -> FloatArray:
    """An input (n, 3) with gaps (d1, d2) and zero sum; a cell of half-width h around
    it is covered by |d theta| <= (h, 2h/3, h) (plus a common turn)."""
    return np.stack([(2 * d1 + d2) / 3, (d2 - d1) / 3, (-d1 - 2 * d2) / 3], axis=-1)


_TABLES: dict[SPMDesign, BoolArray] = {}


def cached_table(design: SPMDesign) -> BoolArray | None:
    """The table of ``design`` if it is built already, else None."""
    return _TABLES.get(design)


def unreachable_table(design: SPMDesign, reachable: Callable[[FloatArray], BoolArray]) -> BoolArray:
    """(TABLE_SIZE, TABLE_SIZE): True where every input of the gap cell has no
    home-mode assembly (certified); indexed by :func:`gap_index`. Coaxial designs only;
    built once per design (about a second) and kept.

    ``reachable(theta)`` is the home-mode solver's verdict on inputs (n, 3): cells whose
    centre it reaches are not refined (the caller hands it in, so that this module does
    not import the solver that uses it)."""
    if design in _TABLES:
        return _TABLES[design]
    if not design.is_coaxial:
        raise ValueError("the gap table needs a coaxial design")
    if len(_TABLES) >= _MAX_TABLES:
        _TABLES.pop(next(iter(_TABLES)))
    table = _build_table(design, reachable)
    _TABLES[design] = table
    return table


def _build_table(design: SPMDesign, reachable: Callable[[FloatArray], BoolArray]) -> BoolArray:
    lip = _lipschitz(design)
    table = np.zeros((TABLE_SIZE, TABLE_SIZE), dtype=bool)
    n = _COARSE
    # Cells as (row, column) at level size n; boxes as (cell, phi1, phi2) with half-width hb.
    row, col = (a.ravel() for a in np.meshgrid(np.arange(n), np.arange(n), indexing="ij"))
    k0 = 8
    hb = _PHI_LIMIT / k0
    grid = -_PHI_LIMIT + hb * (2 * np.arange(k0) + 1)
    cell = np.repeat(np.arange(row.size), k0 * k0)
    p1 = np.tile(np.repeat(grid, k0), row.size)
    p2 = np.tile(np.tile(grid, k0), row.size)
    while True:
        width = 2 * math.pi / n
        hc = 0.5 * width * (1 + _CELL_INFLATE)
        d1 = -math.pi + width * (row + 0.5).astype(np.float64)
        d2 = -math.pi + width * (col + 0.5).astype(np.float64)
        centre = _cell_theta(d1, d2)
        # Refine the boxes of each cell until they are no wider than the cell.
        while True:
            values = _values(centre[cell], p1, p2, design)
            spread = lip[:, :2].sum(axis=1) * hb + lip[:, 2:] @ np.array([hc, 2 * hc / 3, hc])
            margin = spread + _TOL
            keep = (
                (np.abs(values[:, 0]) <= margin[0])
                & (np.abs(values[:, 1]) <= margin[1])
                & (values[:, 2] >= -margin[2])
                & (values[:, 3] >= -margin[3])
            )
            cell, p1, p2 = cell[keep], p1[keep], p2[keep]
            if hb <= hc:
                break
            hb *= 0.5
            cell = np.repeat(cell, 4)
            p1 = np.repeat(p1, 4) + np.tile([-hb, -hb, hb, hb], p1.size)
            p2 = np.repeat(p2, 4) + np.tile([-hb, hb, -hb, hb], p2.size)
        alive = np.zeros(row.size, dtype=bool)
        alive[cell] = True
        scale = TABLE_SIZE // n
        for r, c in zip(row[~alive], col[~alive], strict=True):
            table[r * scale : (r + 1) * scale, c * scale : (c + 1) * scale] = True
        if n >= TABLE_SIZE:
            break
        # Split the undecided cells whose centre is not reachable; children inherit the
        # parent's surviving boxes.
        open_cells = np.nonzero(alive)[0]
        reach = reachable(centre[open_cells])
        open_cells = open_cells[~reach]
        new_index = np.full(row.size, -1)
        new_index[open_cells] = np.arange(open_cells.size)
        sel = new_index[cell] >= 0
        cell, p1, p2 = new_index[cell[sel]], p1[sel], p2[sel]
        row = (2 * row[open_cells, None] + np.array([0, 0, 1, 1])).ravel()
        col = (2 * col[open_cells, None] + np.array([0, 1, 0, 1])).ravel()
        cell = (4 * np.repeat(cell, 4) + np.tile(np.arange(4), cell.size)).astype(np.intp)
        p1, p2 = np.repeat(p1, 4), np.repeat(p2, 4)
        n *= 2
    table.setflags(write=False)
    return table
