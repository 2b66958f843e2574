#!/usr/bin/env python3
"""Writes the hand-made part of the fuzz seed corpus (fuzz/corpus/<target>/seed-*).

Run from fuzz/: `python3 make_seeds.py`. The other seeds are copies of tests/data and
examples/ files (see docs/fuzzing.md); fuzzer findings are added as `finding-*` files. The
basis seeds were written by the CLI:
  freeform modes box:1,1,1 --kernels 12 --modes 2 --points 2000 --out corpus/basis/seed-box_k12_m2.npz
  freeform modes box:2,1,1 --kernels 15 --modes 3 --kernel gaussian --points 2000 \
      --out corpus/basis/seed-box_k15_m3_gaussian.npz
"""
import os
import shutil
import struct

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
CUBE_V = [(x, y, z) for z in (0, 1) for y in (0, 1) for x in (0, 1)]
CUBE_F = [(0, 2, 3), (0, 3, 1), (4, 5, 7), (4, 7, 6), (0, 1, 5), (0, 5, 4),
          (2, 6, 7), (2, 7, 3), (0, 4, 6), (0, 6, 2), (1, 3, 7), (1, 7, 5)]


def write(target, name, data):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    with open(os.path.join(d, name), "wb") as f:
        f.write(data.encode() if isinstance(data, str) else data)


def copy(target, rel):
    d = os.path.join(HERE, "corpus", target)
    os.makedirs(d, exist_ok=True)
    shutil.copy(os.path.join(ROOT, rel), os.path.join(d, "seed-" + os.path.basename(rel)))


# PLY: ASCII and binary meshes and point clouds, a double-typed and a uchar-list variant.
for rel in ["tests/data/tetra_ascii.ply", "tests/data/points_ascii.ply",
            "tests/data/splats_3dgs_tiny.ply"]:
    copy("ply", rel)
head = ("ply\nformat binary_little_endian 1.0\nelement vertex 8\nproperty float x\n"
        "property float y\nproperty float z\nelement face 12\n"
        "property list uchar int vertex_indices\nend_header\n").encode()
body = b"".join(struct.pack("<3f", *v) for v in CUBE_V)
body += b"".join(struct.pack("<B3i", 3, *f) for f in CUBE_F)
write("ply", "seed-cube_binary_le.ply", head + body)
head_be = head.replace(b"binary_little_endian", b"binary_big_endian")
body_be = b"".join(struct.pack(">3f", *v) for v in CUBE_V)
body_be += b"".join(struct.pack(">B3i", 3, *f) for f in CUBE_F)
write("ply", "seed-cube_binary_be.ply", head_be + body_be)
write("ply", "seed-cube_double_ascii.ply",
      "ply\nformat ascii 1.0\ncomment hand-made\nelement vertex 8\nproperty double x\n"
      "property double y\nproperty double z\nproperty uchar red\nelement face 6\n"
      "property list uchar uint vertex_index\nend_header\n"
      + "".join("%s %s %s 255\n" % v for v in CUBE_V)
      + "4 0 2 3 1\n4 4 5 7 6\n4 0 1 5 4\n4 2 6 7 3\n4 0 4 6 2\n4 1 3 7 5\n")

# OBJ: quads, an open cube, negative indices with vt/vn, groups.
copy("obj", "tests/data/cube_quads.obj")
copy("obj", "tests/data/cube_open.obj")
write("obj", "seed-cube_negative_vt_vn.obj",
      "o cube\ng all\nmtllib none.mtl\n"
      + "".join("v %s %s %s\n" % v for v in CUBE_V)
      + "vt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
      + "".join("f %d/1/1 %d/2/1 %d/3/1\n" % tuple(i - 8 for i in f) for f in CUBE_F))
write("obj", "seed-tetra.obj",
      "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")

# STL: ASCII and binary cubes, a binary file whose header starts with `solid`.
tris = [tuple(CUBE_V[i] for i in f) for f in CUBE_F]
ascii_stl = "solid cube\n"
for t in tris:
    ascii_stl += " facet normal 0 0 0\n  outer loop\n"
    ascii_stl += "".join("   vertex %s %s %s\n" % v for v in t)
    ascii_stl += "  endloop\n endfacet\n"
write("stl", "seed-cube_ascii.stl", ascii_stl + "endsolid cube\n")
def binary(header):
    out = header.ljust(80, b" ") + struct.pack("<I", len(tris))
    for t in tris:
        out += struct.pack("<3f", 0, 0, 0) + b"".join(struct.pack("<3f", *v) for v in t) + b"\0\0"
    return out
write("stl", "seed-cube_binary.stl", binary(b"binary cube"))
write("stl", "seed-cube_binary_solid_header.stl", binary(b"solid exported by a tool"))

# Scenes: the examples plus a minimal one and one with every table.
for rel in ["examples/beam_bend.toml", "examples/beam_twist.toml", "examples/drop.toml",
            "examples/heterogeneous.toml"]:
    copy("scene", rel)
write("scene", "seed-minimal.toml",
      '[simulation]\ndt = 0.01\nsteps = 2\n[[object]]\nname = "a"\nshape = "sphere:1"\n')
write("scene", "seed-tables.toml",
      '[simulation]\ndt = 0.01\nsteps = 4\ngravity = [0.0, -9.81, 0.0]\n'
      '[solver]\nhessian = "newton"\ntol = 1e-7\nmax_iter = 20\ncubature = 300\n'
      '[output]\nevery = 2\nformats = ["vtk", "ply"]\n[cache]\nenabled = false\n'
      '[[object]]\nname = "bar"\nshape = "box:1,0.2,0.2"\n'
      'material = { youngs = 1e6, poisson = 0.3, density = 500.0 }\n'
      'basis = { kernels = 40, modes = 4, points = 2000, kernel = "quartic" }\n')

# MatrixMarket: symmetric, general with duplicates, pattern, skew-symmetric.
write("matrix_market", "seed-symmetric.mtx",
      "%%MatrixMarket matrix coordinate real symmetric\n% comment\n3 3 5\n"
      "1 1 2.0\n2 1 -1.0\n2 2 2.0\n3 2 -1.0\n3 3 2.0\n")
write("matrix_market", "seed-general.mtx",
      "%%MatrixMarket matrix coordinate real general\n2 2 4\n1 1 1.5\n2 1 -1\n1 2 -1\n1 1 0.5\n")
write("matrix_market", "seed-pattern.mtx",
      "%%MatrixMarket matrix coordinate pattern symmetric\n3 3 3\n1 1\n2 2\n3 3\n")
write("matrix_market", "seed-skew.mtx",
      "%%MatrixMarket matrix coordinate integer skew-symmetric\n3 3 2\n2 1 4\n3 1 -7\n")
