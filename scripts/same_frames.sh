#!/usr/bin/env bash
# Do two builds of `freeform` simulate the example scenes bit for bit alike?
#
#   scripts/same_frames.sh OLD_BINARY NEW_BINARY [STEPS]
#
# Runs every examples/*.toml with both binaries (the first STEPS steps, default 30, a fresh
# basis each time), then compares the frame files byte for byte and the JSON reports with
# their timing fields (`*_s`, `*_ms*`, `wall*`) removed and the output directory renamed. A
# structural change (issue 27) must leave both identical. Exit 0: all the same; 1: a
# difference (printed). Run both binaries on the same machine: the bits depend on the CPU's
# vector width, so this compares builds, not machines. 30 steps of all 12 scenes: ~4 min on
# 2 cores.
set -euo pipefail
old=$(realpath "$1")
new=$(realpath "$2")
steps=${3:-30}
cd "$(dirname "$0")/.."
work=$(mktemp -d)
copies=()
cleanup() { rm -rf "$work"; rm -f "${copies[@]}"; }
trap cleanup EXIT
status=0
for scene in examples/*.toml; do
  name=$(basename "$scene" .toml)
  # The copy sits beside the original, so the scene's relative paths still resolve.
  copy="examples/.same_frames_$name.toml"
  copies+=("$copy")
  sed "s/^steps = .*/steps = $steps/" "$scene" > "$copy"
  for which in old new; do
    bin=$old; [ "$which" = new ] && bin=$new
    mkdir -p "$work/$which/$name"
    "$bin" run "$copy" --out "$work/$which/$name/frames" --json --no-cache --threads 2 \
      > "$work/$which/$name/report.json" 2> "$work/$which/$name/stderr" || {
        echo "$name: $which run failed"; tail -3 "$work/$which/$name/stderr"; status=1; continue 2; }
    python3 - "$work/$which/$name/report.json" "$work/$which" <<'EOF'
import json, sys
timing = lambda k: k.endswith("_s") or "_ms" in k or k.startswith("wall")
def strip(x):
    if isinstance(x, dict):
        return {k: strip(v) for k, v in x.items() if not timing(k)}
    if isinstance(x, list):
        return [strip(v) for v in x]
    if isinstance(x, str):  # output paths name the run's own directory
        return x.replace(sys.argv[2], "OUT")
    return x
path = sys.argv[1]
with open(path) as f:
    d = strip(json.load(f))
with open(path, "w") as f:
    json.dump(d, f, indent=1, sort_keys=True)
EOF
  done
  if diff -rq "$work/old/$name" "$work/new/$name" --exclude=stderr > "$work/diff" ; then
    echo "$name: same ($(find "$work/new/$name/frames" -type f | wc -l) files)"
  else
    echo "$name: DIFFERENT"; cat "$work/diff"; status=1
  fi
done
exit $status
