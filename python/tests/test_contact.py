"""Object-object contact reports from Python against the command line's `run --json`."""

import json
import subprocess
from pathlib import Path

import numpy as np

import freeform as ff

STEPS = 8

# A block resting on a floor and a second one 1 cm above it falling at 1 m/s: they meet
# within two steps and stay in contact. Small (30 kernels, 3 modes) so it runs in a second.
SCENE = f"""
[simulation]
dt = 0.01
steps = {STEPS}
gravity = [0.0, -9.81, 0.0]

[solver]
cubature = 200
hessian = "newton"

[cache]
enabled = false

[contact]
friction = 0.3

[[object]]
name = "low"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 300
placement = {{ translation = [0.0, 0.0, 0.0] }}

[[object]]
name = "high"
shape = "box:0.2,0.2,0.2"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 30, modes = 3, points = 1500 }}
contact_samples = 300
placement = {{ translation = [0.02, 0.21, 0.0], velocity = [0.0, -1.0, 0.0] }}

[[collider]]
shape = {{ plane = {{ point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] }} }}
"""

# Wall times differ between runs; every other number is computed by the same library code.
TIMED = {"wall_ms", "step_ms_mean"}


def untimed(d):
    return {k: v for k, v in d.items() if k not in TIMED}


def test_contact_reports_equal_the_cli_json_report(freeform_bin, tmp_path):
    path = tmp_path / "two.toml"
    path.write_text(SCENE)
    out = subprocess.run([freeform_bin, "run", str(path), "--json"],
                         check=True, capture_output=True, text=True).stdout
    cli = json.loads(out)["contact"]
    assert len(cli["steps"]) == STEPS

    world = ff.World(ff.Scene.from_file(path))
    assert world.contact is None  # no step yet
    rows = []
    for _ in range(STEPS):
        world.step()
        rows.append(world.contact)
    # The scene does what it is for: the blocks touch, as one island of two.
    assert any(r["sample_pairs_active"] > 0 and r["penetration"] > 0.0 for r in rows)
    assert any(r["island_count"] == 1 and r["largest_island"] == 2 for r in rows)
    for row, ref in zip(rows, cli["steps"]):
        assert row["island_count"] == len(ref["islands"])
        assert row["largest_island"] == max(ref["islands"], default=0)
        # The same library on the same scene with the same thread count is deterministic,
        # and JSON round-trips doubles (shortest representation): equal exactly.
        plain = {k: v for k, v in untimed(row).items()
                 if k not in ("island_count", "largest_island")}
        assert plain == untimed(ref)
    summary = world.contact_summary()
    assert summary["worst_penetration"] > 0.0
    assert untimed(summary) | {"steps": None} == untimed(cli) | {"steps": None}
    assert [untimed(r) for r in summary["steps"]] == [untimed(r) for r in cli["steps"]]


EGG = Path(__file__).resolve().parents[2] / "examples" / "data" / "splats" / "egg.ply"


def test_a_splat_object_lands_on_a_box(tmp_path):
    # The splat egg (examples/data/splats, 507 splats) has no surface of its own: its contact
    # samples lie on the surface derived from the volume its centres occupy.
    head = SCENE[:SCENE.index('[[object]]\nname = "high"')]
    collider = SCENE[SCENE.index("[[collider]]"):]
    text = head + f"""[[object]]
name = "egg"
shape = "{EGG}"
material = {{ youngs = 1e6, poisson = 0.3, density = 500.0 }}
basis = {{ kernels = 40, modes = 3 }}
contact_samples = 300
placement = {{ translation = [0.1, 0.275, 0.1], velocity = [0.0, -1.0, 0.0] }}

""" + collider
    world = ff.World(ff.Scene.from_toml(text))
    for _ in range(STEPS):
        world.step()
    summary = world.contact_summary()
    assert summary["derived_surface_triangles"][0] is None
    assert summary["derived_surface_triangles"][1] > 0
    assert all(n > 0 for n in summary["surface_points"])
    assert any(r["sample_pairs_active"] > 0 for r in summary["steps"])
    assert summary["worst_penetration_fraction"] < summary["penetration_tolerance"]
    # Feature samples are off by default; the worst visible penetration says where it was.
    assert summary["feature_samples"] == [0, 0]
    spot = summary["worst_visible_at"]
    if summary["worst_visible_penetration"] > 0.0:
        assert {spot["surface_object"], spot["other_object"]} == {"low", "egg"}
        assert len(spot["rest_point"]) == 3 and 1 <= spot["step"] <= STEPS
    else:
        assert spot is None


def test_no_contact_section_no_contact_report(tmp_path):
    text = SCENE.replace("[contact]\nfriction = 0.3\n", "")
    world = ff.World(ff.Scene.from_toml(text))
    world.step()
    assert world.contact is None
    assert world.contact_summary() is None


def test_objects_in_contact_are_differentiated():
    # The blocks meet within two steps and are solved as an island; its steps are reversed
    # jointly (docs/gradients.md): every object gets its gradients and its row of the pair
    # stiffness and friction gradients. (Central differences: test_gradient.py.)
    world = ff.World(ff.Scene.from_toml(SCENE))
    rec = ff.Recording(world, STEPS)
    for _ in range(STEPS):
        rec.step(world)
    n = len(world.state("high")[0])
    dl = np.zeros((STEPS + 1, n))
    dl[-1, :] = 1.0
    g = rec.backward(world, {"high": dl})
    assert set(g) == {"low", "high"}
    for name in g:
        assert g[name]["contact_stiffness"].shape == (2,)
        assert np.all(np.isfinite(g[name]["contact_friction"]))
    assert g["low"]["contact_stiffness"][1] == g["high"]["contact_stiffness"][0]
    assert g["high"]["contact_stiffness"][0] != 0.0
