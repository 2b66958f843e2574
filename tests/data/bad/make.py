#!/usr/bin/env python3
"""Writes the bad-input corpus that tests/integration/bad_inputs.rs drives through the CLI and the library.

Run from this directory: `python3 make.py`. Every file is small and deterministic; the
expected error of each one is in the table at the top of tests/integration/bad_inputs.rs.
"""
import os
import random
import struct

HERE = os.path.dirname(os.path.abspath(__file__))


def write(name, data):
    path = os.path.join(HERE, name)
    os.makedirs(os.path.dirname(path), exist_ok=True)
    mode = "wb" if isinstance(data, bytes) else "w"
    with open(path, mode) as f:
        f.write(data)


# A unit cube: 8 vertices, 12 outward triangles (0-based).
CUBE_V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_F = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
          (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]


def ply_ascii(vertices, faces, nv=None, nf=None, extra_header=""):
    nv = len(vertices) if nv is None else nv
    nf = len(faces) if nf is None else nf
    head = ("ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\n"
            "property float z\n%selement face %d\nproperty list uchar int vertex_indices\n"
            "end_header\n" % (nv, extra_header, nf))
    body = "".join("%s %s %s\n" % v for v in vertices)
    body += "".join("%d %s\n" % (len(f), " ".join(str(i) for i in f)) for f in faces)
    return head + body


def ply_binary_points(points, declared=None):
    n = len(points) if declared is None else declared
    head = ("ply\nformat binary_little_endian 1.0\nelement vertex %d\nproperty float x\n"
            "property float y\nproperty float z\nend_header\n" % n).encode()
    return head + b"".join(struct.pack("<3f", *p) for p in points)


def obj(vertices, faces):
    return ("".join("v %s %s %s\n" % v for v in vertices)
            + "".join("f %s\n" % " ".join(str(i + 1) for i in f) for f in faces))


def off(vertices, faces, nv=None, nf=None, header="OFF\n"):
    nv = len(vertices) if nv is None else nv
    nf = len(faces) if nf is None else nf
    return (header + "%d %d 0\n" % (nv, nf)
            + "".join("%s %s %s\n" % v for v in vertices)
            + "".join("%d %s\n" % (len(f), " ".join(str(i) for i in f)) for f in faces))


def stl_binary(tris, declared=None):
    n = len(tris) if declared is None else declared
    out = b"freeform bad-input corpus".ljust(80, b" ") + struct.pack("<I", n)
    for t in tris:
        out += struct.pack("<3f", 0, 0, 0)
        for v in t:
            out += struct.pack("<3f", *v)
        out += b"\0\0"
    return out


rng = random.Random(6)
garbage = bytes(rng.randrange(256) for _ in range(512))

# --- PLY -------------------------------------------------------------------------------
write("ply/empty.ply", b"")
write("ply/garbage.ply", garbage)
write("ply/header_only.ply", "ply\n")
write("ply/no_end_header.ply", "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n")
write("ply/truncated_ascii.ply", ply_ascii(CUBE_V[:3], [], nv=8, nf=0))
write("ply/truncated_binary.ply",
      ply_binary_points([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], declared=8)[:-5])
write("ply/nan_ascii.ply", ply_ascii([(0, 0, 0), ("nan", 1, 1), (1, 1, 1)], [], nf=0))
write("ply/inf_binary.ply", ply_binary_points([(0, 0, 0), (1, float("inf"), 0), (1, 1, 1)]))
write("ply/nan_binary.ply", ply_binary_points([(0, 0, 0), (1, 1, 0), (1, 1, float("nan"))]))
write("ply/missing_z.ply",
      "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n"
      "end_header\n0 0\n1 1\n")
write("ply/face_out_of_range.ply", ply_ascii(CUBE_V, CUBE_F[:-1] + [(1, 7, 99)]))
write("ply/face_negative_index.ply", ply_ascii(CUBE_V, CUBE_F[:-1] + [(1, -7, 5)]))
write("ply/face_two_vertices.ply", ply_ascii(CUBE_V, CUBE_F[:-1] + [(1, 7)]))
write("ply/too_few_faces.ply", ply_ascii(CUBE_V, CUBE_F, nf=20))
write("ply/too_many_vertices_declared.ply", ply_ascii(CUBE_V, CUBE_F, nv=9))
write("ply/huge_vertex_count.ply", ply_ascii(CUBE_V, [], nv=10**15, nf=0))
write("ply/open_mesh.ply", ply_ascii(CUBE_V, CUBE_F[:-2]))
write("ply/flat_mesh.ply",
      ply_ascii([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 1)]))
write("ply/huge_coordinates.ply",
      ply_ascii([tuple(1e300 * c for c in v) for v in CUBE_V], CUBE_F).replace("float", "double"))
write("ply/no_vertices.ply", ply_ascii([], [], nf=0))
write("ply/coincident_points.ply", ply_ascii([(1, 2, 3)] * 5, [], nf=0))
for name, scale in [("huge", 1e300), ("tiny", 1e-200)]:
    cloud = [tuple(repr(scale * rng.random()) for _ in range(3)) for _ in range(60)]
    write("ply/%s_point_cloud.ply" % name, ply_ascii(cloud, [], nf=0).replace("float", "double"))

# --- OBJ -------------------------------------------------------------------------------
write("obj/empty.obj", b"")
write("obj/binary.obj", garbage)
write("obj/words.obj", "this is not an obj file\njust words\n")
write("obj/no_faces.obj", obj(CUBE_V, []))
write("obj/face_out_of_range.obj", obj(CUBE_V, CUBE_F[:-1] + [(1, 7, 8)]))
write("obj/nan_vertex.obj", obj(CUBE_V[:-1] + [("nan", 1, 1)], CUBE_F))
write("obj/short_vertex.obj", "v 0 0\n" + obj(CUBE_V, CUBE_F))
write("obj/open_box.obj", obj(CUBE_V, CUBE_F[:-2]))
write("obj/misoriented.obj", obj(CUBE_V, CUBE_F[:-1] + [(1, 5, 7)]))
write("obj/flat.obj", obj([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2), (0, 2, 1)]))
write("obj/huge_coordinates.obj", obj([tuple(1e300 * c for c in v) for v in CUBE_V], CUBE_F))

# --- OFF -------------------------------------------------------------------------------
# Line 1 is the header, line 2 the counts, lines 3-10 the vertices, 11-22 the faces.
write("off/garbled_header.off", off(CUBE_V, CUBE_F, header="OFX\n"))
write("off/too_few_faces.off", off(CUBE_V, CUBE_F, nf=14))
write("off/face_out_of_range.off", off(CUBE_V, CUBE_F[:-1] + [(1, 7, 8)]))
write("off/nan_vertex.off", off(CUBE_V[:-1] + [(1, "nan", 1)], CUBE_F))
write("off/trailing_garbage.off", off(CUBE_V, CUBE_F) + "3 0 1 2\n")
write("off/open_box.off", off(CUBE_V, CUBE_F[:-2]))

# --- STL -------------------------------------------------------------------------------
cube_tris = [tuple(CUBE_V[i] for i in f) for f in CUBE_F]
write("stl/empty.stl", b"")
write("stl/short.stl", b"\x01\x02\x03\x04\x05")
write("stl/garbage.stl", garbage)
write("stl/truncated_binary.stl", stl_binary(cube_tris)[:-70])
write("stl/trailing_binary.stl", stl_binary(cube_tris) + b"\0" * 7)
write("stl/huge_count_binary.stl", stl_binary(cube_tris[:1], declared=0xFFFFFFFF))
write("stl/nan_binary.stl",
      stl_binary(cube_tris[:-1] + [((1, 0, 0), (float("nan"), 1, 1), (1, 0, 1))]))
write("stl/open_binary.stl", stl_binary(cube_tris[:-1]))
write("stl/bad_ascii.stl",
      "solid bad\n facet normal 0 0 1\n  outer loop\n   vertex 0 0\n   vertex 1 0 0\n"
      "   vertex 0 1 0\n  endloop\n endfacet\nendsolid bad\n")
write("stl/no_triangles.stl", "solid nothing\nendsolid nothing\n")

# --- Scenes ----------------------------------------------------------------------------
GOOD = ('[simulation]\ndt = 0.01\nsteps = 2\n[[object]]\nname = "bar"\n'
        'shape = "box:1,0.2,0.2"\nbasis = { kernels = 40, modes = 4, points = 2000 }\n')
write("scene/empty.toml", "")
write("scene/garbage.toml", garbage)
write("scene/not_toml.toml", "this is = = not toml [[\n")
write("scene/unknown_top_key.toml", GOOD + "[rendering]\nfancy = true\n")
write("scene/unknown_object_key.toml", GOOD.replace('name = "bar"', 'name = "bar"\nkernals = 50'))
write("scene/wrong_type_steps.toml", GOOD.replace("steps = 2", 'steps = "two"'))
write("scene/negative_steps.toml", GOOD.replace("steps = 2", "steps = -2"))
write("scene/negative_dt.toml", GOOD.replace("dt = 0.01", "dt = -0.01"))
write("scene/nan_dt.toml", GOOD.replace("dt = 0.01", "dt = nan"))
write("scene/inf_gravity.toml", GOOD.replace("steps = 2", "steps = 2\ngravity = [0.0, -inf, 0.0]"))
write("scene/missing_simulation.toml", GOOD.split("\n", 3)[3])
write("scene/no_objects.toml", "[simulation]\ndt = 0.01\nsteps = 2\n")
write("scene/duplicate_names.toml", GOOD + GOOD.split("\n", 3)[3])
write("scene/bad_name.toml", GOOD.replace('name = "bar"', 'name = "../escape"'))
write("scene/negative_box.toml", GOOD.replace("box:1,0.2,0.2", "box:-1,1,1"))
write("scene/huge_box.toml", GOOD.replace("box:1,0.2,0.2", "box:1e300,1,1"))
write("scene/missing_mesh.toml", GOOD.replace("box:1,0.2,0.2", "does_not_exist.obj"))
write("scene/huge_kernels.toml", GOOD.replace("kernels = 40", "kernels = 1000000000000"))
write("scene/huge_points.toml", GOOD.replace("points = 2000", "points = 1000000000000"))
write("scene/huge_steps.toml", GOOD.replace("steps = 2", "steps = 1000000000000"))
write("scene/negative_youngs.toml", GOOD + "material = { youngs = -5e6 }\n")
write("scene/bad_poisson.toml", GOOD + "material = { poisson = 0.5 }\n")
write("scene/zero_every.toml", GOOD + "[output]\nevery = 0\n")
write("scene/bad_format.toml", GOOD + '[output]\nformats = ["gif"]\n')
write("scene/bad_hessian.toml", GOOD + '[solver]\nhessian = "magic"\n')
write("scene/nan_placement.toml", GOOD + "placement = { translation = [nan, 0.0, 0.0] }\n")
write("scene/nan_boundary_region.toml", GOOD + "[[object.boundary]]\n"
      "region = { sphere = { center = [nan, 0.0, 0.0], radius = 1.0 } }\n")
HOLD = ("[[object.boundary]]\n"
        "region = { half_space = { point = [%s, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] } }\n")
write("scene/overlapping_boundaries.toml", GOOD + HOLD % "0.3" + HOLD % "0.2")
write("scene/boundary_covers_object.toml", GOOD + "[[object.boundary]]\n"
      "region = { box = { min = [-1.0, -1.0, -1.0], max = [2.0, 2.0, 2.0] } }\n")
write("scene/bad_boundaries_mode.toml",
      GOOD.replace("points = 2000 }", 'points = 2000, boundaries = "sometimes" }'))
write("scene/zero_normal_boundary.toml", GOOD + "[[object.boundary]]\n"
      "region = { half_space = { point = [0.1, 0.0, 0.0], normal = [0.0, 0.0, 0.0] } }\n")
write("scene/negative_stiffness.toml", GOOD + "[[object.boundary]]\n"
      "region = { half_space = { point = [0.1, 0.0, 0.0], normal = [-1.0, 0.0, 0.0] } }\n"
      "stiffness = -5.0\n")
write("scene/inverted_region_material.toml", GOOD + "[[object.region_material]]\n"
      "region = { box = { min = [0.5, 0.0, 0.0], max = [0.0, 1.0, 1.0] } }\n"
      "material = { youngs = 1e7 }\n")
write("scene/huge_youngs.toml", GOOD + "material = { youngs = 1e308 }\n")
write("scene/zero_normal_collider.toml", GOOD + "[[collider]]\n"
      "shape = { plane = { point = [0.0, -1.0, 0.0], normal = [0.0, 0.0, 0.0] } }\n")

# Colliders of issue 15: meshes that cannot be obstacles, bad numbers, bad kinematics.
write("scene/collider_open_solid.toml", GOOD + "[[collider]]\nname = \"lid\"\n"
      "shape = { mesh = { file = \"../obj/open_box.obj\" } }\n")
write("scene/collider_open_off.toml", GOOD + "[[collider]]\nname = \"lid\"\n"
      "shape = { mesh = { file = \"../off/open_box.off\" } }\n")
# Triangle 1 of a tetrahedron collapsed onto a line (its third corner between the others).
write("scene/collider_flat.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.5 0 0\n"
      "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 1 4 3\n")
write("scene/collider_degenerate.toml", GOOD + "[[collider]]\n"
      "shape = { mesh = { file = \"collider_flat.obj\" } }\n")
write("scene/collider_points.ply", "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\n"
      "property float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n")
write("scene/collider_point_cloud.toml", GOOD + "[[collider]]\n"
      "shape = { mesh = { file = \"collider_points.ply\" } }\n")
write("scene/collider_missing_mesh.toml", GOOD + "[[collider]]\n"
      "shape = { mesh = { file = \"nowhere_collider.stl\" } }\n")
write("scene/collider_zero_radius.toml", GOOD + "[[collider]]\nname = \"ball\"\n"
      "shape = { sphere = { center = [0.0, 0.0, 0.0], radius = 0.0 } }\n")
write("scene/collider_nan_pose.toml", GOOD + "[[collider]]\n"
      "shape = { capsule = { a = [0.0, 0.0, 0.0], b = [1.0, 0.0, 0.0], radius = 0.1 } }\n"
      "motion = { pose = { rotation = [[1, 0, 0], [0, 1, 0], [0, 0, 1]], translation = [nan, 0, 0] } }\n")
write("scene/collider_bad_parent.toml", GOOD + "[[collider]]\nname = \"fore\"\nparent = \"upper\"\n"
      "shape = { capsule = { a = [0.0, 0.0, 0.0], b = [1.0, 0.0, 0.0], radius = 0.1 } }\n")

# Object-object contact of issue 15: objects that start interpenetrating (overlapping, or
# one wholly inside the other), and bad [contact] settings.
SECOND = ('[[object]]\nname = "other"\nshape = "box:1,0.2,0.2"\n'
          'basis = { kernels = 40, modes = 4, points = 2000 }\n')
write("scene/contact_overlap.toml", GOOD + SECOND
      + "placement = { translation = [0.5, 0.1, 0.0] }\n[contact]\n")
write("scene/contact_inside.toml", GOOD.replace("box:1,0.2,0.2", "box:1,1,1")
      + SECOND.replace("box:1,0.2,0.2", "sphere:0.1")
      + "placement = { translation = [0.5, 0.5, 0.5] }\n[contact]\n")
write("scene/contact_negative_stiffness.toml", GOOD + "[contact]\nstiffness = -1.0\n")
write("scene/contact_zero_samples.toml", GOOD + "contact_samples = 0\n[contact]\n")
write("scene/contact_bad_tolerance.toml", GOOD + "[contact]\npenetration_tolerance = 2.0\n")
write("scene/contact_huge_radius.toml", GOOD + "[contact]\nradius = 0.5\n")
write("scene/contact_negative_friction.toml", GOOD + "[contact]\nfriction = -0.2\n")
write("scene/contact_nan_friction.toml", GOOD + "[contact]\n[[contact.pair]]\n"
      "between = [\"bar\", \"floor\"]\nfriction = nan\n")
write("scene/contact_unknown_pair.toml", GOOD + "[contact]\n[[contact.pair]]\n"
      "between = [\"bar\", \"nobody\"]\nfriction = 0.3\n")
write("scene/contact_negative_pair_friction.toml", GOOD + "[contact]\n[[contact.pair]]\n"
      "between = [\"bar\", \"floor\"]\nfriction = -1.0\n")
# Collider meshes (issue 15): a solid with two faces turned the wrong way, a non-finite
# vertex, and a one-sided surface with an edge shared by three triangles (a fin).
write("scene/collider_misoriented.toml", GOOD + "[[collider]]\nname = \"crate\"\n"
      "shape = { mesh = { file = \"../obj/misoriented.obj\" } }\n")
write("scene/collider_nan_vertex.toml", GOOD + "[[collider]]\n"
      "shape = { mesh = { file = \"../obj/nan_vertex.obj\" } }\n")
write("scene/collider_fin.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\n"
      "f 1 2 3\nf 2 1 4\nf 1 2 5\n")
write("scene/collider_fin_surface.toml", GOOD + "[[collider]]\n"
      "shape = { mesh = { file = \"collider_fin.obj\", sided = \"outside\" } }\n")


# --- MatrixMarket pairs (`freeform modes --from-matrices DIR`) -------------------------
# A 6 x 6 diagonal SPD matrix: big enough for `--modes 1` (nev = 2 <= K - 2).
SPD = ("%%MatrixMarket matrix coordinate real symmetric\n6 6 6\n"
       + "".join("%d %d 2\n" % (i, i) for i in range(1, 7)))
def pair(name, hessian, mass=SPD):
    if hessian is not None:
        write("mtx/%s/hessian.mtx" % name, hessian)
    if mass is not None:
        write("mtx/%s/mass.mtx" % name, mass)

pair("missing_mass", SPD, None)
pair("empty", "")
pair("garbage", garbage)
pair("array", "%%MatrixMarket matrix array real general\n3 3\n1\n0\n0\n0\n1\n0\n0\n0\n1\n")
pair("complex", "%%MatrixMarket matrix coordinate complex general\n3 3 1\n1 1 1 0\n")
pair("not_square", "%%MatrixMarket matrix coordinate real general\n3 4 1\n1 1 1\n")
pair("nan_value", SPD.replace("2 2 2\n", "2 2 nan\n"))
pair("index_out_of_range", SPD.replace("6 6 2\n", "7 6 2\n"))
pair("too_few_entries", SPD.replace("6 6 2\n", ""))
pair("huge_size", "%%MatrixMarket matrix coordinate real symmetric\n"
     "1000000000000 1000000000000 1\n1 1 1\n")
pair("huge_entry_count", "%%MatrixMarket matrix coordinate real symmetric\n"
     "3 3 1000000000000000\n1 1 2\n2 2 2\n3 3 2\n")
pair("size_mismatch", SPD, "%%MatrixMarket matrix coordinate real symmetric\n7 7 7\n"
     + "".join("%d %d 2\n" % (i, i) for i in range(1, 8)))
pair("indefinite_mass", SPD, SPD.replace("1 1 2\n", "1 1 -2\n"))

# 3DGS splat objects and render inputs (issue 16): the splat reader's errors name the file,
# the element `vertex`, the vertex and the property; a render input outside the object or
# missing is named with its object.
SPLAT_PROPS = ["x", "y", "z", "nx", "ny", "nz", "f_dc_0", "f_dc_1", "f_dc_2", "opacity",
               "scale_0", "scale_1", "scale_2", "rot_0", "rot_1", "rot_2", "rot_3"]


def splat_ply(rows, props=SPLAT_PROPS):
    head = "ply\nformat ascii 1.0\nelement vertex %d\n" % len(rows)
    head += "".join("property float %s\n" % p for p in props) + "end_header\n"
    return head + "".join(" ".join(repr(v) for v in r) + "\n" for r in rows)


SPLATS = [[0.1 * i, 0.1 * j, 0.1 * k, 0, 0, 0, 0.5, 0.2, 0.1, 2.0, -3.0, -3.0, -3.0,
           1.0, 0.0, 0.0, 0.0] for i in range(10) for j in range(3) for k in range(3)]
zero_quat = [list(r) for r in SPLATS]
zero_quat[7][13:17] = [0.0, 0.0, 0.0, 0.0]
nan_scale = [list(r) for r in SPLATS]
nan_scale[3][11] = float("nan")
no_rot2 = [r[:15] + r[16:] for r in SPLATS]
write("scene/splats_zero_quat.ply", splat_ply(zero_quat))
write("scene/splats_nan_scale.ply", splat_ply(nan_scale))
write("scene/splats_no_rot_2.ply", splat_ply(no_rot2, SPLAT_PROPS[:15] + SPLAT_PROPS[16:]))
for name in ("zero_quat", "nan_scale", "no_rot_2"):
    write("scene/splats_%s.toml" % name, GOOD.replace("box:1,0.2,0.2", "splats_%s.ply" % name))
write("scene/far_render.obj", "v 9 9 9\nv 9 9 10\nv 9 10 9\nf 1 2 3\n")
write("scene/render_outside.toml", GOOD + 'render = ["far_render.obj"]\n')
write("scene/render_missing.toml", GOOD + 'render = ["nowhere.obj"]\n')

# Voxel images (issue 19): NIfTI-1 and .npy files with bad geometry, values or layout, and
# scenes whose label maps leave labels or points without material.


def nifti(dims, data, datatype=2, bitpix=8, pixdim=(1.0, 0.1, 0.1, 0.1), sform=None,
          rank=None):
    """A single-file NIfTI-1 image (little endian, 348-byte header, data at byte 352)."""
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    dim = [len(dims) if rank is None else rank] + list(dims)
    dim += [1] * (8 - len(dim))
    struct.pack_into("<8h", h, 40, *dim)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, *((1.0,) + tuple(pixdim[1:]) + (0.0,) * 4))
    struct.pack_into("<f", h, 108, 352.0)
    h[123] = 1  # metres
    if sform is not None:
        struct.pack_into("<h", h, 254, 1)
        struct.pack_into("<12f", h, 280, *[v for row in sform for v in row])
    h[344:348] = b"n+1\x00"
    return bytes(h) + b"\x00" * 4 + data


def u8(values):
    return bytes(values)


def f32(values):
    return b"".join(struct.pack("<f", v) for v in values)


def npy(descr, shape, data):
    d = "{'descr': '%s', 'fortran_order': True, 'shape': (%s), }" % (
        descr, "".join("%d, " % s for s in shape))
    d += " " * ((64 - (10 + len(d) + 1) % 64) % 64) + "\n"
    return b"\x93NUMPY\x01\x00" + struct.pack("<H", len(d)) + d.encode() + data


LABELS_4 = [1 if i < 2 else 2 for k in range(4) for j in range(4) for i in range(4)]
with_3 = list(LABELS_4)
with_3[1 + 4 * (2 + 4 * 3)] = 3  # voxel [1, 2, 3]
nan_e = [1e5] * 8
nan_e[1] = float("nan")  # voxel [1, 0, 0]
neg_e = [1e5] * 8
neg_e[6] = -2e5  # voxel [0, 1, 1]
write("image/zero_spacing.nii", nifti((2, 2, 2), u8([1] * 8), pixdim=(1, 0.1, 0.0, 0.1)))
write("image/negative_spacing.nii", nifti((2, 2, 2), u8([1] * 8), pixdim=(1, 0.1, 0.1, -0.1)))
write("image/nan_spacing.nii", nifti((2, 2, 2), u8([1] * 8), pixdim=(1, float("nan"), 0.1, 0.1)))
write("image/zero_sform.nii", nifti((2, 2, 2), u8([1] * 8),
                                    sform=[(0.1, 0, 0, 0), (0, 0.0, 0, 0), (0, 0, 0.1, 0)]))
write("image/nan_sform.nii", nifti((2, 2, 2), u8([1] * 8),
                                  sform=[(0.1, float("nan"), 0, 0), (0, 0.1, 0, 0), (0, 0, 0.1, 0)]))
write("image/rotated.nii", nifti((2, 2, 2), u8([1] * 8),
                                 sform=[(0.07, -0.07, 0, 0), (0.07, 0.07, 0, 0), (0, 0, 0.1, 0)]))
write("image/nan_modulus.nii", nifti((2, 2, 2), f32(nan_e), 16, 32))
write("image/negative_modulus.nii", nifti((2, 2, 2), f32(neg_e), 16, 32))
write("image/two_d.nii", nifti((4, 4), u8([1] * 16)))
write("image/four_d.nii", nifti((2, 2, 2, 3), u8([1] * 24)))
write("image/truncated.nii", nifti((4, 4, 4), f32([1e5] * 64))[:352 + 10])
write("image/truncated_header.nii", nifti((2, 2, 2), u8([1] * 8))[:100])
write("image/empty.nii", nifti((2, 2, 2), u8([0] * 8)))
write("image/zero_dims.nii", nifti((2, 0, 2), b""))
write("image/complex.nii", nifti((2, 2, 2), b"\x00" * 64, 32, 64))
write("image/labels.npy", npy("|u1", (4, 4, 4), u8(LABELS_4)))
write("image/two_d.npy", npy("|u1", (4, 16), u8(LABELS_4)))
write("image/truncated.npy", npy("<f8", (4, 4, 4), f32([1e5] * 20)))
write("scene/labels_4.nii", nifti((4, 4, 4), u8(LABELS_4), pixdim=(1, 0.25, 0.25, 0.25)))
write("scene/labels_with_3.nii", nifti((4, 4, 4), u8(with_3), pixdim=(1, 0.25, 0.25, 0.25)))
write("scene/moduli_2.nii", nifti((2, 2, 2), f32([1e5] * 8), 16, 32, pixdim=(1, 0.5, 0.5, 0.5)))
write("scene/labels_4.npy", npy("|u1", (4, 4, 4), u8(LABELS_4)))
MATS = ('[materials.soft]\nyoungs = 1e5\n[materials.stiff]\nyoungs = 1e7\n')
IMG = GOOD.replace("box:1,0.2,0.2", "image") + '[object.image]\nfile = "%s"\n%s'
LAB = 'labels = { 1 = "soft", 2 = "stiff" }\n'
write("scene/image_unknown_label.toml", MATS + IMG % ("labels_with_3.nii", LAB))
write("scene/image_unknown_material.toml",
      MATS + IMG % ("labels_4.nii", 'labels = { 1 = "soft", 2 = "bone" }\n'))
write("scene/image_bad_label_key.toml",
      MATS + IMG % ("labels_4.nii", 'labels = { one = "soft", 2 = "stiff" }\n'))
write("scene/image_gap.toml", MATS + (IMG % ("labels_4.nii", LAB)).replace(
    'shape = "image"', 'shape = "box:2,1,1"'))
write("scene/image_zero_spacing.toml",
      MATS + IMG % ("labels_4.nii", LAB + "spacing = [0.0, 0.25, 0.25]\n"))
write("scene/image_nan_origin.toml",
      MATS + IMG % ("labels_4.nii", LAB + "origin = [nan, 0.0, 0.0]\n"))
write("scene/image_npy_no_spacing.toml", MATS + IMG % ("labels_4.npy", LAB))
write("scene/image_modulus_with_labels.toml", MATS + IMG % ("moduli_2.nii", LAB))
write("scene/image_no_table.toml", GOOD.replace("box:1,0.2,0.2", "image"))
write("scene/image_missing_file.toml", MATS + IMG % ("nowhere.nii", LAB))
write("scene/image_bad_material.toml",
      MATS.replace("youngs = 1e7", "youngs = -1e7") + IMG % ("labels_4.nii", LAB))
write("scene/image_npy_two_d.toml",
      MATS + IMG % ("../image/two_d.npy", LAB + "spacing = [0.25, 0.25, 0.25]\n"))
write("scene/image_npy_truncated.toml",
      MATS + IMG % ("../image/truncated.npy", "spacing = [0.25, 0.25, 0.25]\n"))
