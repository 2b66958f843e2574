#!/usr/bin/env python3
"""Writes the small triangle meshes of examples/container.toml into examples/data/:

- container.obj: an open-top box (floor and four walls, 0.9 x 0.5 x 0.5 m, floor at y = 0),
  its normals pointing inward: a one-sided surface (`sided = "outside"`, the free side is
  the inside of the box);
- torus.obj: a closed torus (major radius 0.06 m, minor 0.025 m, 24 x 12 quads split in two);
- ell.obj: a closed L-shaped prism (0.12 x 0.12 x 0.05 m with a 0.06 m square notch);
- clip.obj: a closed U-shaped prism lying on its side (examples/self_contact.toml): two arms
  0.5 m long and 0.04 m thick, 0.1 m apart, joined by a 0.06 m wide base, 0.1 m deep.

Every solid is closed and outward-oriented (the library checks it when it reads them).
    python3 scripts/example_meshes.py [OUT_DIR]   (default examples/data)
"""
import math
import os
import sys


def write_obj(path, vertices, faces, comment):
    with open(path, "w") as f:
        f.write(f"# {comment}\n# written by scripts/example_meshes.py\n")
        for v in vertices:
            f.write("v {:.6f} {:.6f} {:.6f}\n".format(*v))
        for t in faces:
            f.write("f {} {} {}\n".format(*(i + 1 for i in t)))


def container(lx=0.9, ly=0.5, lz=0.5):
    x, z = lx / 2, lz / 2
    v = [(-x, 0, -z), (x, 0, -z), (x, 0, z), (-x, 0, z),
         (-x, ly, -z), (x, ly, -z), (x, ly, z), (-x, ly, z)]
    # Counter-clockwise seen from inside the box (the free side).
    quads = [(0, 3, 2, 1),   # floor, normal +y
             (0, 1, 5, 4),   # back wall z = -z, normal +z
             (2, 3, 7, 6),   # front wall z = +z, normal -z
             (3, 0, 4, 7),   # left wall x = -x, normal +x
             (1, 2, 6, 5)]   # right wall x = +x, normal -x
    f = []
    for a, b, c, d in quads:
        f += [(a, b, c), (a, c, d)]
    return v, f


def torus(R=0.06, r=0.025, nu=24, nv=12):
    v = []
    for i in range(nu):
        u = 2 * math.pi * i / nu
        for j in range(nv):
            w = 2 * math.pi * j / nv
            v.append(((R + r * math.cos(w)) * math.cos(u), r * math.sin(w),
                      (R + r * math.cos(w)) * math.sin(u)))
    f = []
    for i in range(nu):
        for j in range(nv):
            a = i * nv + j
            b = ((i + 1) % nu) * nv + j
            c = ((i + 1) % nu) * nv + (j + 1) % nv
            d = i * nv + (j + 1) % nv
            f += [(a, d, c), (a, c, b)]
    return v, f


def ell(s=0.12, notch=0.06, depth=0.05):
    # The L in the xy plane, counter-clockwise, extruded along z.
    outline = [(0, 0), (s, 0), (s, s - notch), (s - notch, s - notch), (s - notch, s), (0, s)]
    n = len(outline)
    c = s / 2
    v = [(x - c, y - c, -depth / 2) for x, y in outline] + \
        [(x - c, y - c, depth / 2) for x, y in outline]
    f = []
    # Caps: the L split into triangles from the re-entrant corner (index 3), which sees every
    # other vertex.
    for i in (4, 5, 0, 1):
        j = (i + 1) % n
        f.append((3, j, i))          # back cap, normal -z
        f.append((n + 3, n + i, n + j))  # front cap, normal +z
    for i in range(n):
        j = (i + 1) % n
        f += [(i, j, n + j), (i, n + j, n + i)]
    return v, f


def clip(length=0.5, arm=0.04, gap=0.1, base=0.06, depth=0.1):
    # The U in the xy plane, counter-clockwise, the base at x in [0, base], the arms along +x;
    # the points where the arms meet the base are outline vertices too, so the caps split
    # into a fan over the base and two rectangles without T-junctions.
    top = 2 * arm + gap
    outline = [(0, 0), (base, 0), (length, 0), (length, arm), (base, arm), (base, arm + gap),
               (length, arm + gap), (length, top), (base, top), (0, top)]
    n = len(outline)
    v = [(x, y, 0.0) for x, y in outline] + [(x, y, depth) for x, y in outline]
    cap = [(0, 1, 4), (0, 4, 5), (0, 5, 8), (0, 8, 9),   # the base, a fan from (0, 0)
           (1, 2, 3), (1, 3, 4),                         # the lower arm
           (5, 6, 7), (5, 7, 8)]                         # the upper arm
    f = []
    for a, b, c in cap:
        f.append((a, c, b))                  # z = 0 cap, normal -z
        f.append((n + a, n + b, n + c))      # z = depth cap, normal +z
    for i in range(n):
        j = (i + 1) % n
        f += [(i, j, n + j), (i, n + j, n + i)]
    return v, f


def main():
    out = sys.argv[1] if len(sys.argv) > 1 else "examples/data"
    os.makedirs(out, exist_ok=True)
    write_obj(os.path.join(out, "container.obj"), *container(),
              "open-top box, 0.9 x 0.5 x 0.5 m, normals inward (sided = \"outside\")")
    write_obj(os.path.join(out, "torus.obj"), *torus(), "torus, R = 0.06 m, r = 0.025 m")
    write_obj(os.path.join(out, "ell.obj"), *ell(), "L-shaped prism, 0.12 x 0.12 x 0.05 m")
    write_obj(os.path.join(out, "clip.obj"), *clip(),
              "U-shaped prism: arms 0.5 x 0.04 m, 0.1 m apart, base 0.06 m, depth 0.1 m")


if __name__ == "__main__":
    main()
