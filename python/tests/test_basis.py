"""The basis from Python against the command line, RKPM identities, and bad input."""

import json
import signal
import subprocess
import sys
import time

import numpy as np
import pytest

import freeform as ff

SMALL = dict(kernels=120, modes=6, points=3000)


def test_eigenvalues_equal_the_cli_on_the_same_input(freeform_bin, tmp_path):
    out = tmp_path / "cli.npz"
    run = subprocess.run(
        [freeform_bin, "modes", "box:2,1,1", "--kernels", "120", "--modes", "6",
         "--points", "3000", "--out", str(out), "--json"],
        capture_output=True, text=True, check=True,
    )
    cli = json.loads(run.stdout)
    basis = ff.Basis.from_shape("box:2,1,1", **SMALL)
    # The same library code on the same input: only the order of parallel sums could
    # differ between the two processes, which moves eigenvalues by rounding (~1e-15
    # relative); 1e-10 leaves room for that and catches any real difference.
    np.testing.assert_allclose(basis.eigenvalues, cli["eigenvalues"], rtol=1e-10, atol=1e-6)
    loaded = ff.Basis.load(out)
    np.testing.assert_allclose(loaded.eigenvalues, basis.eigenvalues, rtol=1e-10, atol=1e-6)
    assert loaded.coefficients.shape == (120, 7)
    assert loaded.metadata["shape"] == "box:2,1,1"


def test_aware_basis_equals_the_cli_and_pins_its_region(freeform_bin, tmp_path):
    region = "halfspace:0.6,0,0,-1,0,0"
    run = subprocess.run(
        [freeform_bin, "modes", "box:2,1,1", "--kernels", "120", "--modes", "6",
         "--points", "3000", "--region=" + region, "--out", str(tmp_path / "a.npz"), "--json"],
        capture_output=True, text=True, check=True,
    )
    cli = json.loads(run.stdout)
    basis = ff.Basis.from_shape("box:2,1,1", regions=[region], **SMALL)
    # Same code, same input: rounding-level differences only (see the test above).
    np.testing.assert_allclose(basis.eigenvalues, cli["eigenvalues"], rtol=1e-10, atol=1e-6)
    assert len(cli["boundaries"]) == 1
    # One region: its lift is the constant (exactly 1 on every kernel), and the free modes
    # are exactly 0 on the kernels centred in the region.
    c = basis.coefficients
    assert np.all(c[:, 0] == 1.0)
    pinned = basis.centers[:, 0] <= 0.6
    assert pinned.sum() == cli["boundaries"][0]["kernels"] > 0
    assert np.all(c[pinned, 1:] == 0.0)


def test_weights_reproduce_constants_and_linear_fields():
    basis = ff.Basis.from_shape("box:2,1,1", **SMALL)
    rng = np.random.default_rng(1)
    x = rng.random((200, 3)) * [1.8, 0.8, 0.8] + 0.1
    # RKPM with linear completeness: sum_k phi_k(x) = 1 and sum_k phi_k(x) p_k = x, to
    # the moment matrices' rounding (condition numbers ~1e3 here, so ~1e-13).
    ones = basis.evaluate(x, np.ones((basis.kernels, 1)))
    np.testing.assert_allclose(ones[:, 0], 1.0, atol=1e-11)
    np.testing.assert_allclose(basis.evaluate(x, basis.centers), x, atol=1e-11)
    # The constant mode is the constant 1/sqrt(V) (M-normalized), V = 2 m^3.
    w = basis.weights(x)
    assert w.shape == (200, 7)
    np.testing.assert_allclose(np.abs(w[:, 0]), 1 / np.sqrt(2.0), rtol=1e-9)
    # The gradients are those of the same field: a central difference agrees to its
    # truncation error (h^2 times third derivatives of a smooth cubic-spline field).
    w, g = basis.weights(x[:5], gradients=True)
    assert g.shape == (5, 7, 3)
    h = 1e-5
    for d in range(3):
        e = np.zeros(3)
        e[d] = h
        fd = (basis.weights(x[:5] + e) - basis.weights(x[:5] - e)) / (2 * h)
        np.testing.assert_allclose(g[:, :, d], fd, atol=1e-6 * np.abs(g).max())


def test_points_in_any_dtype_and_layout_give_the_same_basis():
    rng = np.random.default_rng(0)
    pts = rng.random((3000, 3)) * [2.0, 1.0, 1.0]
    ref = ff.Basis.from_points(pts, 1e6, 0.4, 1000.0, kernels=80, modes=4)
    vol = np.full(3000, 2.0 / 3000)
    a = ff.Basis.from_points(pts, 1e6, 0.4, 1000.0, volumes=vol, kernels=80, modes=4)
    b = ff.Basis.from_points(np.asfortranarray(pts), np.full(3000, 1e6, dtype=np.float32),
                             0.4, np.full(3000, 1000, dtype=np.int64), volumes=list(vol),
                             kernels=80, modes=4)
    np.testing.assert_array_equal(a.eigenvalues, b.eigenvalues)
    # The estimated volumes (voxel fill of the cloud) are not the exact ones: the
    # eigenvalues agree to a few per cent, not exactly.
    np.testing.assert_allclose(ref.eigenvalues[1:], a.eigenvalues[1:], rtol=0.1)
    # float32 points are the float64 points rounded once.
    c = ff.Basis.from_points(pts.astype(np.float32), 1e6, 0.4, 1000.0, volumes=vol,
                             kernels=80, modes=4)
    np.testing.assert_allclose(c.eigenvalues, a.eigenvalues, rtol=1e-4, atol=1e-3)


def test_a_stiff_half_raises_the_eigenvalues():
    rng = np.random.default_rng(0)
    pts = rng.random((3000, 3)) * [2.0, 1.0, 1.0]
    vol = np.full(3000, 2.0 / 3000)
    soft = ff.Basis.from_points(pts, 1e6, volumes=vol, kernels=80, modes=4)
    youngs = np.where(pts[:, 0] > 1.0, 1e8, 1e6)
    mixed = ff.Basis.from_points(pts, youngs, volumes=vol, kernels=80, modes=4)
    assert np.all(mixed.eigenvalues[1:] > soft.eigenvalues[1:])


def test_save_and_load_round_trip(tmp_path):
    basis = ff.Basis.from_shape("sphere:0.5", kernels=60, modes=4, points=2000)
    path = tmp_path / "b.npz"
    basis.save(path)
    back = ff.Basis.load(path)
    np.testing.assert_array_equal(back.eigenvalues, basis.eigenvalues)
    np.testing.assert_array_equal(back.coefficients, basis.coefficients)
    np.testing.assert_array_equal(back.centers, basis.centers)
    np.testing.assert_array_equal(back.radii, basis.radii)
    assert back.kernel == "cubic" and back.modes == 4 and back.kernels == 60
    report = basis.report
    assert report["kernels"] == 60 and len(report["eigenvalues"]) == 5
    assert report["max_relative_residual"] <= 1e-8


@pytest.mark.parametrize(
    "call, match",
    [
        (lambda: ff.Basis.from_points(np.zeros((10, 2)), 1e6), "expected N x 3"),
        (lambda: ff.Basis.from_points([[0, 0, np.nan]] * 50, 1e6), "row 0 is not finite"),
        (lambda: ff.Basis.from_points(np.zeros((50, 3)), np.ones(7)), "expected 50 values"),
        (lambda: ff.Basis.from_points(np.random.rand(500, 3), -1.0, kernels=20, modes=2), "youngs"),
        (lambda: ff.Basis.from_points("points", 1e6), "expected an N x 3 array"),
        (lambda: ff.Basis.from_points(np.zeros((50, 3), dtype=complex), 1e6), "complex"),
        (lambda: ff.Basis.from_shape("box:2,1,1", kernals=10), "unknown option `kernals`"),
        (lambda: ff.Basis.from_shape("box:2,1,1", kernels="many"), "kernels"),
        (lambda: ff.Basis.from_shape("box:2,1,1", kernels=10, modes=20), "modes"),
        (lambda: ff.Basis.from_shape("box:2,1,1", points=100, spacing=0.1), "not both"),
        (lambda: ff.Basis.from_shape("cone:1"), "unknown shape"),
        (lambda: ff.Basis.from_shape("box:2,1,1", eigensolver="magic"), "magic"),
        (lambda: ff.Basis.from_shape("box:2,1,1", eigensolver="lobpcg:gaurd=12"),
         "unknown field `gaurd`"),
        # The pip build has no SLEPc: a request for it is invalid input, not a failed solve.
        (lambda: ff.Basis.from_shape("box:2,1,1", eigensolver="slepc", **SMALL), "without SLEPc"),
        (lambda: ff.Basis.from_shape("box:2,1,1", regions=["halfspace:0.5,0,0"]), "need 6"),
        (lambda: ff.Basis.from_shape("box:2,1,1", regions=["sphere:9,9,9,0.1"], **SMALL),
         "no integration point"),
    ],
)
def test_bad_input_raises_a_clear_error(call, match):
    with pytest.raises(ff.InvalidInputError, match=match):
        call()


def test_lobpcg_settings_in_the_solver_string():
    # More guard vectors change how LOBPCG gets there, not where: the same eigenvalues.
    plain = ff.Basis.from_shape("box:2,1,1", **SMALL)
    guarded = ff.Basis.from_shape("box:2,1,1", eigensolver="lobpcg:guard=12", **SMALL)
    a, b = plain.report["eigenvalues"], guarded.report["eigenvalues"]
    # Both converged to a relative residual of 1e-8, so each eigenvalue to ~1e-8 relative.
    assert np.allclose(a, b, rtol=1e-7, atol=0.0)
    assert "12 guard" in " ".join(guarded.report["eigen"]["notes"])


def test_evaluate_refuses_coefficients_that_are_not_finite():
    basis = ff.Basis.from_shape("box:2,1,1", **SMALL)
    c = np.ones((basis.kernels, 2))
    c[3, 1] = np.nan
    with pytest.raises(ff.InvalidInputError, match=r"entry \(3, 1\) is not finite"):
        basis.evaluate(np.full((4, 3), 0.5), c)
    c[3, 1] = np.inf
    with pytest.raises(ff.InvalidInputError, match="not finite"):
        basis.evaluate(np.full((4, 3), 0.5), c)


def test_an_uncovered_point_past_the_first_chunk_is_named_by_its_index():
    # weights() works in chunks of 100,000 points (for Ctrl-C); the error is the whole
    # array's: the index counts from its start.
    basis = ff.Basis.from_shape("box:2,1,1", **SMALL)
    x = np.full((100_005, 3), 0.5)
    x[100_003] = [50.0, 50.0, 50.0]
    with pytest.raises(ff.CoverageError, match=r"1 point\(s\).*worst at index 100003"):
        basis.weights(x)


def test_bad_files_and_uncovered_points(tmp_path):
    with pytest.raises(ff.FreeformIOError, match="missing.npz"):
        ff.Basis.load(tmp_path / "missing.npz")
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"not a zip")
    with pytest.raises(ff.FreeformIOError):
        ff.Basis.load(junk)
    basis = ff.Basis.from_shape("box:1,1,1", kernels=40, modes=3, points=2000)
    with pytest.raises(ff.CoverageError, match="not covered"):
        basis.weights([[10.0, 0.0, 0.0]])
    # Every freeform error is also the matching built-in kind.
    assert issubclass(ff.InvalidInputError, ValueError)
    assert issubclass(ff.FreeformIOError, OSError)
    assert issubclass(ff.CoverageError, ff.FreeformError)


CTRL_C = """
import signal, sys, time, freeform
# A child of a background job inherits SIGINT ignored (and Python then installs no handler):
# the test needs Python's own Ctrl-C handling whatever launched it.
signal.signal(signal.SIGINT, signal.default_int_handler)
t = time.time()
try:
    freeform.Basis.from_shape("box:2,1,1", kernels=20000, modes=32, progress=True)
    print("finished", time.time() - t)
except KeyboardInterrupt:
    print("interrupted", time.time() - t)
"""


def test_ctrl_c_interrupts_a_long_build():
    p = subprocess.Popen([sys.executable, "-c", CTRL_C], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, text=True)
    # Wait for the build to be under way (its progress lines on stderr), then interrupt.
    for line in p.stderr:
        if "centers done" in line:
            break
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert out.startswith("interrupted"), out + err
