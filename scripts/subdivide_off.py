#!/usr/bin/env python3
# usage: scripts/subdivide_off.py IN.off OUT.off  (docs/evaluation.md, FEM convergence)
# Split every triangle of an OFF surface in four at its edge midpoints (shared per edge):
# the same solid with a 4x finer surface, original vertices first and unchanged.
import sys
src, dst = sys.argv[1], sys.argv[2]
# Line-based: a COFF file (CGAL's data set) has colours after each vertex's coordinates
# and each face's indices; only the first 3 numbers of a vertex line are kept.
lines = [l.split('#')[0].split() for l in open(src)]
lines = [l for l in lines if l]
assert lines[0][0] in ('OFF', 'COFF'), f"{src}: not an OFF or COFF file"
head = lines[0][1:] if len(lines[0]) > 1 else lines[1]
body = lines[1:] if len(lines[0]) > 1 else lines[2:]
nv, nf = int(head[0]), int(head[1])
V = [tuple(float(x) for x in l[:3]) for l in body[:nv]]
F = []
for l in body[nv:nv + nf]:
    n = int(l[0]); F.append([int(x) for x in l[1:1 + n]])
mid = {}
def m(a, b):
    k = (min(a, b), max(a, b))
    if k not in mid:
        mid[k] = len(V); V.append(tuple((V[a][j]+V[b][j])/2 for j in range(3)))
    return mid[k]
out = []
for f in F:
    assert len(f) == 3
    a, b, c = f; ab, bc, ca = m(a, b), m(b, c), m(c, a)
    out += [[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]
with open(dst, 'w') as w:
    w.write(f"OFF\n{len(V)} {len(out)} 0\n")
    for p in V: w.write("%r %r %r\n" % p)
    for t in out: w.write("3 %d %d %d\n" % tuple(t))
