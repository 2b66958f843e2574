#!/usr/bin/env python3
"""Time and memory per rank of the distributed precompute on a cluster (docs/slepc.md,
"A model for clusters").

    python3 scripts/cluster_model.py            # the table in docs/slepc.md
    python3 scripts/cluster_model.py --alpha 5e-6 --kernels 1e6 1e7

The per-kernel costs are the ones measured on this 2-core VM (docs/slepc.md, "Scaling");
the network figures are assumptions for an InfiniBand-class cluster (change them with the
flags). Each stage:

- kernel placement (exact distributed FPS): local work K / P, plus one small collective per
  kernel (all-gather up to 16 ranks, maximum + broadcast past that), each alpha * log2(P):
  latency bound, it does not shrink with P;
- rows: K / P, times (1 + the point halo): the points a rank evaluates beyond its own, those
  its kernels' supports reach past its part, a shell around a part of K / P kernels:
  c (K / P)^(-1/3), c fitted to the 3.5 % measured at K / P = 50,000;
- eigensolve (the SLEPc default, LOBPCG + GAMG): iterations (flat in P, measured) x [local
  work K / P + reductions x alpha log2 P + V-cycles x levels x neighbour exchanges (alpha +
  ghost bytes / beta)], the ghost entries of a product being the kernels within w kernel
  spacings of the part: 6 w (K / P)^(-1/3) of K / P;
- memory: a fixed part (process, MPI, PETSc), the arrays every rank holds per kernel (centres,
  radii, FPS choices), and the per-kernel share, with its point halo.
"""
import argparse
import math

# Measured (docs/slepc.md, "Scaling"; K = 100,000 unless said otherwise).
FPS_S_PER_KERNEL = 3.1e-5  # centres stage on one rank / K (3.1 s at K = 100,000)
ROWS_S_PER_KERNEL = 2.5e-4  # neighbours + shape functions + assembly on one core / K (25 s)
SOLVE_S_PER_KERNEL_ITER = 1.96e-4  # SLEPc LOBPCG + GAMG, one rank: 510.6 s / 26 / K
ITERATIONS = 26  # the default at K = 100,000 (flat in P; docs/slepc.md "Scaling")
REDUCTIONS_PER_ITER = 190  # BVDotVec + BVOrthogonalizeV calls per iteration (-log_view)
VCYCLES_PER_ITER = 142  # KSPSolve calls per iteration (-log_view): 44 columns x ~3
BLOCK = 44  # vectors per LOBPCG block (m + 1 = 33 pairs + guard vectors)
FIXED_BYTES = 0.095e9  # memory fit a + b K / P at K = 100,000 and 300,000 (2026-12-05)
BYTES_PER_KERNEL_SHARE = 15e3  # b of that fit (14.8 and 15.1 kB)
BYTES_PER_KERNEL_EVERY_RANK = 120  # centres, radii, FPS choices (memory.rs)
POINT_HALO = 1.29  # evaluated / owned points - 1 = 0.035 at K / P = 50,000 (P = 2): 1.29 x 50,000^(-1/3)
GHOST_WIDTH = 2.0  # kernel spacings a row's non-zeros reach (supports of radius ~2 spacings)


def levels(kernels):
    """GAMG levels: about one per factor 10 of unknowns down to ~100 (measured 3 at 1e5)."""
    return max(2, math.ceil(math.log10(kernels / 100.0)))


def model(k, p, alpha, beta):
    own = k / p
    halo = min(POINT_HALO * own ** (-1.0 / 3.0), 26.0)
    ghosts = min(6.0 * GHOST_WIDTH * own ** (-1.0 / 3.0), 26.0)
    hop = alpha * max(1.0, math.log2(p)) if p > 1 else 0.0
    per_kernel_collectives = 1 if p <= 16 else 2
    fps = FPS_S_PER_KERNEL * own + k * per_kernel_collectives * hop
    rows = ROWS_S_PER_KERNEL * own * (1 + halo)
    exchange = (alpha + 8.0 * ghosts * own / beta) if p > 1 else 0.0
    per_iter = (
        SOLVE_S_PER_KERNEL_ITER * own
        + REDUCTIONS_PER_ITER * hop
        + VCYCLES_PER_ITER * levels(k) * 4 * exchange
    )
    solve = ITERATIONS * per_iter
    memory = (
        FIXED_BYTES
        + BYTES_PER_KERNEL_EVERY_RANK * k
        + BYTES_PER_KERNEL_SHARE * own * (1 + halo)
    )
    return fps, rows, solve, memory, ghosts


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--kernels", type=float, nargs="+", default=[1e6, 1e7])
    ap.add_argument("--ranks", type=int, nargs="+", default=[16, 64, 256, 1024])
    ap.add_argument("--alpha", type=float, default=2e-6, help="latency per hop, s")
    ap.add_argument("--beta", type=float, default=10e9, help="bandwidth per rank, bytes/s")
    a = ap.parse_args()
    print("| K | P | FPS s | rows s | eigensolve s | total s | memory per rank GB | ghosts / own |")
    print("|---|---|---|---|---|---|---|---|")
    for k in a.kernels:
        for p in a.ranks:
            fps, rows, solve, mem, ghosts = model(k, p, a.alpha, a.beta)
            print(
                f"| {k:,.0f} | {p} | {fps:.1f} | {rows:.1f} | {solve:.1f} | "
                f"{fps + rows + solve:.1f} | {mem / 1e9:.2f} | {ghosts:.2f} |"
            )


if __name__ == "__main__":
    main()
