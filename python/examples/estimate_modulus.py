"""Recover Young's modulus of the standard beam from the FEM reference's bend
(docs/gradients.md).

The observations are the FEM reference's node positions over the bend test's 200 steps
(quadratic tets, the beam benchmark's cached reference). The reduced model (m = 16,
K = 1,000, boundary-aware basis) starts from 10x the FEM's E; scipy's L-BFGS-B minimises the
mean squared distance of the reduced map at the FEM nodes from the FEM frames, over the
parameter ln(E / E_start), with the gradient from the reverse pass (freeform.Recording).

    python python/examples/estimate_modulus.py [--cache .freeform-cache/fem] [--scan]

The first run computes the FEM reference (3-8 minutes on 2 cores) and caches it. ``--scan``
also evaluates the loss on a grid of E around the FEM's, so the reduced model's own bias (the
minimum of the loss, not the optimiser) is visible. The last line printed is a JSON object
with ``relative_error`` (recovered E against the FEM's) and ``iterations``.
"""

import argparse
import json
import time

import numpy as np
from scipy.optimize import minimize

import freeform as ff


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--cache", default=".freeform-cache/fem", help="FEM reference cache (the CLI's default)"
    )
    p.add_argument("--frames", type=int, default=200, help="frames observed (from the start)")
    p.add_argument("--kernels", type=int, default=1000)
    p.add_argument("--modes", type=int, default=16)
    p.add_argument("--start", type=float, default=10.0, help="starting E as a multiple of the FEM's")
    p.add_argument("--tol", type=float, default=1e-8, help="each step's solver tolerance (x D)")
    p.add_argument("--max-iter", type=int, default=30, help="L-BFGS-B iterations at most")
    p.add_argument("--scan", action="store_true", help="also scan the loss over E")
    p.add_argument("--csv", default=None, help="write the loss per evaluation here")
    p.add_argument("--plot", default=None, help="draw the loss per iteration to this PNG (matplotlib)")
    p.add_argument(
        "--observe",
        choices=["fem", "reduced"],
        default="fem",
        help="observe the FEM reference, or the reduced model's own run at the FEM's E (which "
        "separates the optimiser's error from the reduced model's bias)",
    )
    return p.parse_args()


class Beam:
    """The reduced beam at any E, its loss against the FEM frames and the loss's gradient."""

    def __init__(self, ref, args):
        self.ref = ref
        self.frames = ref["frames"][: args.frames]
        self.rest = ref["rest"]
        sx, sy, sz = ref["size"]
        self.diag = float(np.linalg.norm(ref["size"]))
        self.tol = args.tol
        self.e_start = args.start * ref["youngs"]
        held = {"half_space": {"point": [ref["held_length"], 0.0, 0.0], "normal": [-1.0, 0.0, 0.0]}}
        self.held = held
        self.points, self.volumes = ff.sample(f"box:{sx},{sy},{sz}")
        # A homogeneous object's modes depend on neither E nor nu (H_w scales with them):
        # the basis is built once, at the starting guess, and held.
        self.basis = ff.Basis.from_points(
            self.points,
            self.e_start,
            ref["poisson"],
            ref["density"],
            volumes=self.volumes,
            kernels=args.kernels,
            modes=args.modes,
            regions=[f"halfspace:{ref['held_length']},0,0,-1,0,0"],
        )
        # The held end's penalty stiffness, fixed at the starting guess's default (it would
        # otherwise move with E and be a second parameter).
        h = ref["dt"]
        self.stiffness = 1e3 * max(ref["density"] / h**2, self.e_start / self.diag**2)
        # The map x = X + B z_r per coordinate row r: B = W (x) [X, 1] at the FEM nodes.
        w = self.basis.weights(self.rest)
        xh = np.hstack([self.rest, np.ones((len(self.rest), 1))])
        self.b = (w[:, :, None] * xh[:, None, :]).reshape(len(self.rest), -1)
        self.evaluations = 0

    def world(self, youngs):
        ref = self.ref
        scene = ff.Scene.from_dict(
            {
                "simulation": {"dt": ref["dt"], "steps": len(self.frames), "gravity": ref["gravity"]},
                "solver": {"tol": self.tol, "max_iter": 1000},
            }
        )
        scene.add_object(
            "beam",
            self.basis,
            self.points,
            youngs,
            ref["poisson"],
            ref["density"],
            self.volumes,
            boundaries=[{"region": self.held, "motion": "fixed", "stiffness": self.stiffness}],
        )
        return ff.World(scene)

    def observe(self, youngs):
        """The reduced model's own positions at the FEM nodes, frame by frame, at E."""
        w = self.world(youngs)
        frames = []
        for _ in range(len(self.frames)):
            w.step()
            z, _ = w.state("beam")
            frames.append(self.rest + self.b @ z.reshape(3, -1).T)
        return np.array(frames)

    def loss(self, youngs, gradient=True):
        """(L, dL/dE): L = mean over frames and nodes of |x_reduced - x_fem|^2 / D^2."""
        self.evaluations += 1
        w = self.world(youngs)
        steps = len(self.frames)
        rec = ff.Recording(w, steps) if gradient else None
        scale = 1.0 / (steps * len(self.rest) * self.diag**2)
        total = 0.0
        dl_dz = np.zeros((steps + 1, self.b.shape[1] * 3))
        for t in range(1, steps + 1):
            if rec is not None:
                rec.step(w)
            else:
                w.step()
            z, _ = w.state("beam")
            x = self.rest + self.b @ z.reshape(3, -1).T
            d = x - self.frames[t - 1]
            total += scale * float(np.sum(d * d))
            dl_dz[t] = (self.b.T @ (2.0 * scale * d)).T.reshape(-1)
        if rec is None:
            return total, None
        g = rec.backward(w, {"beam": dl_dz})["beam"]
        return total, g["youngs"]


def plot(path, iterates, e_fem, scan):
    """The loss against the L-BFGS-B iterations, and the scan of the loss over E beside it."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print(f"matplotlib is not installed: no plot written to {path}")
        return
    fig, axes = plt.subplots(1, 2 if scan else 1, figsize=(10 if scan else 5, 3.6), squeeze=False)
    ax = axes[0][0]
    ax.semilogy(range(len(iterates)), [loss for _, loss in iterates], "o-")
    ax.set_xlabel("L-BFGS-B iteration")
    ax.set_ylabel("loss (mean squared distance / D^2)")
    ax.set_title("E from 10x the FEM's")
    for i, (e, _) in enumerate(iterates):
        ax.annotate(f"{e / e_fem:.3f}", (i, iterates[i][1]), fontsize=7, xytext=(3, 3), textcoords="offset points")
    if scan:
        ax = axes[0][1]
        ax.semilogy([s["youngs"] / e_fem for s in scan], [s["loss"] for s in scan], "s-")
        ax.axvline(iterates[-1][0] / e_fem, color="gray", linestyle="--", label="recovered")
        ax.set_xlabel("E / E_fem")
        ax.set_title("loss over E (the reduced model's bias)")
        ax.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    print(f"wrote {path}")


def main():
    args = parse()
    clock = time.perf_counter()
    ref = ff.beam_reference("bend", cache_dir=args.cache, progress=True)
    e_fem = ref["youngs"]
    beam = Beam(ref, args)
    if args.observe == "reduced":
        beam.frames = beam.observe(e_fem)
    history = []
    iterates = []
    seen = {}
    loss0 = beam.loss(beam.e_start, gradient=False)[0]

    def objective(p):
        e = beam.e_start * np.exp(p[0])
        loss, de = beam.loss(e)
        history.append((e, loss))
        seen[float(p[0])] = (e, loss)
        print(f"  E = {e:.6e} Pa: loss {loss:.6e}, dL/dE {de:.3e}", flush=True)
        # Scaled by the starting loss, so that the tolerances are relative.
        return loss / loss0, np.array([de * e / loss0])

    # gtol: the steps are solved to tol x D, so the loss carries noise of about 1e-10 of its
    # size and its gradient about 1e-6 of the starting loss near the minimum; stop there.
    result = minimize(
        objective,
        x0=np.array([0.0]),
        jac=True,
        method="L-BFGS-B",
        bounds=[(-12.0, 12.0)],
        options={"maxiter": args.max_iter, "maxfun": 4 * args.max_iter, "ftol": 1e-14, "gtol": 1e-7},
        callback=lambda p: iterates.append(seen.get(float(p[0]), history[-1])),
    )
    e_best = beam.e_start * float(np.exp(result.x[0]))
    scan = []
    if args.scan:
        for f in [0.8, 0.9, 0.95, 0.98, 1.0, 1.02, 1.05, 1.1, 1.25]:
            loss, _ = beam.loss(f * e_fem, gradient=False)
            scan.append({"youngs": f * e_fem, "loss": loss})
            print(f"  scan: E = {f:.2f} x E_fem: loss {loss:.6e}", flush=True)
    if args.csv:
        with open(args.csv, "w") as f:
            f.write("evaluation,youngs,loss\n")
            for i, (e, loss) in enumerate(history):
                f.write(f"{i},{e!r},{loss!r}\n")
    if args.plot:
        plot(args.plot, [(beam.e_start, loss0)] + iterates, e_fem, scan)
    summary = {
        "youngs": e_best,
        "youngs_fem": e_fem,
        "youngs_start": beam.e_start,
        "relative_error": abs(e_best - e_fem) / e_fem,
        "iterations": int(result.nit),
        "evaluations": beam.evaluations,
        "loss": float(result.fun) * loss0,
        "observed": args.observe,
        "converged": bool(result.success),
        "message": str(result.message),
        "frames": len(beam.frames),
        "seconds": time.perf_counter() - clock,
        "scan": scan,
        "per_iteration": [{"youngs": e, "loss": loss} for e, loss in iterates],
    }
    print(json.dumps(summary))


if __name__ == "__main__":
    main()
