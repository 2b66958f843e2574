"""The USD stage of a run read by Pixar's own reader (usd-core, `pxr`), against the run's PLY
and VTK frames to float precision: prims, time samples, metadata, splat attributes in the
OpenUSD ParticleField layout, collider poses, stress primvars and Kaolin's physics attributes
(the names and types of Kaolin's schema.usda, PR #972). Skipped, with the reason, where
usd-core is not installed (.ci/run installs it)."""

import re
import subprocess

import numpy as np
import pytest

pxr = pytest.importorskip("pxr", reason="usd-core is not installed: pip install usd-core")
from pxr import Usd, UsdGeom  # noqa: E402

TORUS = "examples/data/torus.obj"

SCENE = """
[simulation]
dt = 0.01
steps = 6
gravity = [0.0, -9.81, 0.0]

[output]
every = 3
formats = ["usd", "ply", "vtk"]
stress = true

[cache]
enabled = false

[[object]]
name = "block-1"
shape = "box:0.4,0.2,0.2"
basis = { kernels = 60, modes = 4 }
placement = { translation = [0.0, 0.5, 0.0], angular_velocity = [0.0, 0.0, 3.0] }

[[object]]
name = "blob"
shape = "blob.ply"
basis = { kernels = 60, modes = 4 }
placement = { translation = [1.0, 0.5, 0.0], angular_velocity = [2.0, 0.0, 0.0] }

[[object]]
name = "torus"
shape = "TORUS"
basis = { kernels = 60, modes = 4 }
placement = { translation = [-1.5, 0.8, 0.0] }

[[collider]]
name = "floor"
shape = { plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] } }

[[collider]]
name = "arm"
shape = { capsule = { a = [3.0, 0.1, 0.0], b = [3.5, 0.1, 0.0], radius = 0.05 } }
motion = { keyframes = { pivot = [3.0, 0.1, 0.0], frames = [
    { time = 0.0, rotation = { axis = [0, 1, 0], degrees = 0 } },
    { time = 0.06, rotation = { axis = [0, 1, 0], degrees = 40 } } ] } }
"""

TYPES = {"float": "<f4", "double": "<f8", "uchar": "u1", "int": "<i4", "uint": "<u4"}


def read_ply(path):
    """Binary little-endian PLY: {property: array} of the vertices, and the faces (or None)."""
    data = path.read_bytes()
    end = data.index(b"end_header\n") + len(b"end_header\n")
    header = data[:end].decode().splitlines()
    assert "format binary_little_endian 1.0" in header
    elements, current = [], None
    for line in header:
        words = line.split()
        if words[0] == "element":
            current = (words[1], int(words[2]), [])
            elements.append(current)
        elif words[0] == "property":
            current[2].append(words[1:])
    pos, vertices, faces = end, None, None
    for name, count, props in elements:
        if name == "vertex":
            dtype = np.dtype([(p[1], TYPES[p[0]]) for p in props])
            vertices = np.frombuffer(data, dtype=dtype, count=count, offset=pos)
            pos += dtype.itemsize * count
        elif name == "face":
            faces = []
            for _ in range(count):
                n = data[pos]
                faces.append(np.frombuffer(data, dtype="<i4", count=n, offset=pos + 1))
                pos += 1 + 4 * n
    return vertices, faces


def read_vtp(path, name=None):
    """Points (name None) or the named point-data array of a freeform .vtp frame (Float64)."""
    data = path.read_bytes()
    head, _, appended = data.partition(b'<AppendedData encoding="raw">\n_')
    if name is None:
        m = re.search(rb"<Points>\s*<DataArray[^>]*offset=\"(\d+)\"", head)
    else:
        m = re.search(rb'<DataArray[^>]*Name="' + name.encode() + rb'"[^>]*offset="(\d+)"', head)
    offset = int(m.group(1))
    size = int(np.frombuffer(appended[offset:offset + 8], dtype="<u8")[0])
    return np.frombuffer(appended[offset + 8:offset + 8 + size], dtype="<f8")


def xyz(v):
    return np.stack([v["x"], v["y"], v["z"]], axis=1)


def splat_file(path, n=200, seed=5):
    """n splats with SH degree 1 in a ball of radius 0.2 m (3DGS layout, float)."""
    rng = np.random.default_rng(seed)
    means = rng.uniform(-0.2, 0.2, (4 * n, 3))
    means = means[np.linalg.norm(means, axis=1) < 0.2][:n]
    q = rng.normal(size=(n, 4))
    q /= np.linalg.norm(q, axis=1, keepdims=True)
    names = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2"]
    names += [f"f_rest_{i}" for i in range(9)]
    names += ["opacity", "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]
    cols = [means, np.zeros((n, 3)), rng.uniform(-1, 1, (n, 3)), rng.uniform(-0.2, 0.2, (n, 9)),
            rng.uniform(-2, 2, (n, 1)), rng.uniform(-5, -4, (n, 3)), q]
    rows = np.concatenate(cols, axis=1).astype("<f4")
    head = f"ply\nformat binary_little_endian 1.0\nelement vertex {n}\n"
    head += "".join(f"property float {p}\n" for p in names) + "end_header\n"
    path.write_bytes(head.encode() + rows.tobytes())


@pytest.fixture(scope="module")
def run(tmp_path_factory, freeform_bin, repo):
    d = tmp_path_factory.mktemp("usd")
    splat_file(d / "blob.ply")
    (d / "scene.toml").write_text(SCENE.replace("TORUS", str(repo / TORUS)))
    subprocess.run([freeform_bin, "run", str(d / "scene.toml"), "--out", str(d / "out")],
                   check=True, capture_output=True)
    return d / "out", Usd.Stage.Open(str(d / "out" / "run.usda"))


FRAMES = [0, 3, 6]


def test_the_stage_states_units_axis_and_time(run):
    _, stage = run
    assert UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    assert UsdGeom.GetStageUpAxis(stage) == "Y"
    assert stage.GetTimeCodesPerSecond() == pytest.approx(100.0, rel=1e-12)
    assert (stage.GetStartTimeCode(), stage.GetEndTimeCode()) == (0, 6)
    assert stage.GetDefaultPrim().GetPath() == "/World"
    kinds = {str(p.GetPath()): p.GetTypeName() for p in stage.Traverse()}
    assert kinds["/World/block_1/points"] == "Points"
    assert kinds["/World/blob/splats"] == "ParticleField3DGaussianSplat"
    assert kinds["/World/torus/surface"] == "Mesh"
    assert kinds["/World/colliders/floor"] == "Mesh"
    assert kinds["/World/colliders/arm"] == "Mesh"


def test_points_and_meshes_equal_the_ply_frames_bit_for_bit(run):
    out, stage = run
    for prim, stem in [("/World/block_1/points", "block-1"), ("/World/torus/surface", "torus")]:
        attr = stage.GetPrimAtPath(prim).GetAttribute("points")
        assert attr.GetTimeSamples() == FRAMES
        for t in FRAMES:
            v, faces = read_ply(out / stem / f"{stem}_{t:06}.ply")
            np.testing.assert_array_equal(np.array(attr.Get(t), dtype="<f4"), xyz(v))
    mesh = UsdGeom.Mesh(stage.GetPrimAtPath("/World/torus/surface"))
    _, faces = read_ply(out / "torus" / "torus_000000.ply")
    assert list(mesh.GetFaceVertexCountsAttr().Get()) == [3] * len(faces)
    np.testing.assert_array_equal(np.array(mesh.GetFaceVertexIndicesAttr().Get()),
                                  np.concatenate(faces))


def test_splats_follow_the_particle_field_layout_of_the_3dgs_frames(run):
    out, stage = run
    prim = stage.GetPrimAtPath("/World/blob/splats")
    degree = prim.GetAttribute("radiance:sphericalHarmonicsDegree").Get()
    assert degree == 1
    for t in FRAMES:
        v, _ = read_ply(out / "blob" / f"blob_{t:06}.ply")
        pos = np.array(prim.GetAttribute("positions").Get(t), dtype="<f4")
        np.testing.assert_array_equal(pos, xyz(v))
        q = prim.GetAttribute("orientations").Get(t)
        wxyz = np.array([[o.GetReal(), *o.GetImaginary()] for o in q])
        ply_q = np.stack([v[f"rot_{i}"] for i in range(4)], axis=1).astype(float)
        ply_q /= np.linalg.norm(ply_q, axis=1, keepdims=True)
        # Both are the same unit quaternion in float32 (the PLY's scaled back by its stored
        # norm, which is 1 to float precision here): 1e-6.
        np.testing.assert_allclose(wxyz, ply_q, atol=1e-6)
        scales = np.array(prim.GetAttribute("scales").Get(t))
        ply_s = np.exp(np.stack([v[f"scale_{i}"] for i in range(3)], axis=1).astype(float))
        np.testing.assert_allclose(scales, ply_s, rtol=1e-6)
        sh = np.array(prim.GetAttribute("radiance:sphericalHarmonicsCoefficients").Get(t))
        sh = sh.reshape(len(v), 4, 3)
        dc = np.stack([v[f"f_dc_{c}"] for c in range(3)], axis=1)
        np.testing.assert_array_equal(sh[:, 0, :].astype("<f4"), dc)
        for c in range(3):
            rest = np.stack([v[f"f_rest_{c * 3 + k}"] for k in range(3)], axis=1)
            np.testing.assert_array_equal(sh[:, 1:, c].astype("<f4"), rest)
    opacities = np.array(prim.GetAttribute("opacities").Get())
    v, _ = read_ply(out / "blob" / "blob_000000.ply")
    np.testing.assert_allclose(opacities, 1 / (1 + np.exp(-v["opacity"].astype(float))), rtol=1e-6)


def test_colliders_move_with_their_poses_as_in_the_vtk_frames(run):
    out, stage = run
    arm = UsdGeom.Mesh(stage.GetPrimAtPath("/World/colliders/arm"))
    rest = np.array(arm.GetPointsAttr().Get(), dtype=float)
    for t in FRAMES:
        m = np.array(arm.ComputeLocalToWorldTransform(t))
        moved = rest @ m[:3, :3] + m[3, :3]
        vtk = read_vtp(out / "colliders" / f"collider-arm_{t:06}.vtp").reshape(-1, 3)
        # Rest points stored as float32 (6e-8 relative of ~3.5 m): 1e-6 m.
        np.testing.assert_allclose(moved, vtk, atol=1e-6)
    assert stage.GetPrimAtPath("/World/colliders/floor").GetAttribute("points").Get() is not None


def test_stress_primvars_equal_the_vtk_point_data(run):
    out, stage = run
    prim = stage.GetPrimAtPath("/World/block_1/points")
    pv = UsdGeom.PrimvarsAPI(prim)
    vm = pv.GetPrimvar("von_mises")
    assert vm.GetInterpolation() == "vertex"
    assert pv.GetPrimvar("stress").GetElementSize() == 9
    for t in FRAMES:
        vtk = read_vtp(out / "block-1" / f"block-1_{t:06}.vtp", "von_mises")
        np.testing.assert_array_equal(np.array(vm.Get(t), dtype="<f4"), vtk.astype("<f4"))
        s = np.array(pv.GetPrimvar("stress").Get(t), dtype="<f4")
        vtk_s = read_vtp(out / "block-1" / f"block-1_{t:06}.vtp", "stress").astype("<f4")
        np.testing.assert_array_equal(s, vtk_s)


def test_kaolin_physics_attributes_have_the_schema_names_and_types(run):
    _, stage = run
    prim = stage.GetPrimAtPath("/World/block_1/points")
    # Kaolin's plugin is not registered here, so HasAPI cannot see them: read the list op.
    applied = prim.GetMetadata("apiSchemas").ApplyOperations([])
    assert list(applied) == ["KaolinPhysicsMaterialAPI:default", "KaolinSkinnedPhysicsAPI:default"]
    # Types as in Kaolin's kaolin/io/usd/custom_schema/schema.usda.
    types = {"pts": "point3f[]", "yms": "float[]", "prs": "float[]", "rhos": "float[]",
             "appx_vol": "float"}
    for prefix in ["kaolin_physics_material:default:", "kaolin_skinned_physics:default:"]:
        for name, ty in types.items():
            attr = prim.GetAttribute(prefix + name)
            assert str(attr.GetTypeName()) == ty, prefix + name
    sk = "kaolin_skinned_physics:default:"
    pts = np.array(prim.GetAttribute(sk + "pts").Get())
    w = np.array(prim.GetAttribute(sk + "skinning_weights").Get()).reshape(len(pts), -1)
    dwdx = np.array(prim.GetAttribute(sk + "dwdx").Get()).reshape(len(pts), -1, 3)
    assert w.shape[1] == 5 and dwdx.shape[1] == 5
    vol = prim.GetAttribute(sk + "appx_vol").Get()
    assert vol == pytest.approx(0.4 * 0.2 * 0.2, rel=1e-6)
    # Kaolin appends its constant handle last: ones, gradient zero.
    np.testing.assert_array_equal(w[:, -1], 1.0)
    np.testing.assert_array_equal(dwdx[:, -1, :], 0.0)
    render = np.array(prim.GetAttribute(sk + "renderable_skinning_weights").Get())
    assert render.size == len(prim.GetAttribute("points").Get(0)) * 5
    e = np.array(prim.GetAttribute("kaolin_physics_material:default:yms").Get())
    np.testing.assert_array_equal(e, 5e6)
    # Without a time code a reader sees the rest points (Kaolin reads them so for the
    # renderable weights).
    assert len(prim.GetAttribute("points").Get()) * 5 == render.size


def test_kaolin_physics_read_back_as_arrays_start_a_basis(run):
    import freeform as ff

    out, stage = run
    k = ff.read_usd_kaolin(out / "run.usda", "/World/block_1/points")
    m, s = k["material"], k["skinned"]
    n = len(m["points"])
    assert m["youngs"].shape == (n,) and m["volume"] == pytest.approx(0.016, rel=1e-6)
    assert s["weights"].shape[1] == 5 and s["gradients"].shape == (*s["weights"].shape, 3)
    # The same arrays as pxr reads.
    prim = stage.GetPrimAtPath("/World/block_1/points")
    w = np.array(prim.GetAttribute("kaolin_skinned_physics:default:skinning_weights").Get())
    np.testing.assert_array_equal(s["weights"].ravel(), w)
    # A Kaolin basis is weights at points: a freeform basis starts from its points and
    # materials.
    b = ff.Basis.from_points(m["points"], m["youngs"], m["poisson"], m["density"],
                             kernels=40, modes=4)
    w0 = b.weights(s["points"])[:, 0]
    # The constant mode is constant (reproducing conditions, to rounding).
    np.testing.assert_allclose(w0, w0[0], rtol=1e-9)
    with pytest.raises(ff.FreeformError, match="/World/nothing: no such prim"):
        ff.read_usd_kaolin(out / "run.usda", "/World/nothing")
