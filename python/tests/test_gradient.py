"""Gradients through a recorded run from Python (docs/gradients.md) against central
differences of the same model re-simulated, and the refusals."""

import numpy as np
import pytest

import freeform as ff

STEPS = 5


def world(basis, points, volumes, youngs, gravity=(0.0, -9.81, 0.0)):
    """The bar held at x <= 0.1 m with a fixed penalty stiffness (the default one scales with
    E), each step solved by Newton far below the default tolerance."""
    scene = ff.Scene.from_dict(
        {
            "simulation": {"dt": 0.02, "steps": STEPS, "gravity": list(gravity)},
            "solver": {"hessian": "newton", "tol": 1e-12, "max_iter": 200, "cubature": 200},
        }
    )
    scene.add_object(
        "bar",
        basis,
        points,
        youngs,
        0.4,
        1000.0,
        volumes,
        boundaries=[
            {
                "region": {"half_space": {"point": [0.1, 0, 0], "normal": [-1, 0, 0]}},
                "motion": "fixed",
                "stiffness": 1e8,
            }
        ],
    )
    return ff.World(scene)


def tip_loss_gradient(w, tip, steps):
    """L = sum over frames of the tip points' y (a linear loss on positions): dL/dz per frame."""
    dl_dx = np.zeros_like(tip)
    dl_dx[:, 1] = 1.0
    row = ff.positions_adjoint(w, "bar", tip, dl_dx)
    return np.tile(row, (steps + 1, 1))


def loss(w, tip, steps):
    total = ff.map_points(w, "bar", tip)[:, 1].sum()
    for _ in range(steps):
        w.step()
        total += ff.map_points(w, "bar", tip)[:, 1].sum()
    return total


@pytest.fixture(scope="module")
def setup():
    points, volumes = ff.sample("box:1,0.2,0.2", points=1200)
    basis = ff.Basis.from_points(points, 1e5, 0.4, 1000.0, volumes=volumes, kernels=40, modes=5)
    tip = np.array([[1.0, 0.0, 0.0], [1.0, 0.2, 0.2], [0.9, 0.1, 0.1]])
    return basis, points, volumes, tip


def test_youngs_and_gravity_match_central_differences(setup):
    basis, points, volumes, tip = setup
    w = world(basis, points, volumes, 1e5)
    rec = ff.Recording(w, STEPS)
    dl_dz = tip_loss_gradient(w, tip, STEPS)
    for _ in range(STEPS):
        rec.step(w)
    g = rec.backward(w, {"bar": dl_dz})["bar"]
    h = 1e-4
    fd_e = (
        loss(world(basis, points, volumes, 1e5 * (1 + h)), tip, STEPS)
        - loss(world(basis, points, volumes, 1e5 * (1 - h)), tip, STEPS)
    ) / (2 * h * 1e5)
    # Steps solved to 1e-12 D and relative steps of 1e-4: differences good to ~1e-7.
    assert g["youngs"] == pytest.approx(fd_e, rel=1e-5)
    assert g["youngs_per_point"].sum() == pytest.approx(g["youngs"], rel=1e-12)
    gy = 1e-3
    fd_g = (
        loss(world(basis, points, volumes, 1e5, (0, -9.81 + gy, 0)), tip, STEPS)
        - loss(world(basis, points, volumes, 1e5, (0, -9.81 - gy, 0)), tip, STEPS)
    ) / (2 * gy)
    assert g["gravity"][1] == pytest.approx(fd_g, rel=1e-5)
    assert g["z0"].shape == g["zdot0"].shape == (72,)
    assert g["backward_s"] >= 0 and g["tape_bytes"] > 0


def test_bad_recordings_are_refused(setup):
    basis, points, volumes, tip = setup
    w = world(basis, points, volumes, 1e5)
    rec = ff.Recording(w, 2)
    rec.step(w)
    good = tip_loss_gradient(w, tip, 1)
    with pytest.raises(ff.InvalidInputError, match=r"has shape \(1, 72\); the recording needs \(2, 72\)"):
        rec.backward(w, {"bar": good[:1]})
    bad = good.copy()
    bad[1, 3] = np.nan
    with pytest.raises(ff.InvalidInputError, match="frame 1 is not finite"):
        rec.backward(w, {"bar": bad})
    with pytest.raises(ff.InvalidInputError, match="no object named|object"):
        rec.backward(w, {"nothing": good})
    # A change between forward and backward.
    w.set_gravity([0.0, -1.0, 0.0])
    with pytest.raises(ff.InvalidInputError, match="changed since"):
        rec.step(w)
    # backward consumes the tape: a second call is refused.
    w2 = world(basis, points, volumes, 1e5)
    rec2 = ff.Recording(w2, 1)
    rec2.step(w2)
    rec2.backward(w2, {"bar": good})
    with pytest.raises(ff.InvalidInputError, match="already taken"):
        rec2.backward(w2, {"bar": good})
