#!/usr/bin/env bash
# The real-shape set of the evaluation (issue 18, docs/evaluation.md): extracts the chosen
# meshes of CGAL's data set (Debian package libcgal-demo, data/meshes/*.off) into OUT_DIR and
# keeps those freeform accepts as solids (closed, edge-manifold, a finite non-zero volume) and
# TetGen can mesh for the FEM reference (no self-intersecting faces, `tetgen -d`). The others
# are listed with the library's or TetGen's own reason. A mesh with more than MAX_FACES
# faces (default 2500) is first reduced to MAX_FACES by scripts/decimate_off.py (MeshLab's
# quadric edge collapse through pymeshlab, installed into OUT_DIR/.venv): the FEM reference
# keeps every surface triangle, so a large input would cost hours of FEM; the reduced mesh is
# then checked like any other. A mesh that fails a check is repaired at its own size by
# MeshFix (scripts/repair_off.py through pymeshfix; REPAIR=0 turns this off), then reduced and
# checked again; it is kept as "repaired" when it passes. Writes OUT_DIR/shapes.csv:
#   name,input_faces,vertices,faces,status,reason
#
#   scripts/cgal_shapes.sh OUT_DIR [FREEFORM_BIN]
#
# FREEFORM_BIN defaults to target/release/freeform (built when missing). Installing the
# packages (libcgal-demo, tetgen) needs root (apt-get); pymeshlab and pymeshfix come from
# PyPI.
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

# The Python tools (pymeshlab, pymeshfix) in OUT_DIR/.venv, installed on first use.
python_with() {
    if [[ ! -x $venv/bin/python ]] || ! "$venv/bin/python" -c "import $1" 2>/dev/null; then
        echo "installing $1 into $venv ..." >&2
        [[ -x $venv/bin/python ]] || python3 -m venv "$venv"
        "$venv/bin/pip" install -q "$1"
    fi
}

# Reduce FILE in place to at most max_faces faces; prints the error if MeshLab cannot.
reduce() {
    local file=$1 name=$2 nf msg status
    read -r _ nf _ < <(grep -v '^\s*#' "$file" | sed -n 2p)
    ((nf > max_faces)) || return 0
    python_with pymeshlab
    if msg=$("$venv/bin/python" scripts/decimate_off.py "$file" "${file%.off}.decimated.off" \
        "$max_faces" 2>&1 >/dev/null); then
        mv "${file%.off}.decimated.off" "$file"
        echo "$name: $nf faces reduced to at most $max_faces" >&2
    else
        status=$?
        rm -f "${file%.off}.decimated.off"
        echo "decimation failed (exit $status): $(printf '%s' "$msg" | tail -n1)"
    fi
}

# Prints why FILE (OUT_DIR/NAME.off) is not a valid solid, or nothing when it is.
check() {
    local file=$1 name=$2 msg found
    # The library's own check: a tiny basis (64 kernels, 2 modes) reads the mesh, welds it,
    # checks it is closed and edge-manifold, and samples its inside.
    if ! msg=$("$bin" modes "$file" --kernels 64 --modes 2 --out /dev/null 2>&1 >/dev/null); then
        printf '%s' "$msg" | grep -m1 '^error' | sed "s|$file: ||; s|^error: ||" || true
        return 0
    fi
    # TetGen's self-intersection check (-d) writes only the surface; no tetrahedra.
    found=$(cd "$out" && tetgen -pd "$name.off" 2>&1 | grep -m1 'are intersecting' || true)
    rm -f "$out/$name".1.*
    if [[ $found == *Found* ]]; then
        echo "TetGen: ${found#!! Found }"
    fi
}

kept=0
repaired=0
for s in "${shapes[@]}"; do
    file=$out/$s.off
    read -r _ nf_in _ < <(grep -v '^\s*#' "$file" | sed -n 2p)
    cp "$file" "$out/$s.input"
    reason=$(reduce "$file" "$s")
    [[ -n $reason ]] || reason=$(check "$file" "$s")
    status=kept
    [[ -z $reason ]] || status=skipped
    if [[ $status == skipped && ${REPAIR:-1} == 1 ]]; then
        # A refused input is repaired by MeshFix (scripts/repair_off.py) at its own size,
        # then reduced and checked like any input; the reason says what was wrong.
        # (`reduce` overwrote FILE; the input is kept beside it until this is done.)
        python_with pymeshfix
        parts=""
        if msg=$("$venv/bin/python" scripts/repair_off.py "$out/$s.input" "$file" 2>&1); then
            read -r comps faces_before faces_after <<<"$(printf '%s' "$msg" | tail -n1)"
            again=$(reduce "$file" "$s")
            [[ -n $again ]] || again=$(check "$file" "$s")
            # The reduction can make faces cross again: one more MeshFix pass on the
            # reduced mesh (it moves or drops a few faces, never adds many).
            if [[ -n $again ]] && msg=$("$venv/bin/python" scripts/repair_off.py "$file" "$file" 2>&1); then
                read -r _ _ n <<<"$(printf '%s' "$msg" | tail -n1)"
                parts="; again after the reduction: $n faces"
                again=$(check "$file" "$s")
            fi
            if [[ -z $again ]]; then
                status=repaired
                ((comps == 1)) || parts=" (kept the largest of $comps components)$parts"
                reason="was: $reason; MeshFix: $faces_before -> $faces_after faces$parts"
                echo "repaired $s: $reason" >&2
            else
                reason="$reason; after MeshFix: $again"
            fi
        else
            reason="$reason; MeshFix failed: $(printf '%s' "$msg" | tail -n1)"
        fi
    fi
    rm -f "$out/$s.input"
    read -r nv nf _ < <(grep -v '^\s*#' "$file" | sed -n 2p)
    if [[ $status != skipped ]]; then
        echo "$s,$nf_in,$nv,$nf,$status,${reason//,/;}" >> "$csv"
        kept=$((kept + 1))
        [[ $status == kept ]] || repaired=$((repaired + 1))
    else
        echo "$s,$nf_in,$nv,$nf,skipped,${reason//,/;}" >> "$csv"
        rm -f "$file"
        echo "skipped $s: $reason" >&2
    fi
done
echo "$kept of ${#shapes[@]} shapes kept in $out ($repaired of them repaired; list: $csv)" >&2
