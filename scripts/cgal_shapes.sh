#!/usr/bin/env bash
# The real-shape set of the evaluation (issue 18, docs/evaluation.md): extracts the chosen
# meshes of CGAL's data set (Debian package libcgal-demo, data/meshes/*.off) into OUT_DIR and
# keeps those freeform accepts as solids (closed, edge-manifold, a finite non-zero volume) and
# TetGen can mesh for the FEM reference (no self-intersecting faces, `tetgen -d`). The others
# are listed with the library's or TetGen's own reason. A mesh with more than MAX_FACES
# faces (default 2500) is first reduced to MAX_FACES by scripts/decimate_off.py (MeshLab's
# quadric edge collapse through pymeshlab, installed into OUT_DIR/.venv): the FEM reference
# keeps every surface triangle, so a large input would cost hours of FEM; the reduced mesh is
# then checked like any other. Writes OUT_DIR/shapes.csv:
#   name,input_faces,vertices,faces,status,reason
#
#   scripts/cgal_shapes.sh OUT_DIR [FREEFORM_BIN]
#
# FREEFORM_BIN defaults to target/release/freeform (built when missing). Installing the
# packages (libcgal-demo, tetgen) needs root (apt-get); pymeshlab comes from PyPI.
set -euo pipefail
cd "$(dirname "$0")/.."

out=${1:?usage: scripts/cgal_shapes.sh OUT_DIR [FREEFORM_BIN]}
bin=${2:-target/release/freeform}
tarball=/usr/share/doc/libcgal-dev/data.tar.gz

# Organic and mechanical shapes of several sizes, genera and thicknesses. Chosen by name
# before any was run; a shape is never dropped for its results, only for the check below.
shapes=(
    armadillo bear bull bunny00 camel cow dino elephant elk femur hand head homer
    horizons knot lion man mannequin-devil mushroom triceratops
    anchor cactus couplingdown fandisk handle pinion rotor spool turbine
    blobby blobby_3cc elephant-with-holes
)

if [[ ! -f $tarball ]] || ! command -v tetgen >/dev/null; then
    echo "installing libcgal-demo (CGAL's data set) and tetgen ..." >&2
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends \
        libcgal-demo tetgen >/dev/null
fi
if [[ ! -x $bin ]]; then
    cargo build --release --quiet
fi

max_faces=${MAX_FACES:-2500}
mkdir -p "$out"
members=()
for s in "${shapes[@]}"; do members+=("data/meshes/$s.off"); done
tar -xzf "$tarball" -C "$out" --strip-components=2 "${members[@]}"

csv=$out/shapes.csv
echo "name,input_faces,vertices,faces,status,reason" > "$csv"
venv=$out/.venv
kept=0
for s in "${shapes[@]}"; do
    file=$out/$s.off
    read -r _ nf_in _ < <(grep -v '^\s*#' "$file" | sed -n 2p)
    if ((nf_in > max_faces)); then
        if [[ ! -x $venv/bin/python ]] || ! "$venv/bin/python" -c 'import pymeshlab' 2>/dev/null; then
            echo "installing pymeshlab into $venv ..." >&2
            python3 -m venv "$venv"
            "$venv/bin/pip" install -q pymeshlab
        fi
        # A mesh MeshLab cannot reduce is skipped with its message, like any failed check.
        if msg=$("$venv/bin/python" scripts/decimate_off.py "$file" "$out/$s.decimated.off" \
            "$max_faces" 2>&1 >/dev/null); then
            mv "$out/$s.decimated.off" "$file"
            echo "$s: $nf_in faces reduced to at most $max_faces" >&2
        else
            status=$?
            rm -f "$out/$s.decimated.off"
            reduce_error="decimation failed (exit $status): $(printf '%s' "$msg" | tail -n1)"
        fi
    fi
    read -r nv nf _ < <(grep -v '^\s*#' "$file" | sed -n 2p)
    # The library's own check: a tiny basis (64 kernels, 2 modes) reads the mesh, welds it,
    # checks it is closed and edge-manifold, and samples its inside.
    reason=
    if [[ -n ${reduce_error:-} ]]; then
        reason=$reduce_error
        unset reduce_error
    elif ! msg=$("$bin" modes "$file" --kernels 64 --modes 2 --out /dev/null 2>&1 >/dev/null); then
        reason=$(printf '%s' "$msg" | grep -m1 '^error' | sed "s|$file: ||; s|^error: ||")
    else
        # TetGen's self-intersection check (-d) writes only the surface; no tetrahedra.
        found=$(cd "$out" && tetgen -pd "$s.off" 2>&1 | grep -m1 'are intersecting' || true)
        rm -f "$out/$s".1.*
        if [[ $found == *Found* ]]; then
            reason="TetGen: ${found#!! Found }"
        fi
    fi
    if [[ -z $reason ]]; then
        echo "$s,$nf_in,$nv,$nf,kept," >> "$csv"
        kept=$((kept + 1))
    else
        reason=${reason//,/;}
        echo "$s,$nf_in,$nv,$nf,skipped,$reason" >> "$csv"
        rm -f "$file"
        echo "skipped $s: $reason" >&2
    fi
done
echo "$kept of ${#shapes[@]} shapes kept in $out (list: $csv)" >&2
