"""Gradients through a recorded run from Python (docs/gradients.md) against central
differences of the same model re-simulated, and the refusals."""

import numpy as np
import pytest

import freeform as ff

STEPS = 5


def world(basis, points, volumes, youngs, gravity=(0.0, -9.81, 0.0), stiffness=1e8):
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
                "stiffness": stiffness,
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
    # The held end's stiffness (1e8 Pa/m^2), moved by 1e-4 relative.
    k = 1e8
    fd_k = (
        loss(world(basis, points, volumes, 1e5, stiffness=k * (1 + h)), tip, STEPS)
        - loss(world(basis, points, volumes, 1e5, stiffness=k * (1 - h)), tip, STEPS)
    ) / (2 * h * k)
    assert abs(fd_k * k) > 1e-4  # a real signal: dL/dln(kappa) is -2.3e-3 here
    assert g["boundary_stiffness"][0] == pytest.approx(fd_k, rel=1e-5)
    assert g["boundary_pose"].shape == (STEPS, 1, 6)
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


# A block pushed along a plane at 1 m/s, held back by friction (mu per [contact]), each step
# solved by Newton far below the default tolerance.
SLIDE = """
[simulation]
dt = 0.01
steps = {steps}
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 200
hessian = "newton"
tol = 1e-12
max_iter = 200

[cache]
enabled = false

[contact]
friction = {mu}
friction_velocity = 0.01

[[object]]
name = "block"
shape = "box:0.2,0.1,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
placement = {{ translation = [0.0, -0.002, 0.0], velocity = [1.0, 0.0, 0.2] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
stiffness = 1e8
"""

CORNERS = np.array([[0.0, 0.0, 0.0], [0.2, 0.1, 0.2], [0.1, 0.05, 0.0]])


def slide_loss(w, steps):
    """L = sum over frames of the corners' x + z."""
    total = 0.0
    for t in range(steps + 1):
        if t > 0:
            w.step()
        x = ff.map_points(w, "block", CORNERS)
        total += x[:, 0].sum() + x[:, 2].sum()
    return total


def slide_gradients(w, steps):
    """Record `steps` steps of a slide world and take the reverse pass of slide_loss."""
    dl_dx = np.zeros_like(CORNERS)
    dl_dx[:, [0, 2]] = 1.0
    row = ff.positions_adjoint(w, "block", CORNERS, dl_dx)
    rec = ff.Recording(w, steps)
    for _ in range(steps):
        rec.step(w)
    return rec.backward(w, {"block": np.tile(row, (steps + 1, 1))})["block"], row


def test_friction_gradient_matches_central_differences():
    steps = 6
    make = lambda mu: ff.World(ff.Scene.from_toml(SLIDE.format(steps=steps, mu=mu)))
    w = make(0.4)
    g, row = slide_gradients(w, steps)
    h = 1e-4
    fd = (slide_loss(make(0.4 + h), steps) - slide_loss(make(0.4 - h), steps)) / (2 * h)
    # Steps solved to 1e-12 D; the contact set does not switch within +-h (the block stays
    # on the plane), so the bound without contact holds.
    assert fd < 0  # friction slows the slide
    assert g["friction"][0] == pytest.approx(fd, rel=1e-5)
    assert g["collider_stiffness"].shape == (1,)


# A second block dropped onto the sliding one: the two are solved together as an island, and
# their pair's friction (a [[contact.pair]] table) drags the top one along.
TOP = """
[[object]]
name = "top"
shape = "box:0.2,0.1,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
placement = {{ translation = [0.0, 0.11, 0.0], velocity = [0.0, -0.5, 0.0] }}

[[contact.pair]]
between = ["block", "top"]
friction = {mu}
"""


def test_objects_in_contact_give_their_pair_gradients():
    steps = 4
    make = lambda mu: ff.World(
        ff.Scene.from_toml(SLIDE.format(steps=steps, mu=0.3) + TOP.format(mu=mu))
    )

    def top_loss(w):
        total = 0.0
        for t in range(steps + 1):
            if t > 0:
                w.step()
            total += ff.map_points(w, "top", CORNERS)[:, 0].sum()
        return total

    w = make(0.4)
    dl_dx = np.zeros_like(CORNERS)
    dl_dx[:, 0] = 1.0
    row = ff.positions_adjoint(w, "top", CORNERS, dl_dx)
    rec = ff.Recording(w, steps)
    islands = []
    for _ in range(steps):
        rec.step(w)
        islands.append(w.contact["largest_island"])
    assert max(islands) == 2
    g = rec.backward(w, {"top": np.tile(row, (steps + 1, 1))})
    # The pair's entry is in both objects' rows; the block's own entry (no self-contact) is 0.
    assert g["top"]["contact_friction"].shape == (2,)
    assert g["block"]["contact_friction"][1] == g["top"]["contact_friction"][0]
    assert g["block"]["contact_friction"][0] == 0.0
    h = 1e-5
    fd = (top_loss(make(0.4 + h)) - top_loss(make(0.4 - h))) / (2 * h)
    assert fd > 0  # the sliding block drags the top one along x
    # Steps solved to 1e-12 D; h small enough that no contact switches within it (the Rust
    # test's bound, tests/integration/gradient_contact.rs).
    assert g["top"]["contact_friction"][0] == pytest.approx(fd, rel=1e-5)
    assert g["top"]["contact_stiffness"].shape == (2,)


def test_placement_gradient_matches_central_differences():
    """A block thrown onto the plane: dL/d(velocity) and dL/d(translation) of its placement."""
    steps = 5
    base = {"translation": [0.0, 0.01, 0.0], "velocity": [1.0, -0.5, 0.2], "angular_velocity": [0.0, 2.0, 1.0]}

    def make(placement):
        w = ff.World(ff.Scene.from_toml(SLIDE.format(steps=steps, mu=0.4)))
        w.set_placement("block", placement)
        return w

    w = make(base)
    g, row = slide_gradients(w, steps)
    g = g["placement"]
    h = 1e-5
    for key in ("velocity", "translation", "angular_velocity"):
        for k in range(3):
            up = {**base, key: list(base[key])}
            down = {**base, key: list(base[key])}
            up[key][k] += h
            down[key][k] -= h
            fd = (slide_loss(make(up), steps) - slide_loss(make(down), steps)) / (2 * h)
            # Steps solved to 1e-12 D; no contact switches within +-h: the bound without contact.
            assert g[key][k] == pytest.approx(fd, rel=1e-5, abs=1e-7), (key, k)
    # After a step the recording no longer starts at the placement: no placement gradient.
    w.step()
    rec = ff.Recording(w, 1)
    rec.step(w)
    assert rec.backward(w, {"block": np.tile(row, (2, 1))})["block"]["placement"] is None


def test_collider_pose_gradient_matches_central_differences():
    """The plane lifted by y between steps (a pose the live API holds through each step):
    dL/dy = sum over steps of the start and end pose gradients' y translation."""
    steps = 5

    def make(lift):
        w = ff.World(ff.Scene.from_toml(SLIDE.format(steps=steps, mu=0.4)))
        w.set_collider_pose(0, translation=[0.0, lift, 0.0])
        return w

    w = make(0.001)
    g, row = slide_gradients(w, steps)
    assert g["collider_pose"].shape == (steps, 1, 2, 6)
    adjoint = g["collider_pose"][:, 0, :, 1].sum()
    h = 1e-6
    fd = (slide_loss(make(0.001 + h), steps) - slide_loss(make(0.001 - h), steps)) / (2 * h)
    # Steps solved to 1e-12 D; no contact switches within +-h: the bound without contact.
    assert abs(fd) > 1e-3, fd  # lifting the floor presses harder: more friction
    assert adjoint == pytest.approx(fd, rel=1e-5)
    assert g["exact_hessians"] >= 1 and g["hessian_products"] >= 0
