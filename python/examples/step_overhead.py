"""The cost of stepping from Python: time per `World.step()` seen from Python against the
library's own time for the same step (the report's `wall_ms`), on a scene file.

    python python/examples/step_overhead.py [SCENE.toml] [--repeat 3]

Default scene: examples/beam_bend.toml (K = 1000, m = 16, 200 steps).
"""

import argparse
import pathlib
import statistics
import time

import freeform as ff

REPO = pathlib.Path(__file__).resolve().parents[2]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default=str(REPO / "examples" / "beam_bend.toml"))
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    scene = ff.Scene.from_file(args.scene)
    rows = []
    for _ in range(args.repeat):
        world = ff.World(scene)  # the basis comes from the scene's cache after the first run
        outside, inside = 0.0, 0.0
        for _ in range(scene.steps):
            t = time.perf_counter()
            reports = world.step()
            outside += time.perf_counter() - t
            inside += sum(r["wall_ms"] for r in reports) / 1e3
        rows.append((outside, inside))
        print(f"{scene.steps} steps: {1e3 * outside / scene.steps:.4f} ms per step from Python, "
              f"{1e3 * inside / scene.steps:.4f} ms inside the library, "
              f"overhead {100 * (outside - inside) / inside:.2f} %")
    overhead = statistics.median((o - i) / i for o, i in rows)
    per_step = statistics.median((o - i) / scene.steps for o, i in rows)
    print(f"median overhead {100 * overhead:.2f} % ({1e6 * per_step:.1f} us per step)")


if __name__ == "__main__":
    main()
