"""freeform: mesh-free, reduced-order simulation of elastic objects from RKPM skinning
eigenmodes, from Python.

- ``sample("mesh.obj", points=20000)``: points inside a shape and their volumes (a USD prim
  too: ``sample("scene.usda:/World/Toy")``).
- ``read_usd_kaolin("run.usda", "/World/ball/points")``: Kaolin's physics schemas of a USD
  prim (points, materials, skinning weights) as arrays.
- ``Basis.from_shape("box:2,1,1", kernels=1000, modes=16)`` or
  ``Basis.from_points(points, youngs, poisson, density, volumes=None)``: the eigenmodes;
  ``basis.weights(points)`` evaluates them anywhere in the object.
- ``eigsh(h, m, nev)``: the native eigensolver on your own H and M (``scipy.sparse``
  matrices, or objects with ``matmat``/``matvec`` and ``shape``).
- ``Scene.from_file("scene.toml")`` / ``Scene.from_dict({...})`` and ``World(scene)``: the
  live simulation (``world.step()``, ``world.positions(i)``, targets and poses between
  steps).
- ``Recording(world, steps)``, ``rec.step(world)``, ``rec.backward(world, dl_dz)``:
  gradients of a loss over a run with respect to materials, gravity and the initial state;
  ``map_points`` and ``positions_adjoint`` carry a loss on positions to z
  (docs/gradients.md).
- ``beam_reference("bend", cache_dir=...)``: the beam benchmark's FEM reference as arrays.

Units are SI (metres, Pa, kg/m^3, s). Arrays in: any real dtype and layout (converted once
to float64); arrays out: new float64 NumPy arrays. Guide: docs/python.md.
"""

from ._errors import (
    CoverageError,
    FreeformError,
    FreeformIOError,
    InvalidInputError,
    NotConvergedError,
    StrictModeError,
)
from ._native import (
    Basis,
    Recording,
    Scene,
    World,
    __version__,
    beam_reference,
    eigsh,
    map_points,
    positions_adjoint,
    read_usd_kaolin,
    sample,
)

__all__ = [
    "Basis",
    "Scene",
    "World",
    "Recording",
    "map_points",
    "beam_reference",
    "positions_adjoint",
    "read_usd_kaolin",
    "sample",
    "eigsh",
    "FreeformError",
    "InvalidInputError",
    "CoverageError",
    "NotConvergedError",
    "StrictModeError",
    "FreeformIOError",
    "__version__",
]
