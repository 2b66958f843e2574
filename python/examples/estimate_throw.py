"""Recover the initial velocity of a thrown ball from 10 observed frames (docs/gradients.md).

A rubber ball (radius 0.1 m, E = 1e6 Pa, 1000 kg/m^3) is thrown from 1 m up at
v = (3, 4, -1) m/s, spinning at w = (0, 6, 3) rad/s, under gravity. Six points of its surface
(the ends of its three axes) are observed every second step of 10 ms, 10 frames, from the
model's own run at the truth.

The fit starts at rest (v = w = 0) and minimises the mean squared distance to the
observations with scipy's L-BFGS-B over the six numbers; each evaluation records a run and
takes one reverse pass (``Recording.backward``'s ``placement``: dL/dv and dL/dw of the
object's placement, set with ``World.set_placement``).

    python python/examples/estimate_throw.py [--noise 0.001] [--plot throw.png]

The last line printed is a JSON object with the velocities found and ``relative_error``
(the 2-norm error of (v, w) against the truth's, relative).
"""

import argparse
import json
import time

import numpy as np
from scipy.optimize import minimize

import freeform as ff

TRUE_V = np.array([3.0, 4.0, -1.0])
TRUE_W = np.array([0.0, 6.0, 3.0])
FRAMES = 10
EVERY = 2
STEPS = FRAMES * EVERY
START = [0.0, 1.0, 0.0]
SCENE = f"""
[simulation]
dt = 0.01
steps = {STEPS}
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
tol = 1e-10
max_iter = 200

[cache]
enabled = false

[[object]]
name = "ball"
shape = "sphere:0.1"
material = {{ youngs = 1e6, poisson = 0.45, density = 1000.0 }}
basis = {{ kernels = 40, modes = 6, points = 2000 }}
"""
MARKERS = 0.1 * np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1]], float)


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--max-iter", type=int, default=50)
    p.add_argument("--noise", type=float, default=0.0,
                   help="standard deviation of Gaussian noise added to the observations, metres")
    p.add_argument("--plot", default=None, help="draw the loss and the velocities per iteration to this PNG")
    return p.parse_args()


class Throw:
    def __init__(self):
        self.scene = ff.Scene.from_toml(SCENE)

    def world(self, v, w):
        world = ff.World(self.scene)
        world.set_placement("ball", {"translation": START, "velocity": list(map(float, v)),
                                     "angular_velocity": list(map(float, w))})
        return world

    def observe(self, v, w):
        """The markers at the observed frames, (FRAMES, 6, 3) metres."""
        world = self.world(v, w)
        frames = []
        for t in range(1, STEPS + 1):
            world.step()
            if t % EVERY == 0:
                frames.append(ff.map_points(world, "ball", MARKERS))
        return np.array(frames)

    def loss(self, v, w, observed):
        """(L, dL/dv, dL/dw): L = the mean squared marker distance over the frames, m^2."""
        world = self.world(v, w)
        rec = ff.Recording(world, STEPS)
        scale = 1.0 / (FRAMES * len(MARKERS))
        dl_dz = np.zeros((STEPS + 1, len(world.state("ball")[0])))
        total = 0.0
        for t in range(1, STEPS + 1):
            rec.step(world)
            if t % EVERY == 0:
                d = ff.map_points(world, "ball", MARKERS) - observed[t // EVERY - 1]
                total += scale * float(np.sum(d * d))
                dl_dz[t] = ff.positions_adjoint(world, "ball", MARKERS, 2.0 * scale * d)
        g = rec.backward(world, {"ball": dl_dz})["ball"]["placement"]
        return total, g["velocity"], g["angular_velocity"]


def plot(path, iterates):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: no plot written to {path}")
        return
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.semilogy(range(len(iterates)), [it["loss"] for it in iterates], "o-")
    a.set_xlabel("L-BFGS-B iteration")
    a.set_ylabel("loss (mean squared distance, m^2)")
    a.set_title("a thrown ball's velocity, from rest")
    for k, name in enumerate(["v_x", "v_y", "v_z", "w_x", "w_y", "w_z"]):
        truth = np.concatenate([TRUE_V, TRUE_W])[k]
        line, = b.plot(range(len(iterates)), [it["x"][k] for it in iterates], "o-", ms=3, label=name)
        b.axhline(truth, color=line.get_color(), linestyle=":", linewidth=0.8)
    b.set_xlabel("L-BFGS-B iteration")
    b.set_ylabel("m/s, rad/s (dotted: truth)")
    b.legend(ncol=2, fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    args = parse()
    clock = time.perf_counter()
    throw = Throw()
    observed = throw.observe(TRUE_V, TRUE_W)
    if args.noise:
        observed += np.random.default_rng(1).normal(0.0, args.noise, observed.shape)
    seen = {}

    def objective(x):
        total, dv, dw = throw.loss(x[:3], x[3:], observed)
        seen[tuple(x)] = total
        return total, np.concatenate([dv, dw])

    x0 = np.zeros(6)
    iterates = [{"x": x0, "loss": objective(x0)[0]}]

    def callback(x):
        iterates.append({"x": x.copy(), "loss": seen[tuple(x)]})
        print(f"iteration {len(iterates) - 1}: v = {np.round(x[:3], 5)}, w = {np.round(x[3:], 5)}, "
              f"loss {iterates[-1]['loss']:.3e}", flush=True)

    res = minimize(objective, x0, jac=True, method="L-BFGS-B", callback=callback,
                   options={"maxiter": args.max_iter, "maxfun": 4 * args.max_iter,
                            "ftol": 1e-16, "gtol": 1e-14})
    truth = np.concatenate([TRUE_V, TRUE_W])
    err = float(np.linalg.norm(res.x - truth) / np.linalg.norm(truth))
    print(f"v = {res.x[:3]}, w = {res.x[3:]} (relative error {err:.2e}) in {res.nit} iterations")
    if args.plot:
        plot(args.plot, iterates)
    print(json.dumps({"velocity": res.x[:3].tolist(), "angular_velocity": res.x[3:].tolist(),
                      "truth": truth.tolist(), "noise": args.noise, "relative_error": err,
                      "iterations": int(res.nit), "evaluations": int(res.nfev),
                      "seconds": time.perf_counter() - clock}))


if __name__ == "__main__":
    main()
