"""Recover both Young's moduli of a two-material bar from its own motion (docs/gradients.md).

A 1 x 0.2 x 0.2 m bar is held at x <= 0.1 m while its end x >= 0.9 m is turned about the
bar's axis (90 degrees per second) under gravity, for 60 steps of 10 ms: the twist loads both
halves, the sag mostly the left one. Its left half (x < 0.5 m) has E1, its right half E2
(truth: 5e6 and 2e7 Pa). The observations are 30 points of the bar, every frame, from the
model whose basis was built at the true moduli.

The fit starts from (3 E1, E2 / 3), builds the basis there and holds it (the recording's
gradient holds the basis fixed), minimises with scipy's L-BFGS-B over ln E1, ln E2, then
rebuilds the basis at the moduli found and fits again ("rounds"): the first round's error is
what holding the basis fixed at the wrong contrast costs, the later rounds remove it.

    python python/examples/estimate_two_materials.py [--rounds 3] [--plot two_materials.png]

The last line printed is a JSON object with the moduli found per round and their relative
errors (``relative_error``: the last round's larger one).
"""

import argparse
import json
import time

import numpy as np
from scipy.optimize import minimize

import freeform as ff

TRUTH = np.array([5e6, 2e7])
STEPS = 60
HELD = {"half_space": {"point": [0.1, 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]}}
TURNED = {"half_space": {"point": [0.9, 0.0, 0.0], "normal": [1.0, 0.0, 0.0]}}
TWIST = {"rotate": {"pivot": [0.0, 0.1, 0.1], "axis": [1.0, 0.0, 0.0], "degrees_per_second": 90.0}}


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--rounds", type=int, default=3, help="basis builds (1: held throughout)")
    p.add_argument("--max-iter", type=int, default=30)
    p.add_argument("--plot", default=None, help="draw the loss and the moduli per iteration to this PNG")
    return p.parse_args()


class Bar:
    def __init__(self):
        self.points, self.volumes = ff.sample("box:1,0.2,0.2", points=3000)
        self.right = self.points[:, 0] >= 0.5
        rng = np.random.default_rng(1)
        self.observed_at = self.points[rng.choice(len(self.points), 30, replace=False)]

    def youngs(self, e):
        return np.where(self.right, e[1], e[0])

    def basis(self, e):
        return ff.Basis.from_points(
            self.points, self.youngs(e), 0.4, 1000.0, volumes=self.volumes, kernels=60, modes=8,
            regions=["halfspace:0.1,0,0,-1,0,0", "halfspace:0.9,0,0,1,0,0"],
        )

    def world(self, basis, e):
        scene = ff.Scene.from_dict(
            {
                "simulation": {"dt": 0.01, "steps": STEPS, "gravity": [0.0, -9.81, 0.0]},
                "solver": {"tol": 1e-7, "max_iter": 1000, "cubature": 1000},
            }
        )
        # Fixed penalty stiffnesses: the default ones would move with E.
        scene.add_object(
            "bar", basis, self.points, self.youngs(e), 0.4, 1000.0, self.volumes,
            boundaries=[
                {"region": HELD, "motion": "fixed", "stiffness": 1e10},
                {"region": TURNED, "motion": TWIST, "stiffness": 1e10},
            ],
        )
        return ff.World(scene)

    def run(self, basis, e):
        w = self.world(basis, e)
        frames = []
        for _ in range(STEPS):
            w.step()
            frames.append(ff.map_points(w, "bar", self.observed_at))
        return np.array(frames)

    def loss(self, basis, e, observed):
        """(L, dL/dE1, dL/dE2): L = mean squared distance from the observations, m^2."""
        w = self.world(basis, e)
        rec = ff.Recording(w, STEPS)
        weights = basis.weights(self.observed_at)
        xh = np.hstack([self.observed_at, np.ones((len(self.observed_at), 1))])
        b = (weights[:, :, None] * xh[:, None, :]).reshape(len(self.observed_at), -1)
        scale = 1.0 / (STEPS * len(self.observed_at))
        dl_dz = np.zeros((STEPS + 1, 3 * b.shape[1]))
        total = 0.0
        for t in range(1, STEPS + 1):
            rec.step(w)
            z, _ = w.state("bar")
            d = self.observed_at + b @ z.reshape(3, -1).T - observed[t - 1]
            total += scale * float(np.sum(d * d))
            dl_dz[t] = (b.T @ (2.0 * scale * d)).T.reshape(-1)
        g = rec.backward(w, {"bar": dl_dz})["bar"]["youngs_per_point"]
        return total, np.array([g[~self.right].sum(), g[self.right].sum()])


def plot(path, rounds):
    """The loss and both moduli's errors against the L-BFGS-B iterations, round after round."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: no plot written to {path}")
        return
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.6))
    at = 0
    for r, history in enumerate(rounds):
        its = range(at, at + len(history))
        a.semilogy(its, [h["loss"] for h in history], "o-", ms=3, label=f"round {r + 1}")
        for k, mark in ((0, "o-"), (1, "s--")):
            b.semilogy(its, [abs(h["youngs"][k] - TRUTH[k]) / TRUTH[k] for h in history], mark, ms=3,
                       label=f"E{k + 1}, round {r + 1}")
        at += len(history)
    a.set_xlabel("L-BFGS-B iteration (all rounds)")
    a.set_ylabel("loss (mean squared distance, m^2)")
    a.set_title("two moduli from (3 E1, E2 / 3)")
    a.legend(fontsize=7)
    b.set_xlabel("L-BFGS-B iteration (all rounds)")
    b.set_ylabel("relative error of E")
    b.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    args = parse()
    clock = time.perf_counter()
    bar = Bar()
    observed = bar.run(bar.basis(TRUTH), TRUTH)
    e = np.array([3.0 * TRUTH[0], TRUTH[1] / 3.0])
    rounds = []
    histories = []
    for r in range(args.rounds):
        basis = bar.basis(e)  # held through this round's fit
        start = e.copy()
        loss0 = bar.loss(basis, start, observed)[0]

        seen = {}
        history = [{"youngs": start.tolist(), "loss": loss0}]

        def objective(p):
            ep = start * np.exp(p)
            loss, de = bar.loss(basis, ep, observed)
            seen[tuple(p)] = (ep, loss)
            return loss / loss0, de * ep / loss0

        def callback(p):
            ep, loss = seen[tuple(p)]
            history.append({"youngs": ep.tolist(), "loss": loss})

        res = minimize(objective, np.zeros(2), jac=True, method="L-BFGS-B", callback=callback,
                       bounds=[(-8.0, 8.0)] * 2,
                       options={"maxiter": args.max_iter, "maxfun": 4 * args.max_iter,
                                "ftol": 1e-15, "gtol": 1e-9})
        e = start * np.exp(res.x)
        histories.append(history)
        err = np.abs(e - TRUTH) / TRUTH
        rounds.append({"youngs": e.tolist(), "relative_error": err.tolist(),
                       "iterations": int(res.nit), "evaluations": int(res.nfev),
                       "loss": float(res.fun * loss0)})
        print(f"round {r + 1}: E1 = {e[0]:.6e}, E2 = {e[1]:.6e} Pa (errors {err[0]:.2e}, "
              f"{err[1]:.2e}), {res.nit} iterations", flush=True)
    if args.plot:
        plot(args.plot, histories)
    print(json.dumps({"truth": TRUTH.tolist(), "rounds": rounds,
                      "relative_error": max(rounds[-1]["relative_error"]),
                      "seconds": time.perf_counter() - clock}))


if __name__ == "__main__":
    main()
