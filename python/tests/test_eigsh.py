"""freeform.eigsh on duck-typed operators: numpy-only operator objects (matmat, matvec, a
tocoo() sparse look-alike) give the analytic eigenvalues of the path-graph Laplacian; a
callback that raises stops the solve with its own exception; bad shapes are refused; scipy
objects work when scipy is installed."""

import numpy as np
import pytest

import freeform

N = 60
NEV = 6


def laplacian():
    """Path-graph Laplacian on N nodes (Neumann, constant null vector), dense."""
    a = 2.0 * np.eye(N) - np.eye(N, k=1) - np.eye(N, k=-1)
    a[0, 0] = a[-1, -1] = 1.0
    return a


def exact():
    # Eigenvalues 2 - 2 cos(pi k / N), k = 0 .. N - 1, with identity mass.
    return 2.0 - 2.0 * np.cos(np.pi * np.arange(NEV) / N)


class MatMat:
    def __init__(self, a, diagonal=True):
        self.a = a
        self.shape = a.shape
        self.calls = 0
        if diagonal:
            self.diagonal = lambda: np.diag(self.a).copy()

    def matmat(self, x):
        self.calls += 1
        return self.a @ x


class MatVec:
    def __init__(self, a):
        self.a = a
        self.shape = a.shape

    def matvec(self, x):
        return self.a @ x


class Coo:
    """Looks like scipy.sparse.coo_matrix: row, col, data."""

    def __init__(self, a):
        self.row, self.col = np.nonzero(a)
        self.data = a[self.row, self.col]


class SparseLike:
    def __init__(self, a):
        self.a = a
        self.shape = a.shape

    def tocoo(self):
        return Coo(self.a)


def check(values, vectors, a):
    # Residual tol 1e-8 bounds the eigenvalue errors far below 1e-8 of lambda_max (~4).
    assert values.shape == (NEV,) and vectors.shape == (N, NEV)
    np.testing.assert_allclose(values, exact(), rtol=0, atol=1e-8)
    # M-orthonormal (M = I) and eigenvectors.
    np.testing.assert_allclose(vectors.T @ vectors, np.eye(NEV), atol=1e-9)
    np.testing.assert_allclose(a @ vectors, vectors * values, atol=1e-6)


@pytest.mark.parametrize("kind", ["matmat", "matvec", "tocoo", "matmat-no-diagonal"])
def test_duck_typed_operators_give_the_analytic_spectrum(kind):
    a = laplacian()
    make = {
        "matmat": MatMat,
        "matvec": MatVec,
        "tocoo": SparseLike,
        "matmat-no-diagonal": lambda a: MatMat(a, diagonal=False),
    }[kind]
    values, vectors = freeform.eigsh(make(a), make(np.eye(N)), NEV, max_iter=3000)
    check(values, vectors, a)


def test_a_preconditioner_object_is_used():
    a = laplacian()
    pre = MatMat(np.linalg.inv(a + 1e-3 * np.eye(N)), diagonal=False)
    values, vectors = freeform.eigsh(MatMat(a), MatMat(np.eye(N)), NEV, preconditioner=pre)
    check(values, vectors, a)
    assert pre.calls > 0


def test_a_callback_that_raises_stops_the_solve_with_its_exception():
    class Boom(MatMat):
        def matmat(self, x):
            raise ZeroDivisionError("device lost")

    with pytest.raises(ZeroDivisionError, match="device lost"):
        freeform.eigsh(Boom(laplacian()), MatMat(np.eye(N)), NEV)


def test_bad_operators_are_refused():
    class WrongShape(MatMat):
        def matmat(self, x):
            return (self.a @ x)[:-1]

    with pytest.raises(freeform.InvalidInputError, match="returned shape"):
        freeform.eigsh(WrongShape(laplacian()), MatMat(np.eye(N)), NEV)

    class Nan(MatMat):
        def matmat(self, x):
            y = self.a @ x
            y[3, 0] = np.nan
            return y

    with pytest.raises(freeform.InvalidInputError, match="NaN"):
        freeform.eigsh(Nan(laplacian()), MatMat(np.eye(N)), NEV)
    with pytest.raises(freeform.InvalidInputError, match="square"):
        freeform.eigsh(MatMat(np.ones((N, N + 1))), MatMat(np.eye(N)), NEV)
    with pytest.raises(freeform.InvalidInputError, match="K x K"):
        freeform.eigsh(MatMat(laplacian()), MatMat(np.eye(N + 1)), NEV)
    with pytest.raises(freeform.InvalidInputError, match="matmat or"):
        freeform.eigsh(object(), MatMat(np.eye(N)), NEV)
    skew = laplacian()
    skew[0, 1] += 0.5
    with pytest.raises(freeform.InvalidInputError, match="not symmetric"):
        freeform.eigsh(MatMat(skew), MatMat(np.eye(N)), NEV, check_symmetry=True)
    with pytest.raises(freeform.InvalidInputError, match="positive definite"):
        freeform.eigsh(MatMat(laplacian()), MatMat(-np.eye(N)), NEV)
    # Sparse input whose indices the native 32-bit matrix cannot hold: negative or fractional
    # (a negative index used to be cast to row 0 silently).
    for bad in (-1.0, 2.5):
        sparse_like = SparseLike(laplacian())
        coo = Coo(laplacian())
        coo.row = coo.row.astype(float)
        coo.row[0] = bad
        sparse_like.tocoo = lambda coo=coo: coo
        with pytest.raises(freeform.InvalidInputError, match="whole numbers"):
            freeform.eigsh(sparse_like, MatMat(np.eye(N)), NEV)


def test_scipy_sparse_and_linear_operators():
    sparse = pytest.importorskip("scipy.sparse")
    linalg = pytest.importorskip("scipy.sparse.linalg")
    a = laplacian()
    values, vectors = freeform.eigsh(sparse.csr_matrix(a), sparse.identity(N, format="csr"), NEV)
    check(values, vectors, a)
    op = linalg.LinearOperator((N, N), matvec=lambda x: a @ x, matmat=lambda x: a @ x)
    values, vectors = freeform.eigsh(op, sparse.identity(N), NEV, max_iter=3000)
    check(values, vectors, a)
