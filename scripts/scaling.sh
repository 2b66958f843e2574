#!/bin/bash
# Memory per MPI rank against the one-process native run (docs/slepc.md "Scaling").
#
#   KERNELS="100000 300000" RANKS="2 4 8" bash scripts/scaling.sh
#   KERNELS="100000 300000" RANKS="2 4 8" EXTRA="--max-iter 3" NATIVE=none bash scripts/scaling.sh
#
# For each K: the native one-process run (NATIVE, default this build's binary; set it to an
# older build to compare against it), then `mpirun -n P ... --solver slepc` for each P, every
# rank under /usr/bin/time -v. Prints one markdown row per run: each rank's peak (from
# /usr/bin/time, in GB of 1e9 bytes), the bar 1.2 x native / P, the ranks' estimates,
# iterations, and the stage times. Ranks beyond the cores are oversubscribed: read their
# times as work, not speedups. Output files go to OUT (default /tmp/freeform-scaling). EXTRA is added to every
# distributed run's arguments: with "--max-iter 3" the solve stops after its set-up and three
# iterations, where the peak is reached, and every rank ends with the iteration-cap error (the
# ranks are let finish so that each writes its peak; there is then no report, so no estimate,
# iterations or times). NATIVE=none skips the native run (the bar column is then empty).
set -euo pipefail

FREEFORM=${FREEFORM:-target/release/freeform}
NATIVE=${NATIVE:-$FREEFORM}
SHAPE=${SHAPE:-box:5,1,1}
KERNELS=${KERNELS:-30000}
RANKS=${RANKS:-"1 2 4"}
MODES=${MODES:-32}
SLEPC=${SLEPC:-}
EXTRA=${EXTRA:-}
OUT=${OUT:-/tmp/freeform-scaling}
mkdir -p "$OUT"
export OMP_NUM_THREADS=1 OMPI_MCA_mpi_yield_when_idle=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
slepc_flag=()
[ -n "$SLEPC" ] && slepc_flag=(--slepc "$SLEPC")

echo "| K | P | peak per rank, GB (max) | bar 1.2 x native / P | estimate per rank, GB | iterations | centres s | rows s | eigensolve s |"
echo "|---|---|---|---|---|---|---|---|---|"
for k in $KERNELS; do
    native_kb=0
    if [ "$NATIVE" != none ]; then
        native="$OUT/native.k$k"
        /usr/bin/time -v -o "$native.time" "$NATIVE" modes "$SHAPE" --kernels "$k" \
            --modes "$MODES" --threads 2 --json --out "$OUT/native.npz" > "$native.json"
        native_kb=$(awk -F': ' '/Maximum resident/ {print $2}' "$native.time")
        echo "| $k | native | $(python3 -c "print(f'{$native_kb * 1024 / 1e9:.3f}')") | | | $(python3 -c "import json; print(json.load(open('$native.json'))['eigen']['iterations'])") | | | |"
    fi
    for p in $RANKS; do
        run="$OUT/k$k.p$p"
        rm -f "$run".time.rank* "$run.json"
        # Every rank runs to its end, also when one fails (the capped runs do, on purpose).
        mpirun --oversubscribe --mca orte_abort_on_non_zero_status 0 -n "$p" bash -c '
            /usr/bin/time -v -o "'"$run"'.time.rank${OMPI_COMM_WORLD_RANK}" "'"$FREEFORM"'" \
                modes "'"$SHAPE"'" --kernels "'"$k"'" --modes "'"$MODES"'" --solver slepc \
                --distributed --threads 1 --json --out "'"$OUT"'/basis.npz" "$@"' _ \
            "${slepc_flag[@]}" $EXTRA > "$run.json" 2> "$run.err" || true
        python3 - "$run" "$native_kb" "$p" "$k" <<'EOF'
import glob, json, sys
run, native_kb, p, k = sys.argv[1], float(sys.argv[2]), int(sys.argv[3]), sys.argv[4]
peaks = []
for f in sorted(glob.glob(run + ".time.rank*")):
    for line in open(f):
        if "Maximum resident" in line:
            # /usr/bin/time reports kibibytes; GB here is 1e9 bytes, as in the JSON reports.
            peaks.append(float(line.split(":")[1]) * 1024 / 1e9)
bar = f"{1.2 * native_kb * 1024 / 1e9 / p:.3f}" if native_kb > 0 else ""
try:
    r = json.load(open(run + ".json"))
    d, t = r["distributed"], r["timings_s"]
    rows = t["neighbors"] + t["shape_functions"] + t["assembly"]
    rest = (f"{max(d['estimated_bytes_per_rank']) / 1e9:.3f} | {r['eigen']['iterations']} | "
            f"{t['centers']:.1f} | {rows:.1f} | {t['eigensolve']:.1f}")
except (OSError, ValueError, KeyError):
    rest = "- | - | - | - | -"  # no report: the run stopped (e.g. at EXTRA's --max-iter)
print(f"| {k} | {p} | {max(peaks):.3f} ({', '.join(f'{x:.3f}' for x in peaks)}) | "
      f"{bar} | {rest} |")
EOF
    done
done
