"""A recorded freeform run as a ``torch.autograd.Function`` (docs/gradients.md): fit the
throw of a block and the friction between it and another block it lands on, with a torch
optimiser.

A block (0.2 x 0.1 x 0.2 m, E = 1e6 Pa) is thrown onto another that slides along a floor; the
two are solved together as an island while they touch, and the friction between them (a
``[[contact.pair]]`` coefficient) drags the thrown block along. Four corners of the thrown
block are observed at every step of 10 ms, 8 frames, from the model's own run at the truth
(v = (0.3, -0.5, 0.2) m/s, mu = 0.6).

``Simulate.apply(velocity, mu)`` returns the corners' positions per frame, (frames, 4, 3), as
a differentiable torch tensor: its forward records a run, its backward takes the reverse pass
(``Recording.backward``: the placement's ``velocity`` and the pair's ``contact_friction``),
and it passes ``torch.autograd.gradcheck`` against torch's own central differences. torch is
not a dependency of freeform: the example needs it installed (``pip install torch``).

    python python/examples/torch_autograd.py [--iterations 40] [--gradcheck]

The last line printed is a JSON object with the fitted values and ``relative_error`` (the
2-norm error of (v, mu) against the truth's, relative).
"""

import argparse
import json
import sys
import time

import numpy as np

import freeform as ff

try:
    import torch
except ImportError:
    torch = None

STEPS = 8
TRUE_V = [0.3, -0.5, 0.2]
TRUE_MU = 0.6
SCENE = """
[simulation]
dt = 0.01
steps = {steps}
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 200
hessian = "newton"
tol = 1e-12
max_iter = 200

[contact]
friction = 0.3
friction_velocity = 0.01

[[contact.pair]]
between = ["block", "top"]
friction = {mu!r}

[[object]]
name = "block"
shape = "box:0.2,0.1,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
placement = {{ translation = [0.0, -0.002, 0.0], velocity = [1.0, 0.0, 0.2] }}

[[object]]
name = "top"
shape = "box:0.2,0.1,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
placement = {{ translation = [0.0, 0.105, 0.0] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
stiffness = 1e8
"""
START = [0.0, 0.105, 0.0]
CORNERS = np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.2], [0.2, 0.0, 0.0], [0.0, 0.1, 0.2]])


def record(velocity, mu):
    """A recorded run from the throw `velocity` (m/s) with pair friction `mu`: the world, the
    recording and the corners per frame, (STEPS + 1, 4, 3) metres."""
    world = ff.World(ff.Scene.from_toml(SCENE.format(steps=STEPS, mu=float(mu))))
    world.set_placement("top", {"translation": START, "velocity": [float(v) for v in velocity]})
    rec = ff.Recording(world, STEPS)
    frames = [ff.map_points(world, "top", CORNERS)]
    for _ in range(STEPS):
        rec.step(world)
        frames.append(ff.map_points(world, "top", CORNERS))
    return world, rec, np.array(frames)


if torch is not None:

    class Simulate(torch.autograd.Function):
        """(velocity (3,), mu ()) -> the thrown block's corners per frame, (STEPS + 1, 4, 3)."""

        @staticmethod
        def forward(ctx, velocity, mu):
            v, m = velocity.detach().numpy(), float(mu)
            world, rec, frames = record(v, m)
            ctx.run = (v, m, world, rec)
            return torch.from_numpy(frames)

        @staticmethod
        def backward(ctx, grad_frames):
            v, m, world, rec = ctx.run
            if rec is None:
                # The reverse pass consumes a recording: record again for a second backward
                # (torch.autograd.gradcheck asks twice to check reentrancy).
                world, rec, _ = record(v, m)
            ctx.run = (v, m, world, None)
            g = grad_frames.detach().numpy()
            dl_dz = np.stack([ff.positions_adjoint(world, "top", CORNERS, g[t])
                              for t in range(STEPS + 1)])
            grads = rec.backward(world, {"top": dl_dz})["top"]
            dv = torch.from_numpy(np.asarray(grads["placement"]["velocity"]))
            # The pair (top, block): the top block's row, the block's entry (object 0).
            dmu = torch.tensor(float(grads["contact_friction"][0]), dtype=torch.float64)
            return dv, dmu


def parse():
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--iterations", type=int, default=40, help="L-BFGS iterations at most")
    p.add_argument("--gradcheck", action="store_true",
                   help="check the Function against torch's central differences first")
    return p.parse_args()


def main():
    if torch is None:
        print("torch is not installed: pip install torch (freeform does not depend on it)")
        sys.exit(2)
    args = parse()
    clock = time.perf_counter()
    if args.gradcheck:
        v = torch.tensor([0.25, -0.45, 0.15], dtype=torch.float64, requires_grad=True)
        mu = torch.tensor(0.5, dtype=torch.float64, requires_grad=True)
        # Steps solved to 1e-12 D; torch's step 1e-6 switches no contact here (a kink lies
        # 1e-4 to 1e-3 away in the Rust test's scene), so its central differences are good to
        # about 1e-6.
        ok = torch.autograd.gradcheck(Simulate.apply, (v, mu), eps=1e-6, atol=1e-7, rtol=1e-5)
        print(f"gradcheck: {ok}")
    observed = torch.from_numpy(record(TRUE_V, TRUE_MU)[2])
    velocity = torch.zeros(3, dtype=torch.float64, requires_grad=True)
    mu = torch.tensor(0.3, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([velocity, mu], lr=1.0, max_iter=args.iterations,
                            tolerance_grad=1e-14, tolerance_change=1e-16,
                            line_search_fn="strong_wolfe")
    history = []

    def closure():
        opt.zero_grad()
        loss = ((Simulate.apply(velocity, mu) - observed) ** 2).mean()
        loss.backward()
        history.append(loss.item())
        return loss

    opt.step(closure)
    truth = np.array(TRUE_V + [TRUE_MU])
    found = np.concatenate([velocity.detach().numpy(), [mu.item()]])
    err = float(np.linalg.norm(found - truth) / np.linalg.norm(truth))
    print(f"v = {found[:3]}, mu = {found[3]:.6f} (truth {TRUE_V}, {TRUE_MU}; relative error "
          f"{err:.2e}) after {len(history)} evaluations, loss {history[0]:.3e} -> {history[-1]:.3e}")
    print(json.dumps({"velocity": found[:3].tolist(), "mu": found[3], "truth": truth.tolist(),
                      "relative_error": err, "evaluations": len(history),
                      "first_loss": history[0], "last_loss": history[-1],
                      "seconds": time.perf_counter() - clock}))


if __name__ == "__main__":
    main()
