#!/usr/bin/env bash
# Regenerate the pictures of docs/img/ that docs/pictures.md and README.md show:
#   scripts/gallery.sh [WORKDIR]      (default WORKDIR: a fresh temporary directory)
# Needs only the release binary (built on first use). The torus is written procedurally
# (no mesh files in the repository), so every picture comes from this script.
set -euo pipefail
cd "$(dirname "$0")/.."
WORK="${1:-$(mktemp -d)}"
mkdir -p "$WORK" docs/img
FF="cargo run --release --quiet --"

# A closed, outward-oriented torus in the xy plane (standing up along +y): major radius 1 m,
# minor radius 0.3 m, 64 x 24 quads split into triangles.
awk -v N=64 -v M=24 -v R=1.0 -v r=0.3 'BEGIN {
    pi = atan2(0, -1)
    for (i = 0; i < N; i++) for (j = 0; j < M; j++) {
        u = 2 * pi * i / N; v = 2 * pi * j / M
        printf "v %.9f %.9f %.9f\n", (R + r * cos(v)) * cos(u), (R + r * cos(v)) * sin(u), r * sin(v)
    }
    for (i = 0; i < N; i++) for (j = 0; j < M; j++) {
        a = i * M + j + 1; b = ((i + 1) % N) * M + j + 1
        c = ((i + 1) % N) * M + (j + 1) % M + 1; d = i * M + (j + 1) % M + 1
        printf "f %d %d %d\nf %d %d %d\n", a, b, c, a, c, d
    }
}' > "$WORK/torus.obj"

# The first six modes of the torus.
$FF modes "$WORK/torus.obj" --modes 8 --out "$WORK/torus.npz" \
    --png docs/img/modes_torus.png --png-tile 300x260 --azimuth 20 --elevation 25

# The first six modes of a point cloud box (integration points drawn as discs).
$FF modes box:2,0.5,0.5 --modes 8 --out "$WORK/box.npz" \
    --png docs/img/modes_box.png --png-tile 300x200

# The drop (examples/drop.toml): frames 0, 20, 30, 50 of 51 with the floor.
$FF run examples/drop.toml --out "$WORK/drop" > /dev/null
$FF render "$WORK/drop" --ground 0 --every 10 --size 480x360 --out "$WORK/drop_png"
for n in 000000 000020 000030 000050; do cp "$WORK/drop_png/frame_$n.png" "docs/img/drop_$n.png"; done

ls -l docs/img/modes_torus.png docs/img/modes_box.png docs/img/drop_*.png
