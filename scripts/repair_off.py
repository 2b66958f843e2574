#!/usr/bin/env python3
# usage: scripts/repair_off.py IN.off OUT.off   (docs/evaluation.md)
# Repair a triangle surface that the evaluation's checks refused (open, or with intersecting
# faces) by MeshFix (Attene's method, through pyvista's pymeshfix): it removes
# self-intersections and degenerate faces and fills holes, and keeps one closed component.
# Writes OUT.off (plain OFF) and prints "components_in faces_in faces_out". Whether the
# result is a valid solid (closed, manifold, no intersecting faces) is checked by the caller
# (scripts/cgal_shapes.sh), like any input.
import sys

import numpy as np
import pymeshfix


def read_off(path):
    """Vertices (n x 3) and triangles (m x 3) of an OFF file (OFF, NOFF, COFF: a vertex line's
    first three numbers are its position); polygons are fanned."""
    with open(path) as f:
        lines = [ln.split("#", 1)[0].split() for ln in f]
    lines = [ln for ln in lines if ln]
    if not lines or not lines[0][0].endswith("OFF"):
        raise SystemExit(f"{path}: not an OFF file")
    head = lines[0][1:] or lines[1]
    at = 1 if lines[0][1:] else 2
    nv, nf = int(head[0]), int(head[1])
    v = np.array([ln[:3] for ln in lines[at : at + nv]], dtype=float)
    tris = []
    for ln in lines[at + nv : at + nv + nf]:
        poly = [int(w) for w in ln[1 : 1 + int(ln[0])]]
        tris += [(poly[0], poly[i], poly[i + 1]) for i in range(1, len(poly) - 1)]
    return v, np.array(tris, dtype=np.int64)


def components(nv, f):
    """Number of edge-connected components of the faces (union-find over vertices)."""
    parent = list(range(nv))

    def root(i):
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b, c in f:
        for x, y in ((a, b), (b, c)):
            rx, ry = root(x), root(y)
            if rx != ry:
                parent[rx] = ry
    return len({root(i) for i in np.unique(f)})


src, dst = sys.argv[1], sys.argv[2]
v, f = read_off(src)
fix = pymeshfix.MeshFix(v, f)
# MeshFix works on one component: it keeps the largest, so a multi-part input loses its
# smaller parts (reported through the component count).
fix.repair(joincomp=False, remove_smallest_components=True)
out_v, out_f = np.asarray(fix.points), np.asarray(fix.faces)
if len(out_f) == 0:
    raise SystemExit(f"{src}: MeshFix returned an empty surface")
with open(dst, "w") as out:
    out.write(f"OFF\n{len(out_v)} {len(out_f)} 0\n")
    out.writelines(f"{x:.17g} {y:.17g} {z:.17g}\n" for x, y, z in out_v)
    out.writelines(f"3 {a} {b} {c}\n" for a, b, c in out_f)
print(components(len(v), f), len(f), len(out_f))
