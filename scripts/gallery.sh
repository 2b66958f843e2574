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

# The robot arm sweeping three objects (examples/robot_push.toml): frame 24 of 33 (t = 1.2 s),
# the arm's capsules drawn from the collider frames.
$FF run examples/robot_push.toml --out "$WORK/robot_push" > /dev/null
$FF render "$WORK/robot_push" --ground 0 --elevation 45 --azimuth 20 --every 24 \
    --out "$WORK/robot_push_png"
cp "$WORK/robot_push_png/frame_000024.png" docs/img/robot_push.png

# Object-object contact (examples/stack.toml): the ball has bounced off the two-block stack and
# rolled away behind it, frame 30 of 40 (t = 0.6 s).
$FF run examples/stack.toml --out "$WORK/stack" > /dev/null
$FF render "$WORK/stack" --ground 0 --elevation 25 --azimuth 120 --every 6 --size 640x480 \
    --out "$WORK/stack_png"
cp "$WORK/stack_png/frame_000030.png" docs/img/stack.png

# Container (examples/container.toml): 13 objects of five shapes settled in the open-top mesh
# container, seen from above (its walls are opaque), the last frame (t = 1.5 s).
$FF run examples/container.toml --out "$WORK/container" > /dev/null
$FF render "$WORK/container" --ground 0 --elevation 65 --azimuth 10 --every 30 --size 640x480 \
    --out "$WORK/container_png"
cp "$WORK/container_png/frame_000030.png" docs/img/container.png

# Plinko (examples/plinko.toml): 18 objects on the first row of pegs, frame 6 (t = 0.3 s). Only
# the first 30 steps are run (a copy of the scene with `steps = 30`): the picture needs no more,
# and the later steps, with most objects in one island, are the slow part (docs/performance.md).
sed 's/^steps = 150$/steps = 30/' examples/plinko.toml > "$WORK/plinko30.toml"
grep -q '^steps = 30$' "$WORK/plinko30.toml"
$FF run "$WORK/plinko30.toml" --out "$WORK/plinko" > /dev/null
$FF render "$WORK/plinko" --ground 0 --elevation 10 --azimuth 0 --every 6 --size 640x480 \
    --color none --out "$WORK/plinko_png"
cp "$WORK/plinko_png/frame_000006.png" docs/img/plinko.png

# Plinko with splat toys (examples/plinko_splats.toml): the derived contact surfaces of the 18
# splat objects among the pegs, frame 12 (t = 0.6 s) of the first 60 steps.
sed 's/^steps = 150$/steps = 60/' examples/plinko_splats.toml > examples/.plinko_splats60.toml
grep -q '^steps = 60$' examples/.plinko_splats60.toml
$FF run examples/.plinko_splats60.toml --out "$WORK/plinko_splats" > /dev/null
rm examples/.plinko_splats60.toml
$FF render "$WORK/plinko_splats" --ground 0 --elevation 15 --azimuth 20 --every 12 \
    --size 640x480 --zoom 1.4 --out "$WORK/plinko_splats_png"
cp "$WORK/plinko_splats_png/frame_000012.png" docs/img/plinko_splats.png

# A splat object before and after: a beach ball of 3D Gaussians (docs/splats.md) dropped on
# the floor. 16 000 flat surface splats (Fibonacci sphere, radius 0.3 m; axes along north,
# east and the normal; six coloured gores and white caps, light baked in) and a grid of faint interior splats
# 0.03 m apart (so the simulated cloud is solid: `voxel = 0.03` gives every interior splat its
# voxel's volume). Written as an ASCII 3DGS PLY.
awk -v N=16000 -v R=0.3 -v G=0.03 'function quat(m,   t, s, w, x, y, z) {
        # Unit quaternion (w, x, y, z) of the rotation matrix m (row-major m[1..9]).
        t = m[1] + m[5] + m[9]
        if (t > 0) { s = 2 * sqrt(1 + t); w = s / 4; x = (m[8] - m[6]) / s; y = (m[3] - m[7]) / s; z = (m[4] - m[2]) / s }
        else if (m[1] > m[5] && m[1] > m[9]) { s = 2 * sqrt(1 + m[1] - m[5] - m[9]); w = (m[8] - m[6]) / s; x = s / 4; y = (m[2] + m[4]) / s; z = (m[3] + m[7]) / s }
        else if (m[5] > m[9]) { s = 2 * sqrt(1 + m[5] - m[1] - m[9]); w = (m[3] - m[7]) / s; x = (m[2] + m[4]) / s; y = s / 4; z = (m[6] + m[8]) / s }
        else { s = 2 * sqrt(1 + m[9] - m[1] - m[5]); w = (m[4] - m[2]) / s; x = (m[3] + m[7]) / s; y = (m[6] + m[8]) / s; z = s / 4 }
        return sprintf("%.7f %.7f %.7f %.7f", w, x, y, z)
    }
    function dc(c) { return (c - 0.5) / 0.28209479177387814 }
    BEGIN {
        pi = atan2(0, -1); ga = pi * (3 - sqrt(5)); n = 0
        for (i = 0; i < N; i++) {
            y = 1 - 2 * (i + 0.5) / N; rr = sqrt(1 - y * y); ph = ga * i
            nx = rr * cos(ph); nz = rr * sin(ph)
            # Axes: north, east (around y), the normal (north x east = normal: a proper rotation).
            ex = -sin(ph); ez = cos(ph)
            qx = -y * cos(ph); qy = rr; qz = -y * sin(ph)
            m[1] = qx; m[2] = ex; m[3] = nx; m[4] = qy; m[5] = 0; m[6] = y; m[7] = qz; m[8] = ez; m[9] = nz
            g = int(((atan2(nz, nx) + pi) / (2 * pi)) * 6) % 6
            if (g == 0) { r = 0.85; gg = 0.12; b = 0.12 } else if (g == 1) { r = 0.97; gg = 0.97; b = 0.95 }
            else if (g == 2) { r = 0.10; gg = 0.35; b = 0.85 } else if (g == 3) { r = 0.98; gg = 0.82; b = 0.10 }
            else if (g == 4) { r = 0.12; gg = 0.65; b = 0.25 } else { r = 0.98; gg = 0.50; b = 0.08 }
            if (y > 0.93 || y < -0.93) { r = 0.97; gg = 0.97; b = 0.95 }
            # Light baked into the colours, as a captured scene has it (from the upper left front).
            l = -0.35 * nx + 0.75 * y + 0.56 * nz; l = 0.5 + 0.5 * (l > 0 ? l : 0); r *= l; gg *= l; b *= l
            line[n++] = sprintf("%.7f %.7f %.7f %.6f %.6f %.6f 4.0 %.6f %.6f %.6f %s", R * nx, R * y, R * nz,
                dc(r), dc(gg), dc(b), log(0.0075), log(0.0075), log(0.0012), quat(m))
        }
        for (x = -R; x <= R; x += G) for (y = -R; y <= R; y += G) for (z = -R; z <= R; z += G)
            if (x * x + y * y + z * z < (R - G) * (R - G))
                line[n++] = sprintf("%.7f %.7f %.7f 0 0 0 -4.0 %.6f %.6f %.6f 1 0 0 0", x, y, z, log(0.01), log(0.01), log(0.01))
        print "ply\nformat ascii 1.0\nelement vertex " n
        print "property float x\nproperty float y\nproperty float z"
        print "property float f_dc_0\nproperty float f_dc_1\nproperty float f_dc_2\nproperty float opacity"
        print "property float scale_0\nproperty float scale_1\nproperty float scale_2"
        print "property float rot_0\nproperty float rot_1\nproperty float rot_2\nproperty float rot_3\nend_header"
        for (i = 0; i < n; i++) print line[i]
    }' > "$WORK/ball.ply"
cat > "$WORK/splat_drop.toml" <<'TOML'
[simulation]
dt = 0.005
steps = 120
gravity = [0.0, -9.81, 0.0]

[solver]
hessian = "newton"
cubature = 2000

[output]
every = 4
formats = ["vtk", "ply"]

[[object]]
name = "ball"
shape = "ball.ply"
material = { youngs = 1e5, poisson = 0.4, density = 1000.0 }
basis = { kernels = 400, modes = 12, voxel = 0.03 }
placement = { translation = [0.0, 0.8, 0.0], velocity = [0.5, 0.0, 0.0], angular_velocity = [0.0, 0.0, -2.0] }

[[collider]]
shape = { plane = { point = [0.0, 0.0, 0.0], normal = [0.0, 1.0, 0.0] } }
TOML
$FF run "$WORK/splat_drop.toml" --out "$WORK/splat" > /dev/null
# Frame 0 (t = 0) and frame 20 (t = 0.4 s, the most squashed).
$FF render "$WORK/splat" --ground 0 --size 480x360 --out "$WORK/splat_png"
cp "$WORK/splat_png/frame_000000.png" docs/img/splat_before.png
cp "$WORK/splat_png/frame_000020.png" docs/img/splat_after.png

# A real mesh: CGAL's pig (Debian's libcgal-demo data set; installed if missing). It has
# holes (1296 boundary edges), so inside is decided by winding number, and thin legs and ears
# that need a wider support than the default.
CGAL_DATA=/usr/share/doc/libcgal-dev/data.tar.gz
if [ ! -f "$CGAL_DATA" ]; then
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends libcgal-demo >/dev/null
fi
tar xzf "$CGAL_DATA" -C "$WORK" data/meshes/pig.stl
$FF modes "$WORK/data/meshes/pig.stl" --allow-open-mesh --support 2.5 --kernels 1000 --modes 8 \
    --out "$WORK/pig.npz" --png docs/img/modes_pig.png --up z --azimuth 300 --elevation 15 \
    --png-tile 320x260 > /dev/null

# The bent beam's von Mises stress (output.stress = true), last frame.
sed 's/^\[output\]/[output]\nstress = true/' examples/beam_bend.toml > "$WORK/bend_stress.toml"
$FF run "$WORK/bend_stress.toml" --out "$WORK/bend" > /dev/null
$FF render "$WORK/bend" --color von_mises --every 50 --size 800x450 --out "$WORK/bend_png" > /dev/null
cp "$WORK/bend_png/frame_000050.png" docs/img/stress_bend.png

# The CT-like voxel phantom (label image, contrast 1e4) held at one end, last frame.
$FF run examples/ct_phantom.toml --out "$WORK/ct" > /dev/null
$FF render "$WORK/ct" --every 20 --size 800x450 --azimuth 20 --elevation 15 --out "$WORK/ct_png" > /dev/null
cp "$WORK/ct_png/frame_000020.png" docs/img/ct_phantom.png

ls -l docs/img/ct_phantom.png docs/img/modes_torus.png docs/img/modes_box.png docs/img/drop_*.png docs/img/splat_*.png \
    docs/img/modes_pig.png docs/img/stress_bend.png
