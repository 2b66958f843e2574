"""Every numeric argument of every public entry point, swept (issue 33; the scene files get
the same in tests/integration/scene_numbers.rs).

Each numeric argument of each call in CASES, in turn, gets NaN, +-Inf, 0, -1, 1e300 and
1e-300 (a count: -1, 0 and 2**63; an array: the bad value in its first entry), the others
staying valid. The call must raise a FreeformError that names the argument, or be listed in
ACCEPTED with the reason the value is meaningful. The list of calls is checked against the
package itself: a public function or method, or a parameter of one, that CASES does not
know fails the test; so do `Basis.from_shape` options missing from the library's option
table's list (which the package prints for an unknown option).
"""

import inspect
import math
import pathlib
import tempfile

import numpy as np
import pytest

import freeform as ff

SCENE = """
[simulation]
dt = 0.01
steps = 2
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 200

[cache]
enabled = false

[[object]]
name = "bar"
shape = "box:1,0.2,0.2"
basis = { kernels = 40, modes = 4, points = 2000 }

[[object.boundary]]
region = { half_space = { point = [0.1, 0, 0], normal = [-1, 0, 0] } }

[[collider]]
shape = { plane = { point = [0.0, -1.0, 0.0], normal = [0.0, 1.0, 0.0] } }
"""

SMALL = dict(kernels=40, modes=4, points=2000)
CLOUD_SMALL = dict(kernels=40, modes=4)  # from_points: its points are the integration points

FLOATS = [("nan", math.nan), ("inf", math.inf), ("-inf", -math.inf), ("0", 0.0),
          ("-1", -1.0), ("1e300", 1e300), ("1e-300", 1e-300)]
COUNTS = [("-1", -1), ("0", 0), ("2**63", 2**63)]

# Parameters that hold no number: names, paths, text, flags, callables, dicts (a dict's
# numbers are the scene's and are swept by the Rust test), matrices (eigsh's checks of
# them are tested in test_eigsh.py), output arrays (test_world.py).
NOT_NUMBERS = {
    "self", "shape", "path", "text", "base_dir", "name", "basis", "scene", "motion",
    "placement", "boundaries", "preconditioner", "check_symmetry", "progress", "gradients",
    "allow_open_mesh", "strict", "cache", "h", "m", "out", "options", "prim", "instance",
    "world", "dl_dz", "test", "cache_dir",
}


def world():
    return ff.World(ff.Scene.from_toml(SCENE))


def small_basis():
    return ff.Basis.from_shape("box:1,0.2,0.2", **SMALL)


def cloud():
    rng = np.random.default_rng(0)
    return rng.random((2000, 3)) * [1.0, 0.2, 0.2]


# name -> (call(**args), baseline args, {numeric argument: "float" | "count" | "array" |
# "index"}). "index" is an object or collider given by its index (a count).
CASES = {
    "sample": (ff.sample, dict(shape="box:1,1,1", points=500), {"points": "count", "spacing": "float"}),
    "eigsh": (None, None, {"nev": "count", "tol": "float", "max_iter": "count"}),
    "Basis.from_shape": (None, None, {}),  # its options: test_every_basis_option
    "Basis.from_points": (
        lambda **a: ff.Basis.from_points(**a, **CLOUD_SMALL),
        dict(points=cloud(), youngs=1e6, poisson=0.4, density=1000.0, volumes=None),
        {"points": "array", "youngs": "float", "poisson": "float", "density": "float",
         "volumes": "array"},
    ),
    "Basis.weights": (lambda **a: small_basis().weights(**a), dict(points=np.full((3, 3), 0.1)),
                      {"points": "array"}),
    "Basis.evaluate": (lambda **a: small_basis().evaluate(**a),
                       lambda: dict(points=np.full((3, 3), 0.1),
                                    coefficients=np.ones((small_basis().kernels, 2))),
                       {"points": "array", "coefficients": "array"}),
    "Scene.add_object": (None, None, {"points": "array", "youngs": "float", "poisson": "float",
                                      "density": "float", "volumes": "array",
                                      "cubature": "count"}),
    "World.step": (lambda **a: world().step(**a), dict(count=1), {"count": "count"}),
    "World.set_gravity": (lambda **a: world().set_gravity(**a), dict(gravity=[0.0, -9.81, 0.0]),
                          {"gravity": "array"}),
    "World.set_boundary_pose": (
        lambda **a: world().set_boundary_pose(**a),
        dict(object=0, boundary=0, rotation=np.eye(3), translation=[0.0, 0.1, 0.0]),
        {"object": "index", "boundary": "index", "rotation": "array", "translation": "array"},
    ),
    "World.set_collider_pose": (
        lambda **a: world().set_collider_pose(**a),
        dict(collider=0, rotation=np.eye(3), translation=[0.0, 0.1, 0.0]),
        {"collider": "index", "rotation": "array", "translation": "array"},
    ),
    "World.set_state": (None, None, {"object": "index", "z": "array", "zdot": "array"}),
    "World.set_boundary_motion": (
        lambda **a: world().set_boundary_motion(**a),
        dict(object=0, boundary=0, motion="fixed"), {"object": "index", "boundary": "index"}),
    "World.set_placement": (lambda **a: world().set_placement(**a),
                            dict(object=0, placement={}), {"object": "index"}),
}
# Calls that take an object (index or name) and nothing else numeric.
for method in ["basis", "integration_positions", "positions", "rest_positions", "state",
               "stress", "triangles"]:
    CASES[f"World.{method}"] = (
        (lambda m: lambda **a: getattr(world(), m)(**a))(method), dict(object=0),
        {"object": "index"})
# Calls without numeric arguments (listed so that a new one must be placed).
for name in ["Basis.load", "Basis.save", "Scene.from_dict", "Scene.from_file",
             "Scene.from_toml", "Scene.to_dict", "Scene.to_toml", "World.contact_summary",
             "World.summaries"]:
    CASES[name] = (None, None, {})


def _eigsh(**a):
    import scipy.sparse as sp

    k = 30
    lap = sp.diags([np.full(k, 2.0), -np.ones(k - 1), -np.ones(k - 1)], [0, 1, -1]).tolil()
    lap[0, 0] = lap[k - 1, k - 1] = 1.0
    return ff.eigsh(lap.tocsr(), sp.identity(k, format="csr"), **a)


def _add_object(**a):
    pts = a.pop("points")
    s = ff.Scene.from_dict({"simulation": {"dt": 0.01, "steps": 1}})
    b = ff.Basis.from_points(cloud(), 1e6, **CLOUD_SMALL)
    s.add_object("blob", b, pts, **a)
    return ff.World(s)


def _set_state(**a):
    w = a.pop("w")
    return w.set_state(**a)


def _state_args():
    w = world()
    z, zdot = w.state(0)
    return dict(w=w, object=0, z=z, zdot=zdot)


CASES["eigsh"] = (_eigsh, dict(nev=4, tol=1e-8, max_iter=500), CASES["eigsh"][2])
CASES["Scene.add_object"] = (
    _add_object,
    dict(points=cloud(), youngs=1e6, poisson=0.4, density=1000.0, volumes=None, cubature=200),
    CASES["Scene.add_object"][2])
CASES["World.set_state"] = (_set_state, None, CASES["World.set_state"][2])

# A stage with Kaolin's material schema on /P (docs/usd.md), for read_usd_kaolin's time code.
KAOLIN_STAGE = pathlib.Path(tempfile.mkdtemp()) / "kaolin.usda"
KAOLIN_STAGE.write_text("""#usda 1.0
def Points "P" (
    prepend apiSchemas = ["KaolinPhysicsMaterialAPI:default"]
)
{
    point3f[] points = [(0, 0, 0)]
    point3f[] kaolin_physics_material:default:pts = [(0, 0, 0)]
    float[] kaolin_physics_material:default:yms = [1e6]
    float[] kaolin_physics_material:default:prs = [0.4]
    float[] kaolin_physics_material:default:rhos = [1000]
    float kaolin_physics_material:default:appx_vol = 1
}
""")
CASES["read_usd_kaolin"] = (lambda **a: ff.read_usd_kaolin(KAOLIN_STAGE, "/P", **a),
                            dict(time=None), {"time": "float"})

# Gradients (docs/gradients.md): the recording's step count, and the positions maps. The
# loss's dL/dz (a dict of arrays) is checked in test_gradient.py.
CASES["Recording"] = (lambda **a: ff.Recording(world(), **a), dict(steps=2), {"steps": "count"})
CASES["map_points"] = (lambda **a: ff.map_points(world(), **a),
                       dict(object=0, points=np.full((3, 3), 0.1)),
                       {"object": "index", "points": "array"})
CASES["positions_adjoint"] = (lambda **a: ff.positions_adjoint(world(), **a),
                              dict(object=0, points=np.full((3, 3), 0.1), dl_dx=np.ones((3, 3))),
                              {"object": "index", "points": "array", "dl_dx": "array"})
for name in ["Recording.step", "Recording.backward", "Recording.steps", "Recording.tape_bytes",
             "beam_reference"]:
    CASES[name] = (None, None, {})

# Meaningful values, by (call, argument): the cases and why.
ACCEPTED = {
    ("sample", "points"): ({"0"}, None),  # refused below, listed for the reason only
    ("World.step", "count"): ({"0"}, "zero steps: nothing to do"),
    ("World.set_gravity", "gravity"): ({"0", "-1", "1e-300"}, "a gravity component, m/s^2"),
    ("World.set_boundary_pose", "translation"): ({"0", "-1", "1e-300"}, "a displacement, m"),
    ("World.set_collider_pose", "translation"): ({"0", "-1", "1e-300"}, "a displacement, m"),
    ("World.set_boundary_pose", "rotation"): ({"1e-300"}, None),
    ("Basis.from_points", "points"): ({"0", "-1", "1e-300"}, "a coordinate, metres"),
    ("Scene.add_object", "points"): ({"0", "-1", "1e-300"}, "a coordinate, metres"),
    ("Basis.weights", "points"): ({"0", "-1", "1e-300"}, "a coordinate (0 and -1 outside the "
                                  "object are refused by coverage, which names the points)"),
    ("Basis.evaluate", "points"): ({"0", "-1", "1e-300"}, "a coordinate"),
    ("Basis.evaluate", "coefficients"): ({"0", "-1", "1e300", "1e-300"},
                                         "any finite coefficients: the field is linear in them"),
    ("Basis.from_points", "poisson"): ({"0", "1e-300"}, "a Poisson ratio at or near 0"),
    ("Scene.add_object", "poisson"): ({"0", "1e-300"}, "a Poisson ratio at or near 0"),
    ("eigsh", "max_iter"): ({"2**63"}, "an iteration cap: the solve stops when it converges"),
    ("World.set_state", "z"): ({"0", "-1", "1e300", "1e-300"}, "any finite state"),
    ("World.set_state", "zdot"): ({"0", "-1", "1e300", "1e-300"}, "any finite velocity"),
    ("Recording", "steps"): ({"0"}, "a hint for the tape's memory check: zero steps is fine"),
    ("map_points", "points"): ({"0", "-1", "1e-300"}, "a coordinate (outside the object: "
                               "refused by coverage, which names the points)"),
    ("positions_adjoint", "points"): ({"0", "-1", "1e-300"}, "a coordinate, as map_points"),
    ("positions_adjoint", "dl_dx"): ({"0", "-1", "1e300", "1e-300"},
                                     "any finite loss gradient: the map is linear"),
    ("read_usd_kaolin", "time"): ({"0", "-1", "1e300", "1e-300"},
                                  "any finite time code: USD resolves a value at every time"),
}


def bad_values(kind):
    return COUNTS if kind in ("count", "index") else FLOATS


def with_bad(value, bad):
    """`value` (a number or an array) with `bad` in its first entry."""
    if np.isscalar(value) or value is None:
        return bad
    a = np.array(value, dtype=float, copy=True)
    a.flat[0] = bad
    return a


def public_calls():
    """Every public function and method of the package: name -> signature."""
    out = {}
    for name in dir(ff):
        obj = getattr(ff, name)
        if name.startswith("_"):
            continue
        if inspect.isclass(obj):
            if issubclass(obj, BaseException):
                continue
            for m, attr in vars(obj).items():
                if m.startswith("_") or not callable(getattr(obj, m)):
                    continue
                out[f"{name}.{m}"] = inspect.signature(getattr(obj, m))
        elif callable(obj):
            out[name] = inspect.signature(obj)
    return out


def test_every_public_call_and_argument_is_in_the_sweep():
    calls = public_calls()
    unknown = sorted(set(calls) - set(CASES))
    assert not unknown, f"public calls the sweep does not know: {unknown}"
    for name, sig in calls.items():
        numeric = CASES[name][2]
        for p in sig.parameters:
            assert p in numeric or p in NOT_NUMBERS, f"{name}: argument {p!r} is not placed"


def sweep(name):
    call, base, numeric = CASES[name]
    problems, count = [], 0
    for arg, kind in numeric.items():
        for label, bad in bad_values(kind):
            args = _state_args() if name == "World.set_state" else (
                base() if callable(base) else dict(base))
            value = args.get(arg)
            if value is None and kind == "array":
                value = np.full(2000, 1e-5)  # volumes: one per point
            args[arg] = with_bad(value, bad) if kind == "array" else bad
            count += 1
            try:
                call(**args)
            except ff.FreeformError as e:
                words = {arg, arg.replace("_", " ")}
                if not any(w in str(e) for w in words):
                    problems.append(f"{name}({arg}={label}): refused without naming it: {e}")
                continue
            except Exception as e:  # noqa: BLE001 - the point is to catch every other class
                problems.append(f"{name}({arg}={label}): {type(e).__name__}: {e}")
                continue
            listed = ACCEPTED.get((name, arg), (set(), None))[0]
            if kind == "index" and label == "0":
                continue  # the first object, boundary or collider
            if label not in listed:
                problems.append(f"{name}({arg}={label}): accepted, not in ACCEPTED")
    return problems, count


@pytest.mark.parametrize("name", sorted(n for n, c in CASES.items() if c[2]))
def test_numeric_arguments_are_refused_by_name_or_accepted_for_a_reason(name):
    problems, _ = sweep(name)
    assert not problems, "\n".join(problems)


def test_every_basis_option():
    """Every keyword option of Basis.from_shape, from the package's own list."""
    with pytest.raises(ff.InvalidInputError) as e:
        ff.Basis.from_shape("box:1,1,1", zz_unknown=1)
    names = str(e.value).split("the options are: ")[1].split(", ")
    assert "kernels" in names and "modes" in names
    problems = []
    for opt in names:
        for label, bad in FLOATS + COUNTS[2:]:
            args = dict(SMALL)
            args[opt] = bad
            try:
                ff.Basis.from_shape("box:1,0.2,0.2", **args)
            except ff.FreeformError as err:
                if not any(w in str(err) for w in {opt, opt.replace("_", " ")}):
                    problems.append(f"{opt}={label}: refused without naming it: {err}")
                continue
            except Exception as err:  # noqa: BLE001
                problems.append(f"{opt}={label}: {type(err).__name__}: {err}")
                continue
            if (opt, label) not in BASIS_ACCEPTED:
                problems.append(f"{opt}={label}: accepted, not in BASIS_ACCEPTED")
    assert not problems, "\n".join(problems)


# Basis options whose value is meaningful: (option, case).
BASIS_ACCEPTED = {
    ("max_iter", "2**63"),  # an iteration cap: the solve stops when it converges
    ("poisson", "0"), ("poisson", "1e-300"),  # a Poisson ratio at or near 0
    # 2**63 = 9.2e18 is a large but representable modulus, density, volume or voxel edge:
    # the sweep's integer case, meaningful for these float options.
    ("youngs", "2**63"), ("density", "2**63"), ("total_volume", "2**63"), ("voxel", "2**63"),
}
