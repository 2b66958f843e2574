"""What Kaolin's Simplicits mesh tutorial does, with freeform: points from a mesh, per-point
materials, a basis, a scene with gravity and a floor, 100 steps, positions written to a file.
Each stage's time is printed.

    python python/examples/kaolin_style.py [MESH.obj|.stl|.ply] [--out positions.npz]

Without a mesh argument a closed, bumpy "blob" mesh is made and written to a temporary OBJ
file, so the example runs anywhere.
"""

import argparse
import pathlib
import tempfile
import time

import numpy as np

import freeform as ff


def blob_mesh(path, subdivisions=3):
    """A closed, outward-oriented triangle mesh: an icosphere with smooth bumps, about 0.5 m
    across, written as OBJ."""
    t = (1 + 5 ** 0.5) / 2
    v = [[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t],
         [0, -1, -t], [0, 1, -t], [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]]
    f = [[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4],
         [11, 10, 2], [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8],
         [3, 8, 9], [4, 9, 5], [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]]
    v = [np.array(p, float) / np.linalg.norm(p) for p in v]
    for _ in range(subdivisions):
        mid = {}

        def middle(a, b):
            key = (min(a, b), max(a, b))
            if key not in mid:
                p = v[a] + v[b]
                v.append(p / np.linalg.norm(p))
                mid[key] = len(v) - 1
            return mid[key]

        f = [tri for a, b, c in f
             for ab, bc, ca in [(middle(a, b), middle(b, c), middle(c, a))]
             for tri in ([a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca])]
    x = np.array(v)
    bumps = 1 + 0.15 * np.sin(3 * x[:, 0]) * np.cos(2 * x[:, 1]) + 0.3 * np.maximum(x[:, 1], 0) ** 2
    x = 0.25 * x * bumps[:, None] * [1.4, 1.0, 0.8]
    with open(path, "w") as out:
        out.writelines(f"v {a:.9f} {b:.9f} {c:.9f}\n" for a, b, c in x)
        out.writelines(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("mesh", nargs="?", help="a watertight OBJ, STL or PLY mesh")
    parser.add_argument("--out", default="positions.npz", help="output file (.npz)")
    parser.add_argument("--steps", type=int, default=100)
    args = parser.parse_args()

    clock = time.perf_counter()

    def stage(name):
        nonlocal clock
        now = time.perf_counter()
        print(f"{name:<34} {now - clock:7.3f} s")
        clock = now

    mesh = args.mesh
    if mesh is None:
        mesh = str(pathlib.Path(tempfile.mkdtemp()) / "blob.obj")
        blob_mesh(mesh)
    stage("mesh")

    # 1. Points from the mesh (Kaolin: uniform points kept where the mesh's sign is inside).
    points, volumes = ff.sample(mesh, points=20_000)
    stage(f"sample {len(points)} points")

    # 2. Per-point materials (Kaolin: yms, prs, rhos arrays): a soft body, ten times stiffer
    #    in its upper half.
    top = points[:, 1] > np.median(points[:, 1])
    youngs = np.where(top, 1e6, 1e5)
    poisson = np.full(len(points), 0.45)
    density = np.full(len(points), 500.0)

    # 3. The basis (Kaolin: a trained network of handles; here eigenmodes of the elastic
    #    Hessian on RKPM kernels, no training).
    basis = ff.Basis.from_points(points, youngs, poisson, density, volumes,
                                 kernels=500, modes=12)
    stage(f"basis K={basis.kernels} m={basis.modes}")

    # 4. A scene with gravity and a floor (Kaolin: set_scene_gravity, set_scene_floor).
    floor = points[:, 1].min() - 0.3
    scene = ff.Scene.from_dict({
        "simulation": {"dt": 0.01, "steps": args.steps, "gravity": [0.0, -9.81, 0.0]},
        "solver": {"cubature": 1000},
        "collider": [{"shape": {"plane": {"point": [0.0, floor, 0.0],
                                          "normal": [0.0, 1.0, 0.0]}}}],
    })
    scene.add_object("blob", basis, points, youngs, poisson, density, volumes)
    world = ff.World(scene)
    stage("scene setup")

    # 5. Simulate (Kaolin: run_sim_step and get_object_deformed_pts).
    frames = np.empty((args.steps + 1, len(points), 3))
    world.positions("blob", out=frames[0])
    not_converged = 0
    for i in range(1, args.steps + 1):
        report = world.step()[0]
        not_converged += not report["converged"]
        world.positions("blob", out=frames[i])
    stage(f"{args.steps} steps")

    np.savez(args.out, positions=frames, rest=points, time=np.arange(args.steps + 1) * 0.01)
    stage(f"write {args.out}")
    lowest = frames[:, :, 1].min()
    # The floor is a penalty (as Kaolin's): points sink below it until its force carries
    # the weight, by a depth that falls as the collider's stiffness rises.
    sink = max(floor - lowest, 0.0)
    print(f"lowest point {lowest:.4f} m (floor at {floor:.4f} m: the penalty floor lets "
          f"points sink {1e3 * sink:.1f} mm, until its force carries the weight; a stiffer "
          f"collider, 'stiffness' in Pa/m^2, sinks less); "
          f"{not_converged} steps not converged; warnings: {len(world.warnings)}")


if __name__ == "__main__":
    main()
