"""Local registration: a smooth displacement field on top of the global fit (seed §2.3).

Seed §2.3: small mis-registrations "may be locally approximated as a translational mis-registration". One
global motion cannot follow a scan's local distortion, a thermally warped panel or a flexing arm, so after
the global fit the globally warped reference ``W`` is compared with the inspection ``I`` tile by tile:

1. **Tiles.** The frame is cut into cells of ``tile_px / 2``; a tile is 2 x 2 cells, so tiles overlap by
   half and their centres (the nodes of the field) lie on the inner cell corners. Every per-tile sum is the
   sum of four per-cell sums (one ``np.add.reduceat`` per axis over the whole frame).
2. **Gauss-Newton per tile on precomputed terms.** Inverse-compositional translation: the Jacobian is the
   gradient of ``W`` and each tile's 2 x 2 Hessian ``H_k`` is computed once ("terms involving the Jacobian
   ... can be pre-computed", seed §2.3). An iteration resamples the inspection once at ``x + u(x)`` for the
   current field ``u``, and each tile's update is ``H_k^-1 sum g r``.
3. **Smooth field.** The tiles' own estimates ``t_k`` are combined by a regularised least-squares fit on the
   node grid, ``sum_k (u_k - t_k)^T H_k (u_k - t_k) / h0 + lambda |grad u|^2 + mu |u|^2`` (a membrane;
   ``mu`` pulls tiles without data of their own, and only those, towards the global fit), and the nodes
   are interpolated bilinearly to every pixel.
4. **Flaws do not pull their tile** (seed §2.4): once the field has converged, pixels whose residual lies
   beyond 4 robust sigmas are dropped, the tiles' Hessians are recomputed without them, and the field is
   refined again.
5. **Uncertainty.** A tile's shift std is ``sigma_k^2 H_k^-1`` (its own residual variance after the fit)
   combined with the misfit between its own estimate and the smooth field at its centre.
6. **Fallback.** A tile with too few usable pixels, a singular or ill-conditioned Hessian (no texture, or
   texture along one direction only) or a shift std above ``_MAX_STD_PX`` has no estimate of its own: the
   field there is the smooth continuation of its neighbours', the global fit where none has one, and the
   tile is reported in ``fallback``.
7. **Trust region.** The field is a small correction to the global fit (seed §2.3: "small
   mis-registrations"): no node moves more than an eighth of a tile along either axis (8 px for 64 px
   tiles, well beyond the 1-3 px a scan's distortion shows). Without it a coarse level whose tiles see
   parallel traces a few pixels apart locked onto the neighbouring trace: DeepPCB pair 20085203's nodes
   went to 26 px, and the fine level, at a pixel per step, never came back. A node held at the bound is
   reported in ``fallback``.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache, partial

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy import sparse
from scipy.sparse import linalg as sparse_linalg

from rsi.errors import InputError

FloatArray = NDArray[np.float64]
Image = NDArray[np.float32]

# Membrane weight relative to a typical node's data weight (the median diagonal of the normal matrix is 1).
# Fitted on the synthetic warps of tests/imaging/test_local_registration.py and on DeepPCB trainval pairs
# 20085000-20085050: 0.01-0.03 follow the 3 px test warps a little closer (0.03 px RMS at 0.1, 0.055 at 0.3)
# but let the nodes of a binarised board that see a trace along its length drift by tens of pixels; 0.1
# holds every node of those boards within 1-2 px.
_SMOOTHNESS = 0.1
# Pull of the global fit on every node (keeps the system definite when no tile has data).
_GLOBAL_PULL = 1e-3
# Levenberg-Marquardt damping of each step, relative to a typical node's data weight (1).
_DAMPING = 0.1
_TRIM_SIGMAS = 4.0
_HUBER_SIGMAS = 4.0
_SIGMA_STRIDE = 7
_MAD_TO_SIGMA = 1.4826
# A tile whose shift is known no better than this, in pixels, falls back (no texture of its own).
_MAX_STD_PX = 0.5
# ... or whose Hessian's eigenvalues differ by more than this (an edge in one direction only: aperture).
_MAX_CONDITION = 1e4
_MIN_USED_FRACTION = 0.25
_MIN_TILE_PX = 8
_MAX_ITERATIONS = 10
_INVERSE_ROUNDS = 3
# Largest change of the field in one Gauss-Newton step, pixels of the level: beyond it the linearisation
# of lightly smoothed images (a binarised board's edges are ~2 px wide) no longer holds.
_MAX_STEP_PX = 1.0
# Default convergence tolerance of the field, full-resolution pixels (estimate_field's tolerance_px).
TOLERANCE_PX = 0.01
# Spacing of the exact inverse-map samples that the warp interpolates (source_maps).
_MAP_STEP_PX = 4
# Largest departure of a node from the global fit, as a fraction of the tile, per axis (step 7 above).
_MAX_FIELD_TILES = 1.0 / 8.0


@dataclass(frozen=True)
class LocalField:
    """A smooth displacement field on top of the global registration (seed §2.3).

    The field lives on the reference grid: reference pixel ``x`` shows in the inspection at
    ``G(x) + u(x)``, ``G`` the global fit's matrix; ``u`` is how far the inspection's content lies from
    where the global fit puts it, in inspection pixels. Arrays are read-only.

    Attributes
    ----------
    tile_px : int
        Side of a tile; tiles overlap by half, their centres are the nodes (the outer ones on the frame's
        edge, their tiles half as large).
    node_rows, node_cols : ndarray of shape (R,) and (C,), float64
        Reference-pixel row and column of the node grid.
    shift_xy : ndarray of shape (R, C, 2), float64
        The smooth field ``(ux, uy)`` at the nodes, pixels.
    tile_shift_xy : ndarray of shape (R, C, 2), float64
        Each tile's own estimate; NaN where it fell back.
    shift_std_px : ndarray of shape (R, C, 2), float64
        One-sigma uncertainty of the field at each node: the tile's statistical std ``sigma_k^2 H_k^-1``
        combined with its estimate's misfit to the smooth field; ``_MAX_STD_PX`` where it fell back.
    fallback : ndarray of shape (R, C), bool
        Tiles without an estimate of their own (too few usable pixels, no texture, or texture along one
        direction only): the field there continues the neighbours', or is the global fit if none has one.
        Also the tiles whose node was held at the trust bound (an eighth of a tile from the global fit).
    iterations : int
        Resamplings of the inspection.
    trimmed_fraction : float
        Fraction of the used pixels dropped as flaws.
    """

    tile_px: int
    node_rows: FloatArray
    node_cols: FloatArray
    shift_xy: FloatArray
    tile_shift_xy: FloatArray
    shift_std_px: FloatArray
    fallback: NDArray[np.bool_]
    iterations: int
    trimmed_fraction: float

    def __post_init__(self) -> None:
        for name in ("node_rows", "node_cols", "shift_xy", "tile_shift_xy", "shift_std_px", "fallback"):
            value = np.array(getattr(self, name))
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    def displacement(self, shape: tuple[int, int]) -> Image:
        """The field at every reference pixel, `shape` (rows, cols): array (rows, cols, 2), (ux, uy)."""
        return _interpolate(self.shift_xy, _node_maps(self.node_rows, self.node_cols, shape))

    def source_maps(self, matrix: FloatArray, shape: tuple[int, int]) -> tuple[Image, Image]:
        """Reference coordinates (map_x, map_y) of every inspection pixel ``y`` of `shape`.

        Solves ``G(x) + u(x) = y`` by the fixed-point iteration ``x <- G^-1(y - u(x))``, which contracts by
        the field's gradient (|grad u| << 1 for a smooth field: 3 px over a 500 px board is ~0.04); three
        rounds leave < 1e-4 px. The solution is found on every _MAP_STEP_PX-th pixel, where the field is
        evaluated bilinearly in float64, and interpolated bilinearly between them: exact where the field is
        bilinear (``G^-1`` is projective, near-affine); the field bends only at its nodes, tiles apart, and
        at the frame's edge, where it stops. On a 3 px field (``tests/imaging``) the maps solve the equation
        to 0.004 px RMS, 0.04 px at worst (a frame corner); the per-pixel solution with OpenCV's remap of
        the nodes, 30 times slower, to 0.010 px RMS (it rounds positions to 1/32 of a tile).
        """
        inverse = np.linalg.inv(matrix)
        cols, rows = _sample_positions(shape[1])[None, :], _sample_positions(shape[0])[:, None]
        sampled = (int(rows.size), int(cols.size))
        shift_x = shift_y = np.zeros(sampled)
        map_x = map_y = np.zeros(sampled)
        for _ in range(_INVERSE_ROUNDS + 1):
            x, y = cols - shift_x, rows - shift_y
            denominator = inverse[2, 0] * x + inverse[2, 1] * y + inverse[2, 2]
            map_x = (inverse[0, 0] * x + inverse[0, 1] * y + inverse[0, 2]) / denominator
            map_y = (inverse[1, 0] * x + inverse[1, 1] * y + inverse[1, 2]) / denominator
            shift_x, shift_y = _bilinear(self.shift_xy, self.node_rows, self.node_cols, map_y, map_x)
        # cv2.resize by _MAP_STEP_PX puts sample i exactly where _sample_positions put it; the samples reach
        # one step past either edge, so no pixel is extrapolated.
        size = (_MAP_STEP_PX * sampled[1], _MAP_STEP_PX * sampled[0])
        inside = (slice(_MAP_STEP_PX, _MAP_STEP_PX + shape[0]), slice(_MAP_STEP_PX, _MAP_STEP_PX + shape[1]))
        first, second = (
            np.ascontiguousarray(cv2.resize(coarse.astype(np.float32), size)[inside], dtype=np.float32)
            for coarse in (map_x, map_y)
        )
        return first, second

    def std(self, shape: tuple[int, int]) -> Image:
        """The field's one-sigma uncertainty at every reference pixel: array (rows, cols, 2), (sx, sy), px.

        The uncertainty varies over a tile's size; read in the inspection frame, the global fit's few pixels
        of offset do not matter.
        """
        return _interpolate(self.shift_std_px, _node_maps(self.node_rows, self.node_cols, shape))


def _node_positions(nodes: FloatArray, size: int) -> NDArray[np.float32]:
    """Fractional node index of every pixel 0 .. size - 1, clamped to the outer nodes."""
    return np.interp(
        np.arange(size, dtype=np.float64), nodes, np.arange(nodes.size, dtype=np.float64)
    ).astype(np.float32)


def _node_maps(rows: FloatArray, cols: FloatArray, shape: tuple[int, int]) -> tuple[Image, Image]:
    """Every pixel's fractional node column and row: the maps of :func:`_interpolate` (fixed per grid)."""
    map_x = np.broadcast_to(_node_positions(cols, shape[1])[None, :], shape)
    map_y = np.broadcast_to(_node_positions(rows, shape[0])[:, None], shape)
    return np.ascontiguousarray(map_x), np.ascontiguousarray(map_y)


def _interpolate(values: FloatArray, maps: tuple[Image, Image]) -> Image:
    """Bilinear interpolation of node values (R, C, K) to every pixel (`maps` from :func:`_node_maps`),
    constant beyond the outer nodes."""
    # A remap of the tiny node image: exact bilinear weights, no BLAS (whose threads stall on busy cores).
    out = cv2.remap(
        np.ascontiguousarray(values, dtype=np.float32),
        *maps,
        cv2.INTER_LINEAR,
        borderMode=cv2.BORDER_REPLICATE,
    )
    shape = maps[0].shape
    return np.asarray(out, dtype=np.float32).reshape(shape[0], shape[1], values.shape[2])


def _sample_positions(size: int) -> FloatArray:
    """Pixel positions of the inverse map's samples along an axis of `size` pixels: the centres of blocks of
    _MAP_STEP_PX pixels, one block more either side of the frame (``cv2.resize``'s alignment)."""
    blocks = -(-size // _MAP_STEP_PX) + 2
    return _MAP_STEP_PX * (np.arange(blocks, dtype=np.float64) - 1.0) + (_MAP_STEP_PX - 1) / 2.0


def _bilinear(
    values: FloatArray, rows: FloatArray, cols: FloatArray, at_rows: FloatArray, at_cols: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The two components of node values (R, C, 2) at points, bilinear in float64, constant beyond the
    outer nodes (``cv2.remap`` would round the position to 1/32 of a node spacing, a pixel of a tile)."""
    row = np.interp(at_rows, rows, np.arange(rows.size, dtype=np.float64))
    col = np.interp(at_cols, cols, np.arange(cols.size, dtype=np.float64))
    low_row = np.minimum(row.astype(np.intp), max(rows.size - 2, 0))
    low_col = np.minimum(col.astype(np.intp), max(cols.size - 2, 0))
    t, s = row - low_row, col - low_col
    step_row, step_col = cols.size if rows.size > 1 else 0, 1 if cols.size > 1 else 0
    corner = low_row * cols.size + low_col
    weights = ((1 - t) * (1 - s), (1 - t) * s, t * (1 - s), t * s)
    offsets = (0, step_col, step_row, step_row + step_col)
    components = []
    for axis in (0, 1):
        flat = np.ascontiguousarray(values[..., axis]).ravel()
        components.append(sum(w * flat.take(corner + o) for w, o in zip(weights, offsets, strict=True)))
    return np.asarray(components[0], dtype=np.float64), np.asarray(components[1], dtype=np.float64)


@dataclass(frozen=True)
class _Grid:
    """Cells of about tile_px / 2; a node on every cell corner, frame corners included.

    Node j's tile is the two cells either side of it (one at the frame's edge), so tiles overlap by half
    and the bilinear field is defined up to the frame's edge without extrapolation.
    """

    row_edges: NDArray[np.intp]
    col_edges: NDArray[np.intp]

    @property
    def nodes(self) -> tuple[FloatArray, FloatArray]:
        def place(edges: NDArray[np.intp]) -> FloatArray:
            # Inner nodes between pixels edges[j] - 1 and edges[j]; outer ones on the first and last pixel.
            positions = edges.astype(np.float64) - 0.5
            positions[0], positions[-1] = 0.0, float(edges[-1] - 1)
            return positions

        return place(self.row_edges), place(self.col_edges)

    @property
    def tiles_shape(self) -> tuple[int, int]:
        return self.row_edges.size, self.col_edges.size

    def tile_sums(self, image: NDArray[np.floating]) -> FloatArray:
        """Sum of `image` over each node's tile, shape tiles_shape."""
        return self.tiles_from_cells(self.cell_sums(image))

    def cell_sums(self, image: NDArray[np.floating]) -> FloatArray:
        """Sum of `image` over each cell, shape (R - 1, C - 1)."""
        rows = np.add.reduceat(image, self.row_edges[:-1], axis=0)
        return np.asarray(np.add.reduceat(rows, self.col_edges[:-1], axis=1), dtype=np.float64)

    @staticmethod
    def tiles_from_cells(cells: FloatArray) -> FloatArray:
        """Per-node tile sums (the up to four cells around each node) from per-cell sums."""
        padded = np.pad(cells, 1)
        return np.asarray(
            padded[:-1, :-1] + padded[1:, :-1] + padded[:-1, 1:] + padded[1:, 1:], dtype=np.float64
        )

    def fractions(self) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
        """Each pixel's position between its cell's two nodes, 0 .. 1: (per row t, per column s)."""

        def along(edges: NDArray[np.intp], nodes: FloatArray) -> NDArray[np.float32]:
            pixels = np.arange(edges[-1], dtype=np.float64)
            cell = np.searchsorted(edges, pixels, side="right") - 1
            low, high = nodes[cell], nodes[cell + 1]
            return np.clip((pixels - low) / (high - low), 0.0, 1.0).astype(np.float32)

        node_rows, node_cols = self.nodes
        return along(self.row_edges, node_rows), along(self.col_edges, node_cols)


def _grid(shape: tuple[int, int], tile_px: int) -> _Grid:
    if not isinstance(tile_px, (int, np.integer)) or isinstance(tile_px, bool) or tile_px < _MIN_TILE_PX:
        raise InputError(f"tile_px must be an int >= {_MIN_TILE_PX}; got {tile_px!r}. Try 64.")
    if tile_px > min(shape):
        raise InputError(
            f"tile_px={tile_px} is larger than the image ({shape[0]} x {shape[1]} px): the grid needs at "
            f"least one whole tile. Pass tile_px <= {min(shape)}, e.g. {max(_MIN_TILE_PX, min(shape) // 4)}."
        )
    cell = tile_px / 2.0
    edges = []
    for size in shape:
        count = max(2, round(size / cell))
        edges.append(np.round(np.linspace(0, size, count + 1)).astype(np.intp))
    return _Grid(edges[0], edges[1])


@dataclass(frozen=True)
class _Tiles:
    """Per-tile (node) sums, in inspection pixels: Hessians ``hxx, hxy, hyy``, usable pixels ``used``,
    and ``own``: enough usable pixels and a well-conditioned Hessian, so the tile has an estimate of its own.
    """

    hxx: FloatArray
    hxy: FloatArray
    hyy: FloatArray
    used: FloatArray
    own: NDArray[np.bool_]


def _carry(
    xx: FloatArray, xy: FloatArray, yy: FloatArray, inverse: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """``K^T [[xx, xy], [xy, yy]] K`` for a 2 x 2 matrix K, element-wise."""
    (a, b), (c, d) = inverse
    return (
        a * a * xx + 2 * a * c * xy + c * c * yy,
        a * b * xx + (a * d + b * c) * xy + c * d * yy,
        b * b * xx + 2 * b * d * xy + d * d * yy,
    )


def _tiles(xx: FloatArray, xy: FloatArray, yy: FloatArray, used: FloatArray, area: FloatArray) -> _Tiles:
    trace = xx + yy
    determinant = xx * yy - xy * xy
    discriminant = np.sqrt(np.maximum(trace * trace / 4.0 - determinant, 0.0))
    low, high = trace / 2.0 - discriminant, trace / 2.0 + discriminant
    own = (used >= _MIN_USED_FRACTION * area) & (low > 0) & (high < _MAX_CONDITION * np.maximum(low, 1e-300))
    return _Tiles(xx, xy, yy, used, own)


@lru_cache(maxsize=8)
def _prior(rows: int, cols: int) -> sparse.csr_matrix:
    """The membrane and the global pull on both components of an R x C node grid (fixed per grid shape)."""
    laplacian = _SMOOTHNESS * _membrane(rows, cols) + _GLOBAL_PULL * sparse.eye(rows * cols)
    return sparse.block_diag([laplacian, laplacian], format="csr")


def _membrane(rows: int, cols: int) -> sparse.csr_matrix:
    def path(n: int) -> sparse.csr_matrix:
        difference = sparse.diags([np.ones(n - 1), -np.ones(n - 1)], [0, 1], shape=(n - 1, n))
        return (difference.T @ difference).tocsr()

    return (sparse.kron(sparse.eye(rows), path(cols)) + sparse.kron(path(rows), sparse.eye(cols))).tocsr()


# Along one axis a pixel at fraction s of its cell has hat weights (1 - s) for the cell's first node and
# s for its second: the coefficients of 1, s (and s^2 for products of two) of each weight and product.
_HAT = ((1.0, -1.0), (0.0, 1.0))
_HAT_PRODUCT = {
    (0, 0): (1.0, -2.0, 1.0),
    (0, 1): (0.0, 1.0, -1.0),
    (1, 0): (0.0, 1.0, -1.0),
    (1, 1): (0.0, 0.0, 1.0),
}
_CORNERS = ((0, 0), (0, 1), (1, 0), (1, 1))


class _Mesh:
    """Gauss-Newton on the node field itself (an inverse-compositional mesh, seed §2.3).

    The residual at a pixel depends on the four nodes of its cell through the bilinear weights phi, so the
    normal matrix is ``N = sum_x w phi phi^T (J^-T g)(J^-T g)^T`` over node pairs. Because phi is a product
    of a polynomial in the pixel's column fraction s and one in its row fraction t, N is assembled from
    per-cell moments ``sum w g_a g_b s^p t^q`` (p, q <= 2) computed once per reference and weight; each
    iteration needs only the moments ``sum w g_a r s^p t^q`` (p, q <= 1) of the residual. The step
    minimises ``|r + g^T phi du|^2 + lambda (u + du)^T L (u + du) + mu |u + du|^2`` with N scaled so that
    a typical node weighs 1 (the smoothness is then scale-free).
    """

    def __init__(self, grid: _Grid, gx: Image, gy: Image, weight: Image, inverse: FloatArray) -> None:
        self.grid, self.inverse = grid, inverse
        self.shape = grid.tiles_shape
        self.t, self.s = grid.fractions()
        moments = {
            key: self._moments(weight * first * second, 3)
            for key, (first, second) in {"xx": (gx, gx), "xy": (gx, gy), "yy": (gy, gy)}.items()
        }
        carried = _carry(moments["xx"], moments["xy"], moments["yy"], inverse)
        used_cells = grid.cell_sums(weight)
        row_sizes, col_sizes = np.pad(np.diff(grid.row_edges), 1), np.pad(np.diff(grid.col_edges), 1)
        area = np.outer(row_sizes[:-1] + row_sizes[1:], col_sizes[:-1] + col_sizes[1:]).astype(np.float64)
        xx, xy, yy = (grid.tiles_from_cells(term[0, 0]) for term in carried)
        self.tiles = _tiles(xx, xy, yy, grid.tiles_from_cells(used_cells), area)
        blocks = [self._assemble(term) for term in carried]
        diagonal = blocks[0].diagonal() + blocks[2].diagonal()
        textured = diagonal[diagonal > 0]
        self.scale = float(np.median(textured)) / 2.0 if textured.size else 1.0
        normal_xx, normal_xy, normal_yy = (block / self.scale for block in blocks)
        self.normal = sparse.bmat([[normal_xx, normal_xy], [normal_xy.T, normal_yy]], format="csr")
        nodes = self.shape[0] * self.shape[1]
        self.prior = _prior(*self.shape)
        # Levenberg-Marquardt damping: a node whose texture barely fixes it (a trace seen along its length,
        # a flaw's residual with little gradient under it) moves slowly instead of leaping; at convergence
        # the step is zero, so the damping does not bias the field.
        damping = _DAMPING * sparse.eye(2 * nodes)
        self.solve = sparse_linalg.factorized((self.normal + self.prior + damping).tocsc())

    def _moments(self, image: Image, order: int) -> FloatArray:
        """Per-cell ``sum image s^p t^q`` for p, q < order: array (order, order, R - 1, C - 1)."""
        out = np.empty((order, order, self.shape[0] - 1, self.shape[1] - 1))
        power = np.ones_like(self.s)
        for p in range(order):
            across = np.add.reduceat(image * power[None, :], self.grid.col_edges[:-1], axis=1)
            row_power = np.ones_like(self.t)
            for q in range(order):
                out[p, q] = np.add.reduceat(across * row_power[:, None], self.grid.row_edges[:-1], axis=0)
                row_power = row_power * self.t
            power = power * self.s
        return out

    def _assemble(self, moments: FloatArray) -> sparse.csr_matrix:
        """The (R C) x (R C) node matrix ``sum w phi_j phi_k G`` from one component's moments."""
        rows, cols = self.shape
        index = np.arange(rows * cols).reshape(rows, cols)
        entries, row_index, col_index = [], [], []
        for row_a, col_a in _CORNERS:
            for row_b, col_b in _CORNERS:
                across, down = _HAT_PRODUCT[(col_a, col_b)], _HAT_PRODUCT[(row_a, row_b)]
                value = sum(across[p] * down[q] * moments[p, q] for p in range(3) for q in range(3))
                entries.append(np.asarray(value).ravel())
                row_index.append(index[row_a : row_a + rows - 1, col_a : col_a + cols - 1].ravel())
                col_index.append(index[row_b : row_b + rows - 1, col_b : col_b + cols - 1].ravel())
        size = rows * cols
        return sparse.csr_matrix(
            (np.concatenate(entries), (np.concatenate(row_index), np.concatenate(col_index))),
            shape=(size, size),
        )

    def gradient(self, weighted_x: Image, weighted_y: Image) -> tuple[FloatArray, FloatArray]:
        """``sum w phi J^-T g r`` per node (R, C, 2), and per tile (uniform weights, R, C, 2)."""
        first, second = self._moments(weighted_x, 2), self._moments(weighted_y, 2)
        (a, b), (c, d) = self.inverse
        moments = (a * first + c * second, b * first + d * second)
        rows, cols = self.shape
        nodes = np.zeros((rows, cols, 2))
        for axis, component in enumerate(moments):
            for row_a, col_a in _CORNERS:
                across, down = _HAT[col_a], _HAT[row_a]
                value = sum(across[p] * down[q] * component[p, q] for p in range(2) for q in range(2))
                nodes[row_a : row_a + rows - 1, col_a : col_a + cols - 1, axis] += value
        tiles = np.stack([self.grid.tiles_from_cells(component[0, 0]) for component in moments], axis=-1)
        return nodes, tiles

    def step(self, field: FloatArray, gradient: FloatArray) -> FloatArray:
        """The Gauss-Newton update of the field (R, C, 2) from the nodes' gradient (R, C, 2)."""
        flat = np.concatenate([field[..., 0].ravel(), field[..., 1].ravel()])
        pull = np.concatenate([gradient[..., 0].ravel(), gradient[..., 1].ravel()])
        change = self.solve(-(pull / self.scale + self.prior @ flat))
        solution = flat + change
        size = self.shape[0] * self.shape[1]
        return np.stack([solution[:size], solution[size:]], axis=-1).reshape(*self.shape, 2)


def _gradients(image: Image) -> tuple[Image, Image]:
    # Sobel / 8: a central difference smoothed across the edge, which keeps noise out of the Jacobian.
    gx = np.asarray(cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3, scale=0.125), dtype=np.float32)
    gy = np.asarray(cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3, scale=0.125), dtype=np.float32)
    return gx, gy


def _forward_maps(matrix: FloatArray, shape: tuple[int, int]) -> tuple[Image, Image]:
    """Inspection coordinates ``matrix @ (x, y, 1)`` of every reference pixel: map_x, map_y (M, N)."""
    cols = np.arange(shape[1], dtype=np.float64)[None, :]
    rows = np.arange(shape[0], dtype=np.float64)[:, None]
    denominator = matrix[2, 0] * cols + matrix[2, 1] * rows + matrix[2, 2]
    map_x = (matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2]) / denominator
    map_y = (matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2]) / denominator
    return np.asarray(map_x, dtype=np.float32), np.asarray(map_y, dtype=np.float32)


class _Solver:
    """Iterates Gauss-Newton steps of the node field on one pyramid level.

    The field lives on the reference grid: reference pixel ``x`` shows in the inspection at
    ``G(x) + u(x)`` (``G`` the global fit). Each iteration resamples the inspection there once; the
    reference, its gradients and the mesh's normal matrix never change (seed §2.3, precomputed terms).
    """

    def __init__(
        self,
        reference: Image,
        inspection: Image,
        matrix: FloatArray,
        weight: Image,
        grid: _Grid,
        *,
        tile_px: int,
        tolerance: float,
        interpolation: int,
    ) -> None:
        self.reference, self.inspection, self.grid = reference, inspection, grid
        self.field_limit = _MAX_FIELD_TILES * tile_px
        self.tolerance = tolerance
        self.interpolation = interpolation
        self.gx, self.gy = _gradients(reference)
        self.energy = self.gx * self.gx + self.gy * self.gy
        shape = (int(reference.shape[0]), int(reference.shape[1]))
        self.base_x, self.base_y = _forward_maps(matrix, shape)
        # The inspection's gradient at the matched point is J^-T times the reference's (J: the global
        # fit's Jacobian, exact for an affine fit; a homography's hardly varies over a board).
        self.inverse = np.linalg.inv(np.asarray(matrix[:2, :2] / matrix[2, 2], dtype=np.float64))
        self.node_maps = _node_maps(*grid.nodes, shape)
        self.field = np.zeros((*grid.tiles_shape, 2))
        self.iterations = 0
        self.set_weight(weight)

    def set_weight(self, weight: Image) -> None:
        self.weight = weight
        self.mesh = _Mesh(self.grid, self.gx, self.gy, weight, self.inverse)
        self.textured = _textured_samples(weight, self.energy)
        self.tiles = self.mesh.tiles

    def residual(self) -> Image:
        field = _interpolate(self.field, self.node_maps)
        map_x = np.add(self.base_x, field[..., 0], dtype=np.float32)
        map_y = np.add(self.base_y, field[..., 1], dtype=np.float32)
        moved = cv2.remap(self.inspection, map_x, map_y, self.interpolation, borderMode=cv2.BORDER_REPLICATE)
        self.iterations += 1
        return np.asarray(moved, dtype=np.float32) - self.reference

    def gradient(self, residual: Image) -> tuple[FloatArray, FloatArray]:
        weighted = residual * self.weight
        return self.mesh.gradient(weighted * self.gx, weighted * self.gy)

    def robust_gradient(self, residual: Image) -> FloatArray:
        """The nodes' gradient with each residual clipped at _HUBER_SIGMAS robust sigmas (Huber).

        A flaw's residual then pulls no harder than a mis-registered edge's; as Huber's weight never
        exceeds 1, the fixed normal matrix still bounds the curvature and every step still descends.
        """
        sigma = _robust_sigma(residual, self.textured)
        if sigma > 0.0:
            limit = np.float32(_HUBER_SIGMAS * sigma)
            residual = np.clip(residual, -limit, limit)
        return self.gradient(residual)[0]

    def own_estimates(self, residual: Image) -> FloatArray:
        """Each tile's own estimate of the field's mean over it (mean less ``H^-1 b``); NaN without one."""
        _, b = self.gradient(residual)
        t = self.tiles
        determinant = np.where(t.own, t.hxx * t.hyy - t.hxy * t.hxy, 1.0)
        step = np.stack(
            [
                (t.hyy * b[..., 0] - t.hxy * b[..., 1]) / determinant,
                (t.hxx * b[..., 1] - t.hxy * b[..., 0]) / determinant,
            ],
            axis=-1,
        )
        means = self.grid.tile_sums(np.ones(self.reference.shape, np.float32))
        field = _interpolate(self.field, self.node_maps)
        mean = np.stack([self.grid.tile_sums(field[..., axis]) / means for axis in (0, 1)], axis=-1)
        return np.where(t.own[..., None], mean - step, np.nan)

    def run(self, max_iterations: int) -> Image:
        """Gauss-Newton steps of the field to convergence; returns the last residual."""
        residual = self.residual()
        for _ in range(max_iterations):
            proposed = self.mesh.step(self.field, self.robust_gradient(residual))
            change = proposed - self.field
            largest = float(np.abs(change).max(initial=0.0))
            # A step beyond a pixel leaves the linear range of the lightly smoothed images: damp it.
            if largest > _MAX_STEP_PX:
                change *= _MAX_STEP_PX / largest
            moved = np.clip(self.field + change, -self.field_limit, self.field_limit)
            # Converged when no node moves (one held at the trust bound may press on, in vain).
            change, self.field = moved - self.field, moved
            residual = self.residual()
            if float(np.abs(change).max(initial=0.0)) < self.tolerance:
                break
        return residual


def _uncertainty(
    solver: _Solver, measured: FloatArray, residual: Image, scale: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Per-tile std of the shift in full-resolution inspection pixels (a level's pixel is `scale` of them),
    and which tiles fall back (no estimate of their own)."""
    t = solver.tiles
    weighted = residual * solver.weight
    variance = solver.grid.tile_sums(weighted * residual) / np.maximum(t.used - 2.0, 1.0)
    determinant = np.where(t.own, t.hxx * t.hyy - t.hxy * t.hxy, 1.0)
    # sigma^2 H^-1 of the tile's own estimate, H already in inspection pixels.
    statistical = np.maximum(
        np.stack([variance * t.hyy / determinant, variance * t.hxx / determinant], -1), 0.0
    )
    own_fit = solver.own_estimates(np.zeros_like(residual))
    misfit = np.nan_to_num(measured - own_fit)
    std = scale * np.sqrt(statistical + misfit * misfit)
    held = np.abs(solver.field).max(axis=-1) >= solver.field_limit
    fallback = ~t.own | held | (std.max(axis=-1) > _MAX_STD_PX)
    std[fallback] = _MAX_STD_PX
    return std, fallback


def _textured_samples(weight: Image, energy: Image) -> NDArray[np.intp]:
    """Flat indices of the pixels a robust residual scale is taken on: every _SIGMA_STRIDE-th used pixel
    whose reference gradient energy is above the median of those (a sample is enough for a scale).

    On a binarised board the flat copper and substrate have no residual at all, and their zeros would make
    every edge an outlier. Fixed for a weight: computed once, not at every step.
    """
    sampled = np.flatnonzero(weight.ravel()[::_SIGMA_STRIDE] > 0) * _SIGMA_STRIDE
    if not sampled.size:
        return sampled
    sampled_energy = energy.ravel()[sampled]
    return sampled[sampled_energy >= np.median(sampled_energy)]


def _robust_sigma(residual: Image, samples: NDArray[np.intp]) -> float:
    """Robust (MAD) sigma of the residual at the textured samples; 0 without any."""
    return _MAD_TO_SIGMA * float(np.median(np.abs(residual.ravel()[samples]))) if samples.size else 0.0


def _trim_weight(residual: Image, weight: Image, samples: NDArray[np.intp], floor: float) -> Image:
    """`weight` less the outliers: |residual| beyond _TRIM_SIGMAS robust sigmas of the textured pixels."""
    sigma = max(_robust_sigma(residual, samples), floor)
    return np.asarray(weight * (np.abs(residual) <= _TRIM_SIGMAS * sigma), dtype=np.float32)


def _inner_weight(valid: NDArray[np.bool_], tile_px: int) -> Image:
    # No pixel within an eighth of a tile of the unusable area is used: the field moves the global fit's
    # points by a few pixels, and the resampled inspection must not reach past the image's edge.
    margin = max(2, tile_px // 8)
    kernel = np.ones((2 * margin + 1, 2 * margin + 1), np.uint8)
    inside = cv2.erode(valid.astype(np.uint8), kernel, borderType=cv2.BORDER_CONSTANT, borderValue=0)
    return inside.astype(np.float32)


def _level_grid(grid: _Grid, level: int, shape: tuple[int, int]) -> _Grid:
    """`grid`'s cells on the images ``2**level`` times smaller (``shape`` is that level's)."""
    return _Grid(np.minimum(grid.row_edges >> level, shape[0]), np.minimum(grid.col_edges >> level, shape[1]))


def _halved(image: Image, times: int) -> Image:
    for _ in range(times):
        image = np.asarray(cv2.pyrDown(image), dtype=np.float32)
    return image


def _level_solver(
    reference: Image,
    inspection: Image,
    matrix: FloatArray,
    valid: NDArray[np.bool_],
    *,
    grid: _Grid,
    tile_px: int,
    level: int,
    tolerance: float,
    interpolation: int,
) -> _Solver:
    """A solver on the images ``2**level`` times smaller, `matrix` and `grid` carried to them."""
    scale = np.diag([2.0**-level, 2.0**-level, 1.0])
    level_reference, level_inspection = _halved(reference, level), _halved(inspection, level)
    shape = (int(level_reference.shape[0]), int(level_reference.shape[1]))
    level_valid = cv2.resize(valid.astype(np.uint8), shape[::-1], interpolation=cv2.INTER_NEAREST)
    return _Solver(
        level_reference,
        level_inspection,
        scale @ matrix @ np.linalg.inv(scale),
        _inner_weight(level_valid.astype(bool), tile_px >> level),
        _level_grid(grid, level, shape),
        tile_px=tile_px >> level,
        tolerance=tolerance,
        interpolation=interpolation,
    )


def estimate_field(
    reference: Image,
    inspection: Image,
    matrix: FloatArray,
    valid: NDArray[np.bool_],
    tile_px: int,
    *,
    finest_level: int = 0,
    tolerance_px: float = TOLERANCE_PX,
) -> LocalField:
    """The local field between the smoothed reference and the smoothed inspection, after a global fit.

    Parameters
    ----------
    reference : ndarray of shape (M, N), float32
        The reference, lightly smoothed, gain and bias applied (``gain * reference + bias``).
    inspection : ndarray of shape (P, Q), float32
        The inspection, smoothed alike.
    matrix : ndarray of shape (3, 3)
        The global fit, reference pixel to inspection pixel.
    valid : ndarray of shape (M, N), bool
        Reference pixels that may be used (they map inside the inspection, and lie in the mask).
    tile_px : int
        Tile side (tiles overlap by half), full-resolution pixels.
    finest_level : int
        The field is solved on the images ``2**finest_level`` times smaller (0: full resolution) and scaled
        back to full-resolution pixels; tiles keep their full-resolution size, so a level keeps
        ``tile_px >> finest_level`` >= _MIN_TILE_PX pixels a side (coarser levels are not used).
    tolerance_px : float
        The Gauss-Newton steps stop when no node moves more than this, full-resolution pixels (the coarser
        level that gives the start: this many of its own pixels).
    """
    shape = (int(reference.shape[0]), int(reference.shape[1]))
    grid = _grid(shape, tile_px)
    level = min(finest_level, max(0, int(np.log2(tile_px / _MIN_TILE_PX))))
    # Bicubic resampling on the finest level: bilinear's bias follows the sub-pixel phase, which a smooth
    # field keeps nearly constant over a tile (0.045 px instead of 0.010 px on the 1 px test warps).
    on_level = partial(_level_solver, reference, inspection, matrix, valid, grid=grid, tile_px=tile_px)
    solver = on_level(level=level, tolerance=tolerance_px / 2.0**level, interpolation=cv2.INTER_CUBIC)
    if tile_px >> level >= 2 * _MIN_TILE_PX:
        # The field found one level coarser first: twice the capture range, a quarter of the cost.
        coarse = on_level(level=level + 1, tolerance=tolerance_px, interpolation=cv2.INTER_LINEAR)
        coarse.run(_MAX_ITERATIONS)
        solver.field = 2.0 * coarse.field
    residual = solver.run(_MAX_ITERATIONS)
    # seed §2.4: a flaw is an outlier of the registration model; drop it and refine (a flaw must not pull
    # its tile).
    floor = 1e-3 * float(np.std(reference[valid])) if valid.any() else 0.0
    trimmed_weight = _trim_weight(residual, solver.weight, solver.textured, floor)
    used = float(solver.weight.sum())
    trimmed_fraction = float((used - float(trimmed_weight.sum())) / used) if used else 0.0
    if trimmed_fraction > 0.0:
        solver.set_weight(trimmed_weight)
        residual = solver.run(_MAX_ITERATIONS)
    measured = solver.own_estimates(residual)
    # A level's pixel is 2**level full-resolution pixels; its nodes lie within a pixel of the full grid's.
    scale = 2.0**level
    std, fallback = _uncertainty(solver, measured, residual, scale)
    node_rows, node_cols = grid.nodes
    return LocalField(
        tile_px=int(tile_px),
        node_rows=node_rows.astype(np.float64),
        node_cols=node_cols.astype(np.float64),
        shift_xy=scale * solver.field,
        tile_shift_xy=np.where(fallback[..., None], np.nan, scale * measured),
        shift_std_px=std,
        fallback=fallback,
        iterations=solver.iterations,
        trimmed_fraction=trimmed_fraction,
    )
