"""Recover a block's friction coefficient from its slide on a plane (docs/gradients.md).

A 0.2 x 0.1 x 0.2 m block (E = 1e6 Pa, 500 kg/m^3) is pushed along a plane at 1.5 m/s (and
0.4 m/s sideways) and slides for 40 steps of 10 ms, slowed by Coulomb friction (the truth:
mu = 0.3, so it decelerates by about mu g = 2.9 m/s^2 and is still sliding at the end). The
observations are its 8 corners, every frame, from the model's own run at the truth.

The fit starts from mu = 0.1 (3x off) and minimises the mean squared distance to the
observations with scipy's L-BFGS-B over ln mu; each evaluation records a run and takes one
reverse pass (``Recording.backward``'s ``friction``: dL/dmu per collider).

    python python/examples/estimate_friction.py [--start 0.1] [--noise 0.001] [--plot friction.png]

``--noise`` adds Gaussian noise (metres, seeded) to the observations, as a camera or a
motion-capture trace would.

The last line printed is a JSON object with ``mu``, ``relative_error`` and ``iterations``.
"""

import argparse
import json
import time

import numpy as np
from scipy.optimize import minimize

import freeform as ff

TRUTH = 0.3
STEPS = 40
SCENE = """
[simulation]
dt = 0.01
steps = {steps}
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
tol = 1e-10
max_iter = 200

[cache]
enabled = false

[contact]
friction = {mu!r}
friction_velocity = 0.01

[[object]]
name = "block"
shape = "box:0.2,0.1,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 40, modes = 4, points = 2000 }}
placement = {{ translation = [0.0, -0.001, 0.0], velocity = [1.5, 0.0, 0.4] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
stiffness = 1e8
"""
CORNERS = np.array([[x, y, z] for x in (0.0, 0.2) for y in (0.0, 0.1) for z in (0.0, 0.2)])


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--start", type=float, default=0.1, help="the starting guess of mu")
    p.add_argument("--max-iter", type=int, default=30)
    p.add_argument("--noise", type=float, default=0.0,
                   help="standard deviation of Gaussian noise added to the observations, metres")
    p.add_argument("--plot", default=None, help="draw the loss per iteration and over mu to this PNG")
    return p.parse_args()


def world(mu):
    return ff.World(ff.Scene.from_toml(SCENE.format(steps=STEPS, mu=float(mu))))


def observe(mu):
    """The corners after each step, (STEPS, 8, 3) metres."""
    w = world(mu)
    frames = []
    for _ in range(STEPS):
        w.step()
        frames.append(ff.map_points(w, "block", CORNERS))
    return np.array(frames)


def loss(mu, observed):
    """(L, dL/dmu): L = the mean over frames and corners of the squared distance, m^2."""
    w = world(mu)
    rec = ff.Recording(w, STEPS)
    scale = 1.0 / (STEPS * len(CORNERS))
    dl_dz = np.zeros((STEPS + 1, len(w.state("block")[0])))
    total = 0.0
    for t in range(1, STEPS + 1):
        rec.step(w)
        d = ff.map_points(w, "block", CORNERS) - observed[t - 1]
        total += scale * float(np.sum(d * d))
        dl_dz[t] = ff.positions_adjoint(w, "block", CORNERS, 2.0 * scale * d)
    g = rec.backward(w, {"block": dl_dz})["block"]
    return total, float(g["friction"][0])


def plot(path, iterates, scan):
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: no plot written to {path}")
        return
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    a.semilogy(range(len(iterates)), [v for _, v in iterates], "o-")
    for i, (mu, v) in enumerate(iterates):
        a.annotate(f"{mu:.4f}", (i, v), fontsize=7, xytext=(3, 3), textcoords="offset points")
    a.set_xlabel("L-BFGS-B iteration")
    a.set_ylabel("loss (mean squared distance, m^2)")
    a.set_title(f"mu from {iterates[0][0]:g} (truth {TRUTH})")
    b.plot([m for m, _ in scan], [v for _, v in scan], "s-")
    b.axvline(TRUTH, color="gray", linestyle="--", label="truth")
    b.set_xlabel("mu")
    b.set_title("loss over mu")
    b.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    args = parse()
    clock = time.perf_counter()
    observed = observe(TRUTH)
    observed += np.random.default_rng(1).normal(0.0, args.noise, observed.shape) if args.noise else 0.0
    loss0 = loss(args.start, observed)[0]
    iterates = [(args.start, loss0)]
    seen = {}

    def objective(p):
        mu = args.start * np.exp(p[0])
        v, g = loss(mu, observed)
        seen[float(p[0])] = (mu, v)
        return v / loss0, np.array([g * mu / loss0])

    def callback(p):
        iterates.append(seen[float(p[0])])
        print(f"iteration {len(iterates) - 1}: mu = {iterates[-1][0]:.6f}, loss {iterates[-1][1]:.3e}", flush=True)

    res = minimize(objective, np.zeros(1), jac=True, method="L-BFGS-B", bounds=[(-6.0, 6.0)],
                   callback=callback,
                   options={"maxiter": args.max_iter, "maxfun": 4 * args.max_iter,
                            "ftol": 1e-15, "gtol": 1e-10})
    mu = float(args.start * np.exp(res.x[0]))
    err = abs(mu - TRUTH) / TRUTH
    print(f"mu = {mu:.6f} (truth {TRUTH}, relative error {err:.2e}) in {res.nit} iterations, "
          f"{res.nfev} evaluations")
    if args.plot:
        scan = [(m, loss(m, observed)[0]) for m in np.linspace(0.1, 0.5, 17)]
        plot(args.plot, iterates, scan)
    print(json.dumps({"truth": TRUTH, "start": args.start, "noise": args.noise, "mu": mu, "relative_error": err,
                      "iterations": int(res.nit), "evaluations": int(res.nfev),
                      "seconds": time.perf_counter() - clock}))


if __name__ == "__main__":
    main()
