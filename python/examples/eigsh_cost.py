"""What a Python operator costs freeform.eigsh: the 7-point Neumann Laplacian of an n^3 grid
(scipy.sparse), solved once assembled (tocoo: H and M never call Python) and once through
Python objects whose matmat calls scipy's product; both with the same Python Jacobi
preconditioner object, so both take the same iterations and the difference is what the Python
H and M cost. Prints the calls, the time inside scipy's products, and the binding's share.

    python python/examples/eigsh_cost.py [n] [nev]
"""

import sys
import time

import numpy as np
import scipy.sparse as sp

import freeform

n = int(sys.argv[1]) if len(sys.argv) > 1 else 27
nev = int(sys.argv[2]) if len(sys.argv) > 2 else 17
path = sp.diags([-np.ones(n - 1), np.r_[1.0, 2.0 * np.ones(n - 2), 1.0], -np.ones(n - 1)], [-1, 0, 1])
eye = sp.identity(n)
a = (sp.kron(sp.kron(path, eye), eye) + sp.kron(sp.kron(eye, path), eye) + sp.kron(sp.kron(eye, eye), path)).tocsr()
m = sp.identity(n**3, format="csr")


class Timed:
    def __init__(self, a):
        self.a, self.shape = a, a.shape
        self.calls, self.columns, self.seconds = 0, 0, 0.0

    def matmat(self, x):
        t = time.perf_counter()
        y = self.a @ x
        self.seconds += time.perf_counter() - t
        self.calls += 1
        self.columns += x.shape[1]
        return y

    def diagonal(self):
        return self.a.diagonal()


class Jacobi:
    def __init__(self, d):
        self.inv, self.shape = 1.0 / d, (d.size, d.size)

    def matmat(self, r):
        return r * self.inv[:, None]


pre = Jacobi(a.diagonal())
t = time.perf_counter()
v0, _ = freeform.eigsh(a, m, nev, preconditioner=pre, max_iter=5000)
t_assembled = time.perf_counter() - t
h_op, m_op = Timed(a), Timed(m)
t = time.perf_counter()
v1, _ = freeform.eigsh(h_op, m_op, nev, preconditioner=pre, max_iter=5000)
t_python = time.perf_counter() - t
calls = h_op.calls + m_op.calls
inside = h_op.seconds + m_op.seconds
binding = t_python - t_assembled - inside
print(f"K = {n**3}, nev = {nev}")
print(f"assembled H, M (tocoo), Python Jacobi: {t_assembled:.2f} s")
print(
    f"Python H, M (matmat), Python Jacobi: {t_python:.2f} s; {calls} H/M calls, "
    f"{h_op.columns + m_op.columns} columns, {inside:.2f} s inside scipy's products"
)
print(
    f"binding cost of the Python H and M (total - assembled - scipy's products): {binding:.2f} s, "
    f"{1e6 * binding / calls:.0f} us per call, {1e9 * binding / ((h_op.columns + m_op.columns) * n**3):.1f} ns per entry"
)
print(f"largest eigenvalue difference: {np.max(np.abs(v0 - v1)):.2e}")
