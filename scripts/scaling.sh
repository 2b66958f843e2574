#!/bin/bash
# Memory per MPI rank against the one-process native run (docs/slepc.md "Scaling").
#
#   KERNELS="100000 300000" RANKS="2 4 8" bash scripts/scaling.sh
#
# For each K: the native one-process run (NATIVE, default this build's binary; set it to an
# older build to compare against it), then `mpirun -n P ... --solver slepc` for each P, every
# rank under /usr/bin/time -v. Prints one markdown row per run: each rank's peak (from
# /usr/bin/time, in GB), the bar 1.2 x native / P, the ranks' estimates, iterations, and the
# stage times. Ranks beyond the cores are oversubscribed: read their times as work, not
# speedups. Output files go to OUT (default /tmp/freeform-scaling).
set -euo pipefail

FREEFORM=${FREEFORM:-target/release/freeform}
NATIVE=${NATIVE:-$FREEFORM}
SHAPE=${SHAPE:-box:5,1,1}
KERNELS=${KERNELS:-30000}
RANKS=${RANKS:-"1 2 4"}
MODES=${MODES:-32}
SLEPC=${SLEPC:-}
OUT=${OUT:-/tmp/freeform-scaling}
mkdir -p "$OUT"
export OMP_NUM_THREADS=1 OMPI_MCA_mpi_yield_when_idle=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
slepc_flag=()
[ -n "$SLEPC" ] && slepc_flag=(--slepc "$SLEPC")

echo "| K | P | peak per rank, GB (max) | bar 1.2 x native / P | estimate per rank, GB | iterations | centres s | rows s | eigensolve s |"
echo "|---|---|---|---|---|---|---|---|---|"
for k in $KERNELS; do
    native="$OUT/native.k$k"
    /usr/bin/time -v -o "$native.time" "$NATIVE" modes "$SHAPE" --kernels "$k" --modes "$MODES" \
        --threads 2 --json --out "$OUT/native.npz" > "$native.json"
    native_kb=$(awk -F': ' '/Maximum resident/ {print $2}' "$native.time")
    echo "| $k | native | $(python3 -c "print(f'{$native_kb / 1e6:.3f}')") | | | $(python3 -c "import json; print(json.load(open('$native.json'))['eigen']['iterations'])") | | | |"
    for p in $RANKS; do
        run="$OUT/k$k.p$p"
        rm -f "$run".time.rank*
        mpirun --oversubscribe -n "$p" bash -c '
            exec /usr/bin/time -v -o "'"$run"'.time.rank${OMPI_COMM_WORLD_RANK}" "'"$FREEFORM"'" \
                modes "'"$SHAPE"'" --kernels "'"$k"'" --modes "'"$MODES"'" --solver slepc \
                --distributed --threads 1 --json --out "'"$OUT"'/basis.npz" "$@"' _ "${slepc_flag[@]}" \
            > "$run.json"
        python3 - "$run" "$native_kb" "$p" "$k" <<'EOF'
import glob, json, sys
run, native_kb, p, k = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
peaks = []
for f in sorted(glob.glob(run + ".time.rank*")):
    for line in open(f):
        if "Maximum resident" in line:
            peaks.append(float(line.split(":")[1]) / 1e6)
r = json.load(open(run + ".json"))
d, t = r["distributed"], r["timings_s"]
est = max(d["estimated_bytes_per_rank"]) / 1e9
rows = t["neighbors"] + t["shape_functions"] + t["assembly"]
print(f"| {k} | {p} | {max(peaks):.3f} ({', '.join(f'{x:.3f}' for x in peaks)}) | "
      f"{1.2 * native_kb / 1e6 / p:.3f} | {est:.3f} | {r['eigen']['iterations']} | "
      f"{t['centers']:.1f} | {rows:.1f} | {t['eigensolve']:.1f} |")
EOF
    done
done
