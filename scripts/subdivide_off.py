#!/usr/bin/env python3
# usage: scripts/subdivide_off.py IN.off OUT.off  (docs/evaluation.md, FEM convergence)
# Split every triangle of an OFF surface in four at its edge midpoints (shared per edge):
# the same solid with a 4x finer surface, original vertices first and unchanged.
import sys
src, dst = sys.argv[1], sys.argv[2]
tok = [l.split('#')[0].split() for l in open(src)]
tok = [t for l in tok for t in l]
assert tok[0] == 'OFF'
nv, nf = int(tok[1]), int(tok[2]); i = 4
V = [tuple(float(x) for x in tok[i+3*k:i+3*k+3]) for k in range(nv)]; i += 3*nv
F = []
for _ in range(nf):
    n = int(tok[i]); F.append([int(x) for x in tok[i+1:i+1+n]]); i += 1+n
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
