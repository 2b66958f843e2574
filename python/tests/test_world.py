"""The live simulation from Python against the command line's batch run, and the calls
between steps."""

import re
import subprocess
import time

import numpy as np
import pytest

import freeform as ff

# A sphere dropped on a floor and a bar held at one end under gravity: small enough to run
# in a second, with contact, a boundary and two objects.
SCENE = """
[simulation]
dt = 0.01
steps = 20
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 300

[output]
every = 5
formats = ["vtk"]

[cache]
enabled = false

[[object]]
name = "ball"
shape = "sphere:0.3"
material = { youngs = 2e5, poisson = 0.4, density = 1000.0 }
basis = { kernels = 80, modes = 6 }
placement = { translation = [2.0, 0.35, 0.0], velocity = [0.5, 0.0, 0.0] }

[[object]]
name = "bar"
shape = "box:1,0.2,0.2"
basis = { kernels = 80, modes = 6 }

[[object.boundary]]
region = { half_space = { point = [0.1, 0, 0], normal = [-1, 0, 0] } }

[[collider]]
shape = { plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] } }
"""


def read_vtp_points(path):
    """Points of a freeform .vtp frame (raw appended Float64 data, UInt64 block headers)."""
    data = path.read_bytes()
    head, _, appended = data.partition(b'<AppendedData encoding="raw">\n_')
    n = int(re.search(rb'NumberOfPoints="(\d+)"', head).group(1))
    points = re.search(rb"<Points>\s*<DataArray[^>]*offset=\"(\d+)\"", head)
    offset = int(points.group(1))
    size = int(np.frombuffer(appended[offset:offset + 8], dtype="<u8")[0])
    assert size == n * 24
    return np.frombuffer(appended[offset + 8:offset + 8 + size], dtype="<f8").reshape(n, 3)


@pytest.fixture()
def scene_file(tmp_path):
    path = tmp_path / "scene.toml"
    path.write_text(SCENE)
    return path


def test_a_scene_stepped_from_python_equals_the_cli_run_frame_for_frame(freeform_bin, scene_file, tmp_path):
    out = tmp_path / "frames"
    subprocess.run([freeform_bin, "run", str(scene_file), "--out", str(out)],
                   check=True, capture_output=True)
    world = ff.World(ff.Scene.from_file(scene_file))
    assert world.object_names == ["ball", "bar"]
    compared = 0
    for step in range(0, 21):
        if step > 0:
            reports = world.step()
            assert [r["object"] for r in reports] == ["ball", "bar"]
            assert all(r["converged"] and r["step"] == step for r in reports)
        if step % 5:
            continue
        for name in world.object_names:
            frame = read_vtp_points(out / name / f"{name}_{step:06}.vtp")
            # The same library code on the same input, and the library is deterministic
            # bit for bit (tests/integration/pipeline.rs): the frames are equal exactly.
            np.testing.assert_array_equal(world.positions(name), frame)
            compared += 1
    assert compared == 10
    assert abs(world.time - 0.2) < 1e-12


def scene(**changes):
    s = ff.Scene.from_toml(SCENE)
    d = s.to_dict()
    for key, value in changes.items():
        d["simulation"][key] = value
    return ff.Scene.from_dict(d)


def test_state_gravity_and_poses_between_steps():
    world = ff.World(scene())
    world.step(3)
    assert world.steps == 3 and abs(world.time - 0.03) < 1e-12
    z, zdot = world.state("ball")
    x = world.positions("ball")
    world.step(2)
    assert not np.array_equal(world.positions("ball"), x)
    world.set_state("ball", z, zdot)
    # x = sum_j W_j (A_j X + b_j): a function of z alone, so equal bit for bit.
    np.testing.assert_array_equal(world.positions("ball"), x)

    # Gravity off and the ball at rest in the air: it stays where it is.
    world.set_gravity(None)
    world.set_placement("ball", {"translation": [2.0, 1.0, 0.0]})
    before = world.positions("ball").mean(axis=0)
    world.step(5)
    np.testing.assert_allclose(world.positions("ball").mean(axis=0), before, atol=1e-9)

    # The bar's held end follows a pose target: lifted by 2 cm.
    rest = world.rest_positions("bar")
    world.set_boundary_pose("bar", 0, translation=[0.0, 0.02, 0.0])
    world.step(30)
    held = rest[:, 0] < 0.1
    lift = (world.positions("bar") - rest)[held, 1]
    # The penalty hold follows to ~1% of the motion (tests/integration/world.rs).
    np.testing.assert_allclose(lift, 0.02, atol=0.02 * 0.03)


def test_positions_into_a_preallocated_array():
    world = ff.World(scene())
    out = np.empty((len(world.rest_positions(0)), 3))
    assert world.positions(0, out=out) is not None
    np.testing.assert_array_equal(out, world.positions(0))
    with pytest.raises(ff.InvalidInputError, match="expected an array of shape"):
        world.positions(0, out=np.empty((3, 3)))
    # float32 (what renderers upload) takes the values rounded; integers are refused.
    out32 = np.empty(out.shape, dtype=np.float32)
    assert world.positions(0, out=out32) is out32
    np.testing.assert_array_equal(out32, world.positions(0).astype(np.float32))
    with pytest.raises(ff.InvalidInputError, match="float array"):
        world.positions(0, out=np.empty(out.shape, dtype=np.int32))


def test_scene_dicts_take_int_label_keys_as_names():
    # {1: "soft"} is what a Python user writes for TOML's labels = { 1 = "soft" }.
    ff.Scene.from_dict({
        "simulation": {"dt": 0.01, "steps": 1},
        "materials": {"soft": {"youngs": 1e5}},
        "object": [{"name": "a", "shape": "image",
                    "image": {"file": "ct.npy", "spacing": [0.01, 0.01, 0.01],
                              "labels": {1: "soft"}}}],
    })


def test_scene_dicts_take_numpy_values_and_name_non_finite_fields():
    settings = {"simulation": {"dt": np.float32(0.01), "steps": np.int64(2),
                               "gravity": np.array([0.0, -9.81, 0.0])}}
    ff.Scene.from_dict(settings)
    bad = {"simulation": {"dt": 0.01, "steps": 2, "gravity": [0.0, np.nan, 0.0]}}
    with pytest.raises(ff.InvalidInputError, match=r"simulation.gravity\[1\] = NaN"):
        ff.Scene.from_dict(bad)


def test_bad_calls_between_steps_raise_clear_errors():
    world = ff.World(scene())
    z, zdot = world.state(0)
    with pytest.raises(ff.InvalidInputError, match="no object named 'cup'"):
        world.positions("cup")
    with pytest.raises(ff.InvalidInputError, match="the scene has 2 objects"):
        world.positions(5)
    with pytest.raises(ff.InvalidInputError, match="expected 84 values"):
        world.set_state(0, z[:10], zdot)
    bad = z.copy()
    bad[3] = np.nan
    with pytest.raises(ff.InvalidInputError, match="not finite"):
        world.set_state(0, bad, zdot)
    with pytest.raises(ff.InvalidInputError, match="proper rotation"):
        world.set_boundary_pose("bar", 0, rotation=2 * np.eye(3))
    with pytest.raises(ff.InvalidInputError, match="boundary"):
        world.set_boundary_pose("bar", 4)
    with pytest.raises(ff.InvalidInputError, match="motion"):
        world.set_boundary_motion("bar", 0, {"wiggle": {}})
    with pytest.raises(ff.InvalidInputError, match="gravity"):
        world.set_gravity([0.0, np.inf, 0.0])
    with pytest.raises(ff.InvalidInputError, match="collider"):
        world.set_collider_pose(3, translation=[0, 1, 0])
    # Negative counts and indices are invalid input naming the argument (pyo3 alone raises a
    # bare OverflowError), and so is gravity beyond the limit.
    with pytest.raises(ff.InvalidInputError, match="count = -1"):
        world.step(-1)
    with pytest.raises(ff.InvalidInputError, match="boundary = -2"):
        world.set_boundary_pose("bar", -2)
    with pytest.raises(ff.InvalidInputError, match="collider = -1"):
        world.set_collider_pose(-1, translation=[0, 1, 0])
    with pytest.raises(ff.InvalidInputError, match="points = -5"):
        ff.sample("box:1,1,1", points=-5)
    with pytest.raises(ff.InvalidInputError, match="above the limit"):
        world.set_gravity([0.0, -1e300, 0.0])
    # Nothing above changed the state.
    np.testing.assert_array_equal(world.state(0)[0], z)


def test_bad_scenes_raise_clear_errors(tmp_path):
    with pytest.raises(ff.FreeformIOError, match="nope.toml"):
        ff.Scene.from_file(tmp_path / "nope.toml")
    with pytest.raises(ff.InvalidInputError, match="dt"):
        scene(dt=-1.0)
    with pytest.raises(ff.InvalidInputError, match="line"):
        ff.Scene.from_toml("[simulation\ndt = 1")
    bad = SCENE.replace('shape = "sphere:0.3"', 'shape = "missing.obj"')
    with pytest.raises(ff.FreeformIOError, match="ball"):
        ff.World(ff.Scene.from_toml(bad, base_dir=str(tmp_path)))


def test_reports_and_summaries_are_dicts():
    world = ff.World(scene())
    reports = world.step()
    assert set(reports[0]) >= {"object", "step", "time", "converged", "iterations", "residual",
                               "energy", "min_det", "contacts", "penetration", "wall_ms"}
    summaries = world.summaries()
    assert [s["name"] for s in summaries] == ["ball", "bar"]
    assert summaries[0]["steps"][0]["step"] == 1
    basis = world.basis("bar")
    assert basis.kernels == 80 and basis.modes == 6


def test_an_object_from_arrays_moves_as_the_same_object_from_its_shape():
    # The scene's own object and the same object made from arrays (the same points,
    # materials, volumes and basis): the same arithmetic, so the same positions.
    spec = {"name": "bar", "shape": "box:1,0.2,0.2", "basis": {"kernels": 60, "modes": 6, "points": 3000},
            "material": {"youngs": 1e5, "poisson": 0.4, "density": 1000.0},
            "boundary": [{"region": {"half_space": {"point": [0.1, 0, 0], "normal": [-1, 0, 0]}}}]}
    settings = {"simulation": {"dt": 0.01, "steps": 5, "gravity": [0.0, -9.81, 0.0]},
                "solver": {"cubature": 300}, "cache": {"enabled": False}}
    from_shape = ff.World(ff.Scene.from_dict({**settings, "object": [spec]}))
    points, volumes = ff.sample("box:1,0.2,0.2", points=3000)
    # The scene's basis is boundary-aware (the default) for its held region: the same here.
    basis = ff.Basis.from_points(points, 1e5, 0.4, 1000.0, volumes, kernels=60, modes=6,
                                 regions=["halfspace:0.1,0,0,-1,0,0"])
    np.testing.assert_array_equal(basis.eigenvalues, from_shape.basis("bar").eigenvalues)
    scene = ff.Scene.from_dict(settings)
    scene.add_object("bar", basis, points, 1e5, 0.4, 1000.0, volumes, boundaries=spec["boundary"])
    assert scene.object_names == ["bar"]
    from_arrays = ff.World(scene)
    from_shape.step(5)
    from_arrays.step(5)
    np.testing.assert_array_equal(from_arrays.positions("bar"), from_shape.positions("bar"))
    # Mistakes are reported when the object is added, naming what is wrong.
    with pytest.raises(ff.InvalidInputError, match="two objects are named 'bar'"):
        scene.add_object("bar", basis, points, 1e5)
    with pytest.raises(ff.InvalidInputError, match=f"expected {len(points)} values"):
        scene.add_object("other", basis, points, np.ones(10))
    with pytest.raises(ff.InvalidInputError, match="boundaries"):
        scene.add_object("other", basis, points, 1e5, boundaries=[{"area": 1}])
    with pytest.raises(ff.InvalidInputError, match="no \\[\\[object\\]\\]"):
        ff.World(ff.Scene.from_dict(settings))


def test_sample_gives_points_inside_with_the_volume():
    points, volumes = ff.sample("sphere:0.5", points=5000)
    assert points.shape == (len(volumes), 3) and abs(len(points) - 5000) < 500
    assert np.all(np.linalg.norm(points, axis=1) < 0.5)
    # The grid cells inside a sphere of radius 0.5 add up to its volume (the sampler
    # scales the cells to the exact volume of primitives).
    np.testing.assert_allclose(volumes.sum(), 4 / 3 * np.pi * 0.125, rtol=1e-9)
    with pytest.raises(ff.InvalidInputError, match="not both"):
        ff.sample("box:1,1,1", points=10, spacing=0.1)
    with pytest.raises(ff.FreeformIOError, match="nothing.obj"):
        ff.sample("nothing.obj")


def test_stress_at_rest_is_zero_and_under_load_balances_gravity():
    world = ff.World(scene())
    assert np.abs(world.stress("bar")).max() < 1e-6
    world.step(30)
    sigma = world.stress("bar")
    assert sigma.shape == (len(world.rest_positions("bar")), 3, 3)
    np.testing.assert_allclose(sigma, np.transpose(sigma, (0, 2, 1)), atol=1e-9 * np.abs(sigma).max())
    # The held bar hangs under gravity: bending stress, largest near the held end, of the
    # order of rho g L^2 / h (1000 * 9.81 * 1 / 0.2 ~ 5e4 Pa).
    assert 1e3 < np.abs(sigma).max() < 1e6


STRICT_SCENE = """
[simulation]
dt = 0.01
steps = 5
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
tol = 1e-9
max_iter = 1
cubature = 300

[cache]
enabled = false

[[object]]
name = "bar"
shape = "box:1,0.2,0.2"
basis = { kernels = 60, modes = 4, points = 3000 }

[[object.boundary]]
region = { half_space = { point = [0.1, 0, 0], normal = [-1, 0, 0] } }
"""


def test_a_strict_world_refuses_every_step_after_it_stopped():
    # One Newton iteration cannot reach 1e-9: the first step warns, and strict mode stops the
    # world there for good, as the C world does.
    world = ff.World(ff.Scene.from_toml(STRICT_SCENE), strict=True)
    with pytest.raises(ff.StrictModeError, match="did not converge"):
        world.step()
    t = world.time
    for _ in range(2):
        with pytest.raises(ff.StrictModeError):
            world.step()
    assert world.time == t
