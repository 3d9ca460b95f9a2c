"""Local registration: a smooth displacement field on top of the global fit (seed §2.3).

Seed §2.3: small mis-registrations "may be locally approximated as a translational mis-registration". One
global motion cannot follow a scan's local distortion, a thermally warped panel or a flexing arm, so after
the global fit the globally warped reference ``W`` is compared with the inspection ``I`` tile by tile:

1. **Tiles and nodes.** The frame is cut into cells of ``tile_px / 2``; a tile is 2 x 2 cells, so tiles
   overlap by half and their centres (the nodes of the field) lie on the inner cell corners. The field is
   bilinear between nodes: each pixel weighs on its cell's four nodes through the hats ``p_r(row) p_c(col)``,
   kept as two small matrices (pixels x nodes, two non-zeros a row).
2. **Gauss-Newton on the nodes, on precomputed terms.** Inverse-compositional: the Jacobian is the gradient
   of ``W``, so the normal matrix over node pairs, ``P_r^T (w g g^T) P_c`` over the hats' products, is
   computed once per weight ("terms involving the Jacobian ... can be pre-computed", seed §2.3) and factored
   once by banded Cholesky (a node couples with its eight neighbours only). An iteration resamples the
   inspection once at ``x + u(x)`` for the current field ``u`` and needs ``P_r^T (w g r) P_c``.
3. **Smooth field.** The step minimises the data term with a membrane ``lambda |grad u|^2`` and a pull
   ``mu |u|^2`` towards the global fit (which holds nodes without data of their own), Levenberg-Marquardt
   damped; a step is scaled to move no node more than a pixel (the images' linear range).
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

from collections.abc import Callable
from dataclasses import dataclass
from functools import cache, partial, wraps
from typing import ParamSpec, TypeVar

import cv2
import numpy as np
from numpy.typing import NDArray
from scipy.linalg import cho_solve_banded, cholesky_banded
from scipy.sparse import csr_matrix
from threadpoolctl import ThreadpoolController

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
# The Gauss-Newton steps read the textured pixels alone when they are fewer than this fraction of the level
# (_Solver._stepping_pixels): 1,920 px binarised boards (DeepPCB pairs scaled 3x, a quarter textured) took
# 255-285 ms instead of 370, camera-like textures (all textured) would take twice as long.
_SPARSE_BELOW = 0.5


_P = ParamSpec("_P")
_R = TypeVar("_R")


@cache
def _blas() -> ThreadpoolController:
    return ThreadpoolController()


def _one_blas_thread(function: Callable[_P, _R]) -> Callable[_P, _R]:
    """Runs `function` with BLAS on one thread. The field's products are small (a few hundred pixels by ~20
    nodes), where OpenBLAS's threads only wait for one another: on a busy 2-core machine a DeepPCB pair's
    field took 381 ms with them and 41 ms without."""

    @wraps(function)
    def on_one_thread(*args: _P.args, **kwargs: _P.kwargs) -> _R:
        with _blas().limit(limits=1, user_api="blas"):
            return function(*args, **kwargs)

    return on_one_thread


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

    @_one_blas_thread
    def displacement(self, shape: tuple[int, int]) -> Image:
        """The field at every reference pixel, `shape` (rows, cols): array (rows, cols, 2), (ux, uy)."""
        return _interpolate(self.shift_xy, self._hats(shape))

    @_one_blas_thread
    def source_maps(self, matrix: FloatArray, shape: tuple[int, int]) -> tuple[Image, Image]:
        """Reference coordinates (map_x, map_y) of every inspection pixel ``y`` of `shape`.

        Solves ``G(x) + u(x) = y`` by the fixed-point iteration ``x <- G^-1(y - u(x))``, which contracts by
        the field's gradient (|grad u| << 1 for a smooth field: 3 px over a 500 px board is ~0.04); three
        rounds leave < 1e-4 px. The solution is found on every _MAP_STEP_PX-th pixel and interpolated
        bilinearly between them: exact where the field is bilinear (``G^-1`` is projective, near-affine); the
        field bends only at its nodes, tiles apart, and at the frame's edge, where it stops. The field is read
        at the samples from its exact per-pixel values (OpenCV's remap rounds the position to 1/32 px: ~1e-3
        px of field at a 3 px field's slope). On a 3 px field (``tests/imaging``) the maps solve the equation
        to 0.004 px RMS, 0.04 px at worst (a frame corner).
        """
        inverse = np.linalg.inv(matrix)
        # The field on the reference frame, where its nodes lie; constant beyond (the outer nodes').
        field = self.displacement((int(self.node_rows[-1]) + 1, int(self.node_cols[-1]) + 1))
        cols, rows = _sample_positions(shape[1])[None, :], _sample_positions(shape[0])[:, None]
        sampled = (int(rows.size), int(cols.size))
        shift_x = shift_y = np.zeros(sampled)
        map_x = map_y = np.zeros(sampled)
        for _ in range(_INVERSE_ROUNDS + 1):
            x, y = cols - shift_x, rows - shift_y
            denominator = inverse[2, 0] * x + inverse[2, 1] * y + inverse[2, 2]
            map_x = (inverse[0, 0] * x + inverse[0, 1] * y + inverse[0, 2]) / denominator
            map_y = (inverse[1, 0] * x + inverse[1, 1] * y + inverse[1, 2]) / denominator
            shifted = np.asarray(
                cv2.remap(
                    field,
                    map_x.astype(np.float32),
                    map_y.astype(np.float32),
                    cv2.INTER_LINEAR,
                    borderMode=cv2.BORDER_REPLICATE,
                ),
                dtype=np.float64,
            )
            shift_x, shift_y = shifted[..., 0], shifted[..., 1]
        # cv2.resize by _MAP_STEP_PX puts sample i exactly where _sample_positions put it; the samples reach
        # one step past either edge, so no pixel is extrapolated.
        size = (_MAP_STEP_PX * sampled[1], _MAP_STEP_PX * sampled[0])
        inside = (slice(_MAP_STEP_PX, _MAP_STEP_PX + shape[0]), slice(_MAP_STEP_PX, _MAP_STEP_PX + shape[1]))
        first, second = (
            np.ascontiguousarray(cv2.resize(coarse.astype(np.float32), size)[inside], dtype=np.float32)
            for coarse in (map_x, map_y)
        )
        return first, second

    @_one_blas_thread
    def std(self, shape: tuple[int, int], window: tuple[slice, slice] | None = None) -> Image:
        """The field's one-sigma uncertainty at every reference pixel: array (rows, cols, 2), (sx, sy), px.

        The uncertainty varies over a tile's size; read in the inspection frame, the global fit's few pixels
        of offset do not matter. `window` (rows, cols) of a frame of `shape`: only its pixels (a detector's
        box), the same values as the whole frame's there.
        """
        row_hat, col_hat = self._hats(shape)
        if window is not None:
            row_hat, col_hat = row_hat[window[0]], col_hat[window[1]]
        return _interpolate(self.shift_std_px, (row_hat, col_hat))

    def _hats(self, shape: tuple[int, int]) -> tuple[FloatArray, FloatArray]:
        return _hats(self.node_rows, shape[0]), _hats(self.node_cols, shape[1])


def _hats(nodes: FloatArray, size: int) -> FloatArray:
    """Each of `size` pixels' bilinear (hat) weights on the nodes at pixel positions `nodes`: array (size, K),
    two non-zeros a row (a pixel at fraction s between two nodes weighs 1 - s on the first and s on the
    second), constant beyond the outer nodes."""
    if nodes.size < 2:
        return np.ones((size, nodes.size))
    low, fraction = _hat_parts(nodes, np.arange(size, dtype=np.float64))
    hat = np.zeros((size, nodes.size))
    pixels = np.arange(size)
    hat[pixels, low] = 1.0 - fraction
    hat[pixels, low + 1] = fraction
    return hat


def _hat_parts(nodes: FloatArray, positions: FloatArray) -> tuple[NDArray[np.intp], FloatArray]:
    """Each position's first node and its fraction of the way to the next, clamped to the outer nodes
    (:func:`_hats`' two non-zeros are ``1 - fraction`` at ``low`` and ``fraction`` at ``low + 1``); needs two
    nodes or more."""
    position = np.interp(positions, nodes, np.arange(nodes.size, dtype=np.float64))
    low = np.minimum(position.astype(np.intp), nodes.size - 2)
    return low, position - low


def _interpolate(values: FloatArray, hats: tuple[FloatArray, FloatArray]) -> Image:
    """Bilinear interpolation of node values (R, C, K) to every pixel: ``P_r V_k P_c^T`` per component (`hats`
    from :func:`_hats`, (M, R) and (N, C)); array (M, N, K), float32."""
    row_hat, col_hat = (np.asarray(hat, dtype=np.float32) for hat in hats)
    layers = [
        row_hat @ np.asarray(values[..., k], dtype=np.float32) @ col_hat.T for k in range(values.shape[2])
    ]
    return np.ascontiguousarray(np.stack(layers, axis=-1), dtype=np.float32)


def _sample_positions(size: int) -> FloatArray:
    """Pixel positions of the inverse map's samples along an axis of `size` pixels: the centres of blocks of
    _MAP_STEP_PX pixels, one block more either side of the frame (``cv2.resize``'s alignment)."""
    blocks = -(-size // _MAP_STEP_PX) + 2
    return _MAP_STEP_PX * (np.arange(blocks, dtype=np.float64) - 1.0) + (_MAP_STEP_PX - 1) / 2.0


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

    def sampled(self, row_step: int) -> _Grid:
        """The same cells on every `row_step`-th row: a cell's rows are the sampled rows within it."""
        return _Grid(-(-self.row_edges // row_step), self.col_edges)

    def hats(self) -> tuple[FloatArray, FloatArray]:
        """Each pixel's hat weight on each node along the rows (M, R) and the columns (N, C)."""
        node_rows, node_cols = self.nodes
        return _hats(node_rows, int(self.row_edges[-1])), _hats(node_cols, int(self.col_edges[-1]))


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


def _membrane_times(field: FloatArray) -> FloatArray:
    """The prior's pull on the field (R, C, 2): ``lambda L u + mu u``, L the grid's membrane (graph Laplacian:
    each node less its four neighbours), the same on both components."""
    pulled = np.zeros_like(field)
    across = field[:, 1:] - field[:, :-1]
    pulled[:, 1:] += across
    pulled[:, :-1] -= across
    down = field[1:] - field[:-1]
    pulled[1:] += down
    pulled[:-1] -= down
    return np.asarray(_SMOOTHNESS * pulled + _GLOBAL_PULL * field, dtype=np.float64)


def _membrane_degree(rows: int, cols: int) -> FloatArray:
    """Neighbours of each node on an R x C grid (the membrane's diagonal)."""
    degree = np.full((rows, cols), 4.0)
    degree[[0, -1], :] -= 1.0
    degree[:, [0, -1]] -= 1.0
    return degree


@dataclass(frozen=True)
class _Couplings:
    """One component pair's entries of the node matrix ``sum w phi_j phi_k G`` on an R x C grid: a node with
    itself (R, C), with its right neighbour (R, C - 1), with the one below (R - 1, C), and across a cell's
    diagonals (R - 1, C - 1; both diagonals of a cell carry the same sum, the product of the same hats)."""

    self_: FloatArray
    right: FloatArray
    down: FloatArray
    diagonal: FloatArray

    @classmethod
    def of(cls, sums: FloatArray, rows: int, cols: int) -> _Couplings:
        """From ``P_r^T (w G) P_c`` over the hat products (same node first, then next node): (2R-1, 2C-1)."""
        return cls(sums[:rows, :cols], sums[:rows, cols:], sums[rows:, :cols], sums[rows:, cols:])

    def scaled(self, factor: float) -> _Couplings:
        return _Couplings(*(factor * part for part in (self.self_, self.right, self.down, self.diagonal)))


def _hat_pairs(hat: Image) -> Image:
    """Products of the hats of a node with itself and with the next node, per pixel: (size, 2 K - 1)."""
    return np.hstack([hat * hat, hat[:, :-1] * hat[:, 1:]])


class _Mesh:
    """Gauss-Newton on the node field itself (an inverse-compositional mesh, seed §2.3).

    The residual at a pixel depends on the four nodes of its cell through the bilinear weights
    ``phi_j(x) = p_r(row) p_c(col)``, so the normal matrix is ``N = sum_x w phi phi^T (J^-T g)(J^-T g)^T``
    over node pairs. With the hats as matrices (pixels x nodes, two non-zeros a row), every entry is a product
    ``P_r^T (w g_a g_b) P_c`` over the hats' pairwise products, computed once per reference and weight; each
    iteration needs only ``sum w phi g_a r``, over the textured pixels alone on a mostly flat image
    (:class:`_TexturedPixels`). The step minimises ``|r + g^T phi du|^2 + lambda (u + du)^T L (u + du) +
    mu |u + du|^2`` with N scaled so that a typical node weighs 1 (the smoothness is then scale-free). The
    matrix couples a node with its eight neighbours only: with the two components of a node side by side it
    is banded (half-width 2C + 3), factored once by Cholesky.
    """

    def __init__(
        self,
        grid: _Grid,
        hats: tuple[Image, Image],
        gradients: tuple[Image, Image],
        weight: Image,
        inverse: FloatArray,
    ) -> None:
        self.grid, self.inverse = grid, inverse
        self.shape = grid.tiles_shape
        rows, cols = self.shape
        row_pairs, col_pairs = (_hat_pairs(hat) for hat in hats)
        gx, gy = gradients
        xx, xy, yy = (weight * first * second for first, second in ((gx, gx), (gx, gy), (gy, gy)))

        def coupled(term: Image) -> FloatArray:
            return np.asarray(row_pairs.T @ term @ col_pairs, dtype=np.float64)

        carried = _carry(coupled(xx), coupled(xy), coupled(yy), inverse)
        cells = _carry(grid.cell_sums(xx), grid.cell_sums(xy), grid.cell_sums(yy), inverse)
        row_sizes, col_sizes = np.pad(np.diff(grid.row_edges), 1), np.pad(np.diff(grid.col_edges), 1)
        area = np.outer(row_sizes[:-1] + row_sizes[1:], col_sizes[:-1] + col_sizes[1:]).astype(np.float64)
        hxx, hxy, hyy = (grid.tiles_from_cells(term) for term in cells)
        self.tiles = _tiles(hxx, hxy, hyy, grid.tile_sums(weight), area)
        couplings = [_Couplings.of(term, rows, cols) for term in carried]
        textured = (couplings[0].self_ + couplings[2].self_).ravel()
        textured = textured[textured > 0]
        self.scale = float(np.median(textured)) / 2.0 if textured.size else 1.0
        self.factor = cholesky_banded(_banded_system(*(c.scaled(1.0 / self.scale) for c in couplings)))

    def step(self, field: FloatArray, gradient: FloatArray) -> FloatArray:
        """The Gauss-Newton update of the field (R, C, 2) from the nodes' gradient (R, C, 2)."""
        right_hand = -(gradient / self.scale + _membrane_times(field))
        change = cho_solve_banded((self.factor, False), right_hand.ravel())
        return np.asarray(field + change.reshape(field.shape), dtype=np.float64)


def _banded_system(xx: _Couplings, xy: _Couplings, yy: _Couplings) -> FloatArray:
    """Upper band of ``N + prior + damping`` with unknown ``2 (r C + c) + k`` for component k of node (r, c)
    (:func:`scipy.linalg.cholesky_banded`'s layout: entry (i, i + d) at ``[u - d, i + d]``)."""
    rows, cols = xx.self_.shape
    nodes = rows * cols
    upper = 2 * cols + 3
    band = np.zeros((upper + 1, 2 * nodes))
    index = np.arange(nodes).reshape(rows, cols)

    def put(first: NDArray[np.intp], offset: int, values: FloatArray) -> None:
        band[upper - offset, first.ravel() + offset] += values.ravel()

    diagonal = _SMOOTHNESS * _membrane_degree(rows, cols) + _GLOBAL_PULL + _DAMPING
    # A node with itself.
    put(2 * index, 0, xx.self_ + diagonal)
    put(2 * index + 1, 0, yy.self_ + diagonal)
    put(2 * index, 1, xy.self_)
    # Node (r, c) with node (r, c) + step: the x-x and y-y entries at 2 step, x of the first with y of the
    # second at 2 step + 1, y of the first with x of the second at 2 step - 1 (the x-y block is symmetric).
    neighbours = (
        (index[:, :-1], 1, "right", -_SMOOTHNESS),
        (index[:-1, :], cols, "down", -_SMOOTHNESS),
        (index[:-1, :-1], cols + 1, "diagonal", 0.0),
        (index[:-1, 1:], cols - 1, "diagonal", 0.0),
    )
    for first, step, part, membrane in neighbours:
        put(2 * first, 2 * step, getattr(xx, part) + membrane)
        put(2 * first + 1, 2 * step, getattr(yy, part) + membrane)
        put(2 * first, 2 * step + 1, getattr(xy, part))
        put(2 * first + 1, 2 * step - 1, getattr(xy, part))
    return band


def _gradients(image: Image) -> tuple[Image, Image]:
    # Sobel / 8: a central difference smoothed across the edge, which keeps noise out of the Jacobian.
    gx = np.asarray(cv2.Sobel(image, cv2.CV_32F, 1, 0, ksize=3, scale=0.125), dtype=np.float32)
    gy = np.asarray(cv2.Sobel(image, cv2.CV_32F, 0, 1, ksize=3, scale=0.125), dtype=np.float32)
    return gx, gy


def _forward_maps(matrix: FloatArray, shape: tuple[int, int], row_step: int = 1) -> tuple[Image, Image]:
    """Inspection coordinates ``matrix @ (x, y, 1)`` of every reference pixel of every `row_step`-th row:
    map_x, map_y (rows sampled, N)."""
    cols = np.arange(shape[1], dtype=np.float64)[None, :]
    rows = np.arange(0, shape[0], row_step, dtype=np.float64)[:, None]
    denominator = matrix[2, 0] * cols + matrix[2, 1] * rows + matrix[2, 2]
    map_x = (matrix[0, 0] * cols + matrix[0, 1] * rows + matrix[0, 2]) / denominator
    map_y = (matrix[1, 0] * cols + matrix[1, 1] * rows + matrix[1, 2]) / denominator
    return np.asarray(map_x, dtype=np.float32), np.asarray(map_y, dtype=np.float32)


# Points per row of the 2-D maps that cv2.remap reads the field's pixels through (below its 32767 a side).
_POINTS_PER_ROW = 1024


def _remap_points(image: Image, map_x: Image, map_y: Image, interpolation: int) -> Image:
    """`image` at the points ``(map_x, map_y)`` (1-D, float32) as cv2.remap reads them (border replicated)."""
    count = int(map_x.size)
    if not count:
        return np.zeros(0, np.float32)
    padded = -(-count // _POINTS_PER_ROW) * _POINTS_PER_ROW
    maps = np.zeros((2, padded), np.float32)
    maps[0, :count], maps[1, :count] = map_x, map_y
    rows = (-1, _POINTS_PER_ROW)
    moved = cv2.remap(
        image, maps[0].reshape(rows), maps[1].reshape(rows), interpolation, borderMode=cv2.BORDER_REPLICATE
    )
    return np.asarray(moved, dtype=np.float32).ravel()[:count]


def _rows_of(values: FloatArray, columns: NDArray[np.intp], width: int) -> csr_matrix:
    """A sparse matrix with as many non-zeros on every row: `values` and their `columns`, both (K, n)."""
    count, per_row = values.shape
    pointers = np.arange(0, count * per_row + 1, per_row)
    return csr_matrix((values.ravel(), columns.ravel(), pointers), shape=(count, width))


class _EveryPixel:
    """Every pixel of a level's sampled rows (shape ``(rows, cols)``), the field read through the hats as
    matrices: ``P_r U P_c^T`` per component (three times faster than a remap of the node image) and
    ``P_r^T q P_c`` onto the nodes, both BLAS products."""

    def __init__(self, hats: tuple[FloatArray, FloatArray]) -> None:
        self.row_hat, self.col_hat = (np.asarray(hat, dtype=np.float32) for hat in hats)
        self.shape = (int(self.row_hat.shape[0]), int(self.col_hat.shape[0]))

    def at(self, image: NDArray[np.floating]) -> Image:
        """`image` (the level's sampled rows) as the pixels' values, 1-D float32."""
        return np.asarray(image, dtype=np.float32).ravel()

    def positions(self, flat: NDArray[np.intp]) -> NDArray[np.intp]:
        """Where the level's pixels at flat indices `flat` lie among these pixels: the same indices."""
        return flat

    def sample(self, image: Image, field: FloatArray, base: tuple[Image, Image], interpolation: int) -> Image:
        """`image` at the pixels' ``base + u`` for the node field `field` (R, C, 2), 1-D."""
        maps = [
            self.row_hat @ field[..., k].astype(np.float32) @ self.col_hat.T + base[k].reshape(self.shape)
            for k in (0, 1)
        ]
        moved = cv2.remap(image, maps[0], maps[1], interpolation, borderMode=cv2.BORDER_REPLICATE)
        return np.asarray(moved, dtype=np.float32).ravel()

    def node_sums(self, values: Image) -> FloatArray:
        """``sum phi_j q`` of per-pixel `values` (1-D) over each node's hats, (R, C)."""
        return np.asarray(self.row_hat.T @ values.reshape(self.shape) @ self.col_hat, dtype=np.float64)


class _TexturedPixels:
    """The pixels that move the field: used (weight > 0) and with a reference gradient (energy > 0).

    A pixel without gradient adds nothing to the normal matrix or to the nodes' gradient (both are weighted
    by the gradient), and a binarised board is mostly flat: 4-45 % of a half-size DeepPCB board's pixels
    have any gradient (ten trainval pairs, every hundredth). The Gauss-Newton steps then resample the
    inspection at these pixels only; the dense residual is formed once a level has converged (the trim and
    the uncertainty read every used pixel). ``spread`` is the bilinear field's matrix, pixels x nodes (four
    non-zeros a row, ``p_r(row) p_c(col)``): the field at the pixels is ``spread @ U``, and a per-pixel
    quantity summed onto the nodes is ``gather @ q`` (``spread``'s transpose, kept).
    """

    def __init__(
        self,
        index: NDArray[np.intp],
        columns: int,
        row_parts: tuple[NDArray[np.intp], FloatArray],
        col_parts: tuple[NDArray[np.intp], FloatArray],
        nodes_shape: tuple[int, int],
    ) -> None:
        self.index = index
        rows, cols = np.divmod(index, columns)
        row_low, row_fraction = (part[rows] for part in row_parts)
        col_low, col_fraction = (part[cols] for part in col_parts)
        first = row_low * nodes_shape[1] + col_low
        corners = np.stack([first, first + 1, first + nodes_shape[1], first + nodes_shape[1] + 1], axis=1)
        weights = np.stack(
            [
                (1.0 - row_fraction) * (1.0 - col_fraction),
                (1.0 - row_fraction) * col_fraction,
                row_fraction * (1.0 - col_fraction),
                row_fraction * col_fraction,
            ],
            axis=1,
        )
        self.spread = _rows_of(weights, corners, nodes_shape[0] * nodes_shape[1])
        self.gather = self.spread.T.tocsr()
        self.nodes_shape = nodes_shape

    def at(self, image: NDArray[np.floating]) -> Image:
        """`image`'s values at the pixels (1-D, float32)."""
        return np.asarray(image.ravel()[self.index], dtype=np.float32)

    def positions(self, flat: NDArray[np.intp]) -> NDArray[np.intp]:
        """Where the level's pixels at flat indices `flat` (all among these pixels) lie among them."""
        return np.searchsorted(self.index, flat)

    def sample(self, image: Image, field: FloatArray, base: tuple[Image, Image], interpolation: int) -> Image:
        """`image` at the pixels' ``base + u`` for the node field `field` (R, C, 2), 1-D."""
        shift = self.spread @ field.reshape(-1, 2)
        map_x, map_y = (np.asarray(shift[:, k] + base[k], dtype=np.float32) for k in (0, 1))
        return _remap_points(image, map_x, map_y, interpolation)

    def node_sums(self, values: Image) -> FloatArray:
        """``sum phi_j q`` of per-pixel `values` (1-D) over each node's hats, (R, C)."""
        return np.asarray(self.gather @ values.astype(np.float64)).reshape(self.nodes_shape)


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
        row_step: int = 1,
    ) -> None:
        # Every row_step-th row only (the sums over a tile's rows then hold its rows' sample).
        sampled = slice(None, None, row_step)
        self.reference, self.inspection, self.grid = reference[sampled], inspection, grid.sampled(row_step)
        self.field_limit = _MAX_FIELD_TILES * tile_px
        self.tolerance = tolerance
        self.interpolation = interpolation
        self.gx, self.gy = (gradient[sampled] for gradient in _gradients(reference))
        self.energy = self.gx * self.gx + self.gy * self.gy
        shape = (int(reference.shape[0]), int(reference.shape[1]))
        self.base_x, self.base_y = _forward_maps(matrix, shape, row_step)
        # The inspection's gradient at the matched point is J^-T times the reference's (J: the global
        # fit's Jacobian, exact for an affine fit; a homography's hardly varies over a board).
        self.inverse = np.linalg.inv(np.asarray(matrix[:2, :2] / matrix[2, 2], dtype=np.float64))
        row_hat, col_hat = grid.hats()
        self.hats = (row_hat[sampled], col_hat)
        self.field = np.zeros((*grid.tiles_shape, 2))
        self.iterations = 0
        used = weight[sampled]
        self.every_pixel = _EveryPixel(self.hats)
        self.pixels = self._stepping_pixels(used, grid, row_step)
        self.at_pixels = {
            name: self.pixels.at(image)
            for name, image in (
                ("reference", self.reference),
                ("gx", self.gx),
                ("gy", self.gy),
                ("base_x", self.base_x),
                ("base_y", self.base_y),
            )
        }
        self.set_weight(used)

    def _stepping_pixels(self, used: Image, grid: _Grid, row_step: int) -> _EveryPixel | _TexturedPixels:
        """The pixels the Gauss-Newton steps read: the textured ones alone where they are few (a binarised
        board), else every pixel (a camera's image, where the BLAS products over the whole level are faster
        than the sparse ones: 64 ms a 3 px warp of ``benchmarks/bench_local_registration.py`` against 139)."""
        textured = np.flatnonzero((used > 0) & (self.energy > 0))
        if textured.size >= _SPARSE_BELOW * used.size:
            return self.every_pixel
        node_rows, node_cols = grid.nodes
        rows, cols = self.every_pixel.shape
        return _TexturedPixels(
            textured,
            cols,
            _hat_parts(node_rows, np.arange(0, rows * row_step, row_step, dtype=np.float64)),
            _hat_parts(node_cols, np.arange(cols, dtype=np.float64)),
            grid.tiles_shape,
        )

    def set_weight(self, weight: Image) -> None:
        """Use `weight` (a trim only ever lowers it: the pixels stay a superset of those it uses)."""
        self.weight = weight
        self.weight_at = self.pixels.at(weight)
        hats = (self.every_pixel.row_hat, self.every_pixel.col_hat)
        self.mesh = _Mesh(self.grid, hats, (self.gx, self.gy), weight, self.inverse)
        self.textured = _textured_samples(weight, self.energy)
        self.textured_at = self.pixels.positions(self.textured)
        self.tiles = self.mesh.tiles

    def residual(self) -> Image:
        """The residual at every pixel of the level's sampled rows under the current field."""
        bases = (self.base_x, self.base_y)
        moved = self.every_pixel.sample(self.inspection, self.field, bases, self.interpolation)
        self.iterations += 1
        return moved.reshape(self.reference.shape) - self.reference

    def pixel_residual(self) -> Image:
        """The residual at the stepping pixels (1-D) under the current field."""
        values = self.at_pixels
        bases = (values["base_x"], values["base_y"])
        moved = self.pixels.sample(self.inspection, self.field, bases, self.interpolation)
        self.iterations += 1
        return moved - values["reference"]

    def gradient(self, residual: Image) -> FloatArray:
        """``sum w phi J^-T g r`` per node (R, C, 2) from the residual at the stepping pixels."""
        weighted = residual * self.weight_at
        first, second = (self.pixels.node_sums(weighted * self.at_pixels[name]) for name in ("gx", "gy"))
        (a, b), (c, d) = self.inverse
        return np.stack([a * first + c * second, b * first + d * second], axis=-1)

    def tile_gradient(self, residual: Image) -> FloatArray:
        """``sum w J^-T g r`` over each tile (uniform weights, R, C, 2)."""
        weighted = residual * self.weight
        first, second = (self.grid.tile_sums(weighted * gradient) for gradient in (self.gx, self.gy))
        (a, b), (c, d) = self.inverse
        return np.stack([a * first + c * second, b * first + d * second], axis=-1)

    def robust_gradient(self, residual: Image) -> FloatArray:
        """The nodes' gradient with each residual clipped at _HUBER_SIGMAS robust sigmas (Huber).

        A flaw's residual then pulls no harder than a mis-registered edge's; as Huber's weight never
        exceeds 1, the fixed normal matrix still bounds the curvature and every step still descends.
        """
        sigma = _robust_sigma(residual, self.textured_at)
        if sigma > 0.0:
            limit = np.float32(_HUBER_SIGMAS * sigma)
            residual = np.clip(residual, -limit, limit)
        return self.gradient(residual)

    def own_steps(self, residual: Image) -> FloatArray:
        """Each tile's own Gauss-Newton step ``H^-1 b`` from `residual` (R, C, 2); NaN without one."""
        b = self.tile_gradient(residual)
        t = self.tiles
        determinant = np.where(t.own, t.hxx * t.hyy - t.hxy * t.hxy, 1.0)
        step = np.stack(
            [
                (t.hyy * b[..., 0] - t.hxy * b[..., 1]) / determinant,
                (t.hxx * b[..., 1] - t.hxy * b[..., 0]) / determinant,
            ],
            axis=-1,
        )
        return np.where(t.own[..., None], step, np.nan)

    def tile_means(self) -> FloatArray:
        """The field's mean over each tile (R, C, 2)."""
        field = _interpolate(self.field, self.hats)
        area = self.grid.tile_sums(np.ones(self.reference.shape, np.float32))
        return np.stack([self.grid.tile_sums(field[..., axis]) / area for axis in (0, 1)], axis=-1)

    def run(self, max_iterations: int) -> None:
        """Gauss-Newton steps of the field to convergence (the residual read at the field's pixels only)."""
        for _ in range(max_iterations):
            residual = self.pixel_residual()
            proposed = self.mesh.step(self.field, self.robust_gradient(residual))
            change = proposed - self.field
            # A step beyond a pixel leaves the linear range of the lightly smoothed images: damp it. The whole
            # step is scaled, not each node's clipped: clipped node by node, the coarse level of DeepPCB
            # pair 20085203 (parallel traces) ran onto the neighbouring trace and a defect's box was lost.
            largest = float(np.abs(change).max(initial=0.0))
            if largest > _MAX_STEP_PX:
                change *= _MAX_STEP_PX / largest
            moved = np.clip(self.field + change, -self.field_limit, self.field_limit)
            # Converged when no node moves (one held at the trust bound may press on, in vain).
            change, self.field = moved - self.field, moved
            if float(np.abs(change).max(initial=0.0)) < self.tolerance:
                break


def _uncertainty(
    solver: _Solver, steps: FloatArray, residual: Image, scale: float
) -> tuple[FloatArray, NDArray[np.bool_]]:
    """Per-tile std of the shift in full-resolution inspection pixels (a level's pixel is `scale` of them),
    and which tiles fall back (no estimate of their own). `steps`: each tile's own step from the field
    (:meth:`_Solver.own_steps`), its misfit to it."""
    t = solver.tiles
    weighted = residual * solver.weight
    variance = solver.grid.tile_sums(weighted * residual) / np.maximum(t.used - 2.0, 1.0)
    determinant = np.where(t.own, t.hxx * t.hyy - t.hxy * t.hxy, 1.0)
    # sigma^2 H^-1 of the tile's own estimate, H already in inspection pixels.
    statistical = np.maximum(
        np.stack([variance * t.hyy / determinant, variance * t.hxx / determinant], -1), 0.0
    )
    misfit = np.nan_to_num(steps)
    std = scale * np.sqrt(statistical + misfit * misfit)
    held = np.abs(solver.field).max(axis=-1) >= solver.field_limit
    fallback = ~t.own | held | (std.max(axis=-1) > _MAX_STD_PX)
    std[fallback] = _MAX_STD_PX
    return std, fallback


def _textured_samples(weight: Image, energy: Image) -> NDArray[np.intp]:
    """Flat indices of the pixels a robust residual scale is taken on: every _SIGMA_STRIDE-th used pixel
    whose reference gradient energy is above the median of those, and not zero (a sample is enough for a
    scale).

    On a binarised board the flat copper and substrate have no residual at all, and their zeros would make
    every edge an outlier. Most of a board is flat, so the median energy itself is zero there: without the
    second condition the flat pixels came back, the scale was zero, Huber's clip fell away and the trim
    dropped every edge with any residual (3-29 % of the used pixels of DeepPCB pairs, most of their edges).
    Fixed for a weight: computed once, not at every step.
    """
    sampled = np.flatnonzero(weight.ravel()[::_SIGMA_STRIDE] > 0) * _SIGMA_STRIDE
    if not sampled.size:
        return sampled
    sampled_energy = energy.ravel()[sampled]
    return sampled[(sampled_energy >= np.median(sampled_energy)) & (sampled_energy > 0)]


def _robust_sigma(residual: Image, samples: NDArray[np.intp]) -> float:
    """Robust (MAD) sigma of the residual at the textured samples (flat indices into `residual`); 0 without
    any."""
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


def _pyramid(reference: Image, inspection: Image, levels: int) -> list[tuple[Image, Image]]:
    """Reference and inspection at levels 0 .. `levels`, each half the one before (cv2.pyrDown)."""
    pyramid = [(reference, inspection)]
    for _ in range(levels):
        reference, inspection = (np.asarray(cv2.pyrDown(image), dtype=np.float32) for image in pyramid[-1])
        pyramid.append((reference, inspection))
    return pyramid


def _level_solver(
    pyramid: list[tuple[Image, Image]],
    matrix: FloatArray,
    valid: NDArray[np.bool_],
    *,
    grid: _Grid,
    tile_px: int,
    level: int,
    tolerance: float,
    interpolation: int,
    row_step: int,
) -> _Solver:
    """A solver on `pyramid`'s `level` (``2**level`` times smaller), `matrix` and `grid` carried to it."""
    scale = np.diag([2.0**-level, 2.0**-level, 1.0])
    level_reference, level_inspection = pyramid[level]
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
        row_step=row_step,
    )


@_one_blas_thread
def estimate_field(
    reference: Image,
    inspection: Image,
    matrix: FloatArray,
    valid: NDArray[np.bool_],
    tile_px: int,
    *,
    finest_level: int = 0,
    tolerance_px: float = TOLERANCE_PX,
    row_step: int = 1,
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
    row_step : int
        The Gauss-Newton steps use every `row_step`-th row of each level (1: every row).
    """
    shape = (int(reference.shape[0]), int(reference.shape[1]))
    grid = _grid(shape, tile_px)
    level = min(finest_level, max(0, int(np.log2(tile_px / _MIN_TILE_PX))))
    # Bicubic resampling on the finest level: bilinear's bias follows the sub-pixel phase, which a smooth
    # field keeps nearly constant over a tile (0.045 px instead of 0.010 px on the 1 px test warps).
    coarser = tile_px >> level >= 2 * _MIN_TILE_PX
    pyramid = _pyramid(reference, inspection, level + coarser)
    on_level = partial(_level_solver, pyramid, matrix, valid, grid=grid, tile_px=tile_px, row_step=row_step)
    solver = on_level(level=level, tolerance=tolerance_px / 2.0**level, interpolation=cv2.INTER_CUBIC)
    if coarser:
        # The field found one level coarser first: twice the capture range, a quarter of the cost.
        coarse = on_level(level=level + 1, tolerance=tolerance_px, interpolation=cv2.INTER_LINEAR)
        coarse.run(_MAX_ITERATIONS)
        solver.field = 2.0 * coarse.field
    solver.run(_MAX_ITERATIONS)
    residual = solver.residual()
    # seed §2.4: a flaw is an outlier of the registration model; drop it and refine (a flaw must not pull
    # its tile).
    floor = (
        1e-3 * float(cv2.meanStdDev(reference, mask=valid.astype(np.uint8))[1][0, 0]) if valid.any() else 0.0
    )
    trimmed_weight = _trim_weight(residual, solver.weight, solver.textured, floor)
    used = float(solver.weight.sum())
    trimmed_fraction = float((used - float(trimmed_weight.sum())) / used) if used else 0.0
    if trimmed_fraction > 0.0:
        solver.set_weight(trimmed_weight)
        solver.run(_MAX_ITERATIONS)
        residual = solver.residual()
    steps = solver.own_steps(residual)
    measured = solver.tile_means() - steps
    # A level's pixel is 2**level full-resolution pixels; its nodes lie within a pixel of the full grid's.
    scale = 2.0**level
    std, fallback = _uncertainty(solver, steps, residual, scale)
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
