"""Type stubs of the compiled part of freeform (units SI; shapes in the docstrings)."""

from os import PathLike
from typing import Any, Literal, Optional, Sequence, Union, overload

import numpy as np
import numpy.typing as npt

__version__: str

ArrayLike = npt.ArrayLike
Float2 = npt.NDArray[np.float64]
ObjectRef = Union[int, str]
Path = Union[str, PathLike]

def sample(
    shape: str,
    *,
    points: Optional[int] = None,
    spacing: Optional[float] = None,
    allow_open_mesh: bool = False,
) -> tuple[Float2, npt.NDArray[np.float64]]:
    """Points inside a shape (N, 3), metres, and their volumes (N,), m^3."""

def read_usd_kaolin(
    path: Path, prim: str, instance: str = "default", time: Optional[float] = None
) -> dict[str, Optional[dict[str, Any]]]:
    """Kaolin's physics schemas of a USD prim: {"material": ..., "skinned": ...} as arrays."""

def eigsh(
    h: Any,
    m: Any,
    nev: int,
    *,
    tol: float = 1e-8,
    max_iter: int = 1000,
    preconditioner: Any = None,
    check_symmetry: bool = False,
    progress: bool = False,
) -> tuple[npt.NDArray[np.float64], Float2]:
    """The nev smallest pairs of H x = lambda M x by freeform's native LOBPCG: values (nev,),
    ascending, the first 0 for the constant mode; vectors (K, nev), M-orthonormal. H and M
    (K x K, symmetric; H PSD with the constant vector in its null space, M SPD): scipy.sparse
    matrices (anything with tocoo()), or objects with shape and matmat(X) (K x b -> K x b) or
    matvec(x), like scipy.sparse.linalg.LinearOperator; an optional diagonal() enables
    Jacobi. preconditioner: such an object applying T ~ (H + sigma M)^-1. An exception raised
    by a callback stops the solve and is re-raised as is."""

class Basis:
    """Skinning eigenmodes: K RKPM kernels and the coefficients of m + 1 modes."""

    @staticmethod
    def from_shape(
        shape: str,
        *,
        kernels: int = 1000,
        modes: int = 16,
        kernel: Literal["cubic", "quartic", "gaussian"] = "cubic",
        support_factor: float = 2.0,
        support_neighbor: int = 4,
        points: Optional[int] = None,
        spacing: Optional[float] = None,
        eigensolver: str = "lobpcg",
        tol: float = 1e-8,
        max_iter: int = 1000,
        voxel: Optional[float] = None,
        total_volume: Optional[float] = None,
        youngs: float = 5e6,
        poisson: float = 0.45,
        density: float = 1000.0,
        allow_open_mesh: bool = False,
        regions: Optional[list[str]] = None,
        progress: bool = False,
    ) -> Basis:
        """A basis from a shape spec ("box:2,1,1", "sphere:0.5") or an OBJ/STL/OFF/PLY file.
        Material: Young's modulus (Pa), Poisson ratio, density (kg/m^3). points: integration
        point count (default 50 K, in [20,000, 2,000,000]); spacing: grid spacing, metres."""
    @staticmethod
    def from_points(
        points: ArrayLike,
        youngs: Union[float, ArrayLike],
        poisson: Union[float, ArrayLike, None] = None,
        density: Union[float, ArrayLike, None] = None,
        volumes: Optional[ArrayLike] = None,
        *,
        kernels: int = 1000,
        modes: int = 16,
        kernel: Literal["cubic", "quartic", "gaussian"] = "cubic",
        support_factor: float = 2.0,
        support_neighbor: int = 4,
        eigensolver: str = "lobpcg",
        tol: float = 1e-8,
        max_iter: int = 1000,
        voxel: Optional[float] = None,
        total_volume: Optional[float] = None,
        regions: Optional[list[str]] = None,
        progress: bool = False,
    ) -> Basis:
        """A basis from integration points (N, 3) in metres with per-point (or one) Young's
        modulus (Pa), Poisson ratio (default 0.45), density (kg/m^3, default 1000) and
        volumes (N,) in m^3 (None: estimated by a voxel fill of the cloud)."""
    @staticmethod
    def load(path: Path) -> Basis:
        """Read a basis file (.npz)."""
    def save(self, path: Path) -> None:
        """Write the basis file (.npz), all or nothing."""
    @property
    def kernels(self) -> int:
        """K."""
    @property
    def modes(self) -> int:
        """m, the non-constant modes (eigenvalues has m + 1 entries)."""
    @property
    def kernel(self) -> str: ...
    @property
    def eigenvalues(self) -> npt.NDArray[np.float64]:
        """(m + 1,), Pa/m^2, ascending; the first ~0 (constant mode)."""
    @property
    def coefficients(self) -> Float2:
        """(K, m + 1), M-orthonormal."""
    @property
    def centers(self) -> Float2:
        """(K, 3), metres."""
    @property
    def radii(self) -> npt.NDArray[np.float64]:
        """(K,), metres."""
    @property
    def report(self) -> Optional[dict[str, Any]]:
        """The build report (residuals, timings, coverage, warnings, monitors)."""
    @property
    def metadata(self) -> dict[str, Any]: ...
    @property
    def warnings(self) -> list[str]: ...
    @overload
    def weights(self, points: ArrayLike, gradients: Literal[False] = False) -> Float2:
        """W at points (N, 3): (N, m + 1), m^(-3/2)."""
    @overload
    def weights(
        self, points: ArrayLike, gradients: Literal[True]
    ) -> tuple[Float2, npt.NDArray[np.float64]]:
        """(W (N, m + 1), grad W (N, m + 1, 3))."""
    def evaluate(self, points: ArrayLike, coefficients: ArrayLike) -> Float2:
        """sum_k phi_k(x) C[k, :] at points (N, 3) for C (K, q): (N, q)."""

class Scene:
    """A scene (docs/scenes.md): objects, materials, boundaries, colliders, time stepping."""

    def add_object(
        self,
        name: str,
        basis: Basis,
        points: ArrayLike,
        youngs: Union[float, ArrayLike],
        poisson: Union[float, ArrayLike, None] = None,
        density: Union[float, ArrayLike, None] = None,
        volumes: Optional[ArrayLike] = None,
        *,
        boundaries: Optional[list[dict[str, Any]]] = None,
        placement: Optional[dict[str, Any]] = None,
        cubature: Optional[int] = None,
    ) -> None:
        """An object from arrays: its basis, integration points (N, 3) metres, per-point
        material (Pa, -, kg/m^3), volumes (N,) m^3."""

    @staticmethod
    def from_file(path: Path) -> Scene: ...
    @staticmethod
    def from_toml(text: str, base_dir: Optional[Path] = None) -> Scene: ...
    @staticmethod
    def from_dict(scene: dict[str, Any], base_dir: Optional[Path] = None) -> Scene: ...
    def to_toml(self) -> str: ...
    def to_dict(self) -> dict[str, Any]: ...
    @property
    def object_names(self) -> list[str]: ...
    @property
    def dt(self) -> float:
        """Time step, s."""
    @property
    def steps(self) -> int: ...
    @property
    def base_dir(self) -> str: ...

class World:
    """A scene being simulated, stepped live."""

    def __init__(
        self,
        scene: Scene,
        *,
        strict: bool = False,
        progress: bool = False,
        cache: Optional[bool] = None,
    ) -> None: ...
    def step(self, count: int = 1) -> list[dict[str, Any]]:
        """Advance count steps; the last step's report per object."""
    @property
    def time(self) -> float:
        """Simulated time, s."""
    @property
    def dt(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def object_names(self) -> list[str]: ...
    @property
    def warnings(self) -> list[str]: ...
    def positions(self, object: ObjectRef, out: Optional[Float2] = None) -> Float2:
        """Deformed render points (N, 3), metres."""
    def rest_positions(self, object: ObjectRef) -> Float2: ...
    def stress(self, object: ObjectRef) -> npt.NDArray[np.float64]:
        """Cauchy stress at the render points, (N, 3, 3), Pa."""
    def integration_positions(self, object: ObjectRef) -> Float2: ...
    def triangles(self, object: ObjectRef) -> Optional[npt.NDArray[np.uint32]]: ...
    def state(self, object: ObjectRef) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.float64]]:
        """(z, zdot), 12 (m + 1) each: z[4 (m + 1) r + 4 j + a] = Z_j[r, a], the 3 x 4 affine
        handle of mode j in x(X) = X + sum_j W_j(X) Z_j [X; 1]; zdot = dz/dt."""
    def set_state(self, object: ObjectRef, z: ArrayLike, zdot: ArrayLike) -> None: ...
    def set_gravity(self, gravity: Optional[Sequence[float]]) -> None:
        """m/s^2; None: off."""
    def set_boundary_pose(
        self,
        object: ObjectRef,
        boundary: int,
        rotation: Optional[ArrayLike] = None,
        translation: Optional[Sequence[float]] = None,
    ) -> None:
        """Hold the boundary at x = R X + t (R proper 3 x 3; t metres)."""
    def set_boundary_motion(self, object: ObjectRef, boundary: int, motion: Any) -> None: ...
    def set_collider_pose(
        self,
        collider: int,
        rotation: Optional[ArrayLike] = None,
        translation: Optional[Sequence[float]] = None,
    ) -> None: ...
    def set_placement(self, object: ObjectRef, placement: dict[str, Any]) -> None: ...
    def basis(self, object: ObjectRef) -> Basis: ...
    @property
    def contact(self) -> Optional[dict[str, Any]]:
        """Object-object contact of the last step ([contact] scenes; None without, or before
        the first step): step, object_pairs_tested, object_pairs_near, sample_pairs_active,
        penetration (deepest, metres), penetration_fraction (of the smaller rest diagonal of
        the two objects), islands (sizes, largest first), island_count, largest_island,
        regrouped (objects solved again), wall_ms (the world step, ms)."""
    def contact_summary(self) -> Optional[dict[str, Any]]:
        """The run's contact summary as `freeform run --json`'s "contact" (None without
        [contact]): steps (rows as `contact`, without island_count and largest_island),
        worst_penetration (metres), worst_penetration_fraction, steps_over_tolerance,
        step_ms_mean (ms), samples and thickness (metres) per object, stiffness (Pa/m^2,
        objects x objects, row-major)."""
    def summaries(self) -> list[dict[str, Any]]: ...

class Recording:
    """A world's run recorded for gradients (docs/gradients.md)."""

    def __init__(self, world: World, steps: int) -> None: ...
    def steps(self) -> int: ...
    def tape_bytes(self) -> int: ...
    def step(self, world: World) -> list[dict[str, Any]]:
        """One step of the world, recorded; the step reports."""
    def backward(
        self, world: World, dl_dz: dict[str, npt.NDArray[np.float64]]
    ) -> dict[str, dict[str, Any]]:
        """The reverse pass: dL/dz per object, (steps + 1, 12 (m + 1)); per object the
        gradients (youngs, poisson, density, their per-point arrays, gravity, friction and
        collider_stiffness per collider, collider_pose (steps, colliders, 2, 6), boundary_pose
        (steps, regions, 6), boundary_stiffness, placement, contact_stiffness and
        contact_friction (the object's row of the pair gradients over the world's objects;
        None without [contact]), z0, zdot0) and what the reverse pass took. Steps that solved
        objects together as an island are reversed jointly."""

def map_points(world: World, object: ObjectRef, points: ArrayLike) -> npt.NDArray[np.float64]:
    """Positions (N, 3) of rest points under the object's current state, metres."""

def positions_adjoint(
    world: World, object: ObjectRef, points: ArrayLike, dl_dx: ArrayLike
) -> npt.NDArray[np.float64]:
    """dL/dz (12 (m + 1)) from dL/dx (N, 3) at rest points."""

def beam_reference(
    test: Literal["bend", "twist"] = "bend",
    *,
    cache_dir: Optional[Union[str, PathLike[str]]] = None,
    progress: bool = False,
) -> dict[str, Any]:
    """The beam benchmark's FEM reference: rest (N, 3), frames (steps, N, 3), the material,
    dt, steps, size, gravity and the held length."""
