#!/usr/bin/env python3
"""Write a synthetic CT-like voxel phantom for freeform's voxel-image materials (numpy only).

The object is an elongated ellipsoidal body (aspect 2:1:1) with nested shells and inclusions:

    label 1  soft tissue       the outer ellipsoid                      E = soft
    label 2  cortical shell    a stiff ellipsoidal shell inside it      E = soft * contrast
    label 3  marrow            the core inside the shell                E = soft * sqrt(contrast)
    label 4  stiff inclusions  spheres in the soft tissue               E = soft * contrast
    label 5  soft inclusions   spheres in the marrow                    E = soft * 3

so the modulus contrast (largest / smallest) is exactly `contrast` (default 1e4). Voxels are
`n x n/2 x n/2` (n = 340 gives ~1e7), spacing `length / n`, the image centred on the origin
along y and z and starting at x = 0. Written as NIfTI-1 (`.nii`, or gzip-compressed `.nii.gz`;
lengths in millimetres, sform set) or `.npy` (axis 0 = x; spacing and origin then go in the
scene), holding either the labels (uint8) or Young's modulus per voxel (float32, Pa; `--kind
moduli`, with `--noise` multiplicative CT-like noise, clipped to the label range).

Examples:
    python3 scripts/ct_phantom.py --n 48 --out examples/data/ct_phantom_48.nii.gz
    python3 scripts/ct_phantom.py --n 340 --kind moduli --out /tmp/phantom_1e7.nii
"""
import argparse
import gzip
import struct

import numpy as np


def phantom_labels(n, seed):
    """Labels (uint8, shape (n, n//2, n//2), axis 0 = x) in unit coordinates."""
    nx, ny, nz = n, max(n // 2, 1), max(n // 2, 1)
    # Voxel centres in [0, 2] x [-0.5, 0.5]^2 (units of the body's width).
    x = (np.arange(nx) + 0.5) / nx * 2.0
    y = (np.arange(ny) + 0.5) / ny - 0.5
    z = (np.arange(nz) + 0.5) / nz - 0.5
    X, Y, Z = np.meshgrid(x, y, z, indexing="ij")

    def ellipsoid(c, r):
        return ((X - c[0]) / r[0]) ** 2 + ((Y - c[1]) / r[1]) ** 2 + ((Z - c[2]) / r[2]) ** 2

    labels = np.zeros((nx, ny, nz), dtype=np.uint8)
    body = ellipsoid((1.0, 0.0, 0.0), (0.98, 0.48, 0.48))
    shell = ellipsoid((1.0, 0.0, 0.0), (0.75, 0.3, 0.3))
    core = ellipsoid((1.0, 0.0, 0.0), (0.68, 0.22, 0.22))
    labels[body <= 1.0] = 1
    labels[shell <= 1.0] = 2
    labels[core <= 1.0] = 3
    rng = np.random.default_rng(seed)
    # Stiff inclusions in the soft tissue (outside the shell), soft ones in the marrow.
    # The same seed draws the same centres at every resolution; a ball that would touch
    # anything but soft tissue is skipped.
    placed = 0
    for _ in range(200):
        c = (rng.uniform(0.2, 1.8), rng.uniform(-0.35, 0.35), rng.uniform(-0.35, 0.35))
        r = rng.uniform(0.05, 0.09)
        ball = ellipsoid(c, (r, r, r)) <= 1.0
        if ball.any() and np.all(labels[ball] == 1):
            labels[ball] = 4
            placed += 1
        if placed == 6:
            break
    for c in [(0.7, 0.05, 0.0), (1.3, -0.05, 0.05)]:
        r = 0.08
        labels[(ellipsoid(c, (r, r, r)) <= 1.0) & (labels == 3)] = 5
    return labels


def moduli_of(labels, soft, contrast, noise, seed):
    table = np.array([0.0, soft, soft * contrast, soft * np.sqrt(contrast), soft * contrast,
                      soft * 3.0])
    e = table[labels]
    if noise > 0:
        rng = np.random.default_rng(seed + 1)
        e = e * (1.0 + noise * rng.standard_normal(e.shape))
        # Keep every voxel inside [soft, soft * contrast] (contrast stays exact) and > 0.
        e = np.clip(e, soft, soft * contrast)
        e[labels == 0] = 0.0
    return e.astype(np.float32)


def nifti_bytes(data, spacing_mm, origin_mm):
    """A single-file NIfTI-1 image (348-byte header, 4-byte extension flag, data)."""
    codes = {np.dtype(np.uint8): (2, 8), np.dtype(np.float32): (16, 32)}
    datatype, bitpix = codes[data.dtype]
    h = bytearray(348)
    struct.pack_into("<i", h, 0, 348)
    dims = [3, *data.shape, 1, 1, 1, 1]
    struct.pack_into("<8h", h, 40, *dims)
    struct.pack_into("<hh", h, 70, datatype, bitpix)
    struct.pack_into("<8f", h, 76, 1.0, *spacing_mm, 0.0, 0.0, 0.0, 0.0)
    struct.pack_into("<f", h, 108, 352.0)  # vox_offset
    struct.pack_into("<ff", h, 112, 1.0, 0.0)  # scl_slope, scl_inter
    h[123] = 2  # xyzt_units: millimetres
    struct.pack_into("<hh", h, 252, 1, 1)  # qform_code, sform_code: scanner
    struct.pack_into("<6f", h, 256, 0.0, 0.0, 0.0, *origin_mm)  # identity quaternion
    sx, sy, sz = spacing_mm
    ox, oy, oz = origin_mm
    struct.pack_into("<4f", h, 280, sx, 0.0, 0.0, ox)
    struct.pack_into("<4f", h, 296, 0.0, sy, 0.0, oy)
    struct.pack_into("<4f", h, 312, 0.0, 0.0, sz, oz)
    h[344:348] = b"n+1\x00"
    # NIfTI stores x fastest: Fortran order of the (x, y, z) array.
    return bytes(h) + b"\x00" * 4 + np.asfortranarray(data).tobytes(order="F")


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--n", type=int, default=48, help="voxels along x (y, z get n/2); 340 ~ 1e7")
    p.add_argument("--length", type=float, default=0.2, help="length along x, metres")
    p.add_argument("--kind", choices=["labels", "moduli"], default="labels")
    p.add_argument("--soft", type=float, default=2e4, help="softest modulus, Pa")
    p.add_argument("--contrast", type=float, default=1e4, help="largest / smallest modulus")
    p.add_argument("--noise", type=float, default=0.0, help="relative noise of moduli")
    p.add_argument("--seed", type=int, default=7)
    p.add_argument("--out", required=True, help=".nii, .nii.gz or .npy")
    a = p.parse_args()
    labels = phantom_labels(a.n, a.seed)
    data = labels if a.kind == "labels" else moduli_of(labels, a.soft, a.contrast, a.noise,
                                                       a.seed)
    h = a.length / a.n
    # Voxel [0, 0, 0]'s centre: x from h/2, y and z centred on 0.
    origin = (h / 2, -(labels.shape[1] - 1) * h / 2, -(labels.shape[2] - 1) * h / 2)
    if a.out.endswith(".npy"):
        np.save(a.out, data)
        print(f"spacing = [{h!r}, {h!r}, {h!r}]\norigin = [{origin[0]!r}, {origin[1]!r}, "
              f"{origin[2]!r}]")
    else:
        raw = nifti_bytes(data, [h * 1e3] * 3, [o * 1e3 for o in origin])
        if a.out.endswith(".gz"):
            raw = gzip.compress(raw, compresslevel=9, mtime=0)
        with open(a.out, "wb") as f:
            f.write(raw)
    counts = np.bincount(labels.ravel(), minlength=6)
    print(f"{a.out}: {labels.shape} voxels ({labels.size:,}), spacing {h:.6g} m, "
          f"voxels per label {counts.tolist()}")


if __name__ == "__main__":
    main()
