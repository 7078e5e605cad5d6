#!/bin/sh
# Layers that hold (STYLE.md, docs/architecture.md): a folder of src/ calls
# only the folders below it, and the files of the folders named in TREES
# call each other without a circle.  Read from the objects' symbols, not
# from the includes: for every src/<folder>/<file>.c, its object in the
# build tree, `nm` gives the names it defines and the names it needs; a
# name one object needs and another defines is a call (or a use of data)
# from the first file into the second.
#   scripts/check_layers.sh [BUILD_DIR]   (default: build; build it first)
# Exit 0 when every arrow points down, 1 with each arrow that does not.
set -eu
cd "$(dirname "$0")/.."
BUILD=${1:-build}

# The folders, bottom first: the data flow of STYLE.md.  A parameterisation
# is geometry (direction pairs <-> cells) and evaluates no BRDF; sources
# use its direction helpers and cover a layout's cells; sample/ evaluates
# sources over layouts (the matrix, the warp scan); then the solvers, the
# factor plan and its errors, the output files, the factor job, the CLI.
ORDER="util param source sample solve factor output job cli"
# Folders whose files form a tree (no circle between two files).
TREES="util solve factor job"

syms=$(mktemp)
trap 'rm -f "$syms"' EXIT
# "object source" for every source file; one nm over all of them
pairs=""
found=0
for src in $(git ls-files 'src/*.c' 2>/dev/null || find src -name '*.c'); do
    [ -f "$src" ] || continue
    obj=""
    for o in "$BUILD"/CMakeFiles/sepbrdf_obj.dir/"$src".o "$BUILD"/CMakeFiles/*.dir/"$src".o; do
        if [ -f "$o" ]; then
            obj=$o
            break
        fi
    done
    if [ -z "$obj" ]; then # an optional part (MPI) this build left out
        echo "check_layers: $src: no object under $BUILD, skipped" >&2
        continue
    fi
    found=1
    pairs="$pairs $obj $src"
done
if [ "$found" = 0 ]; then
    echo "check_layers: no objects under $BUILD: build first" >&2
    exit 1
fi
# shellcheck disable=SC2086
set -- $pairs
objs=""
while [ $# -gt 0 ]; do
    objs="$objs $1"
    shift 2
done
# "source kind name": U for a name needed, D for one defined
# shellcheck disable=SC2086
nm -A $objs | awk -v pairs="$pairs" '
    BEGIN { n = split(pairs, p, " "); for (i = 1; i < n; i += 2) src[p[i]] = p[i + 1] }
    {
        at = index($0, ":"); obj = substr($0, 1, at - 1); $0 = substr($0, at + 1)
        if (NF == 2 && $1 == "U") print src[obj], "U", $2
        else if (NF == 3 && $2 ~ /^[A-TV-Z]$/) print src[obj], "D", $3, $2
    }' >"$syms"

awk -v order="$ORDER" -v trees="$TREES" '
    function folder(f,   p) { split(f, p, "/"); return p[2] }
    BEGIN {
        n = split(order, o, " ")
        for (i = 1; i <= n; i++) rank[o[i]] = i
        split(trees, t, " ")
        for (i in t) tree[t[i]] = 1
    }
    $2 == "D" { def[$3] = $1; code[$3] = ($4 == "T"); next }
    { need[++nu] = $1; what[nu] = $3 }
    END {
        bad = 0
        for (i = 1; i <= nu; i++) {
            a = need[i]; s = what[i]
            if (!(s in def) || def[s] == a) continue
            b = def[s]; fa = folder(a); fb = folder(b)
            if (!(fa in rank) || !(fb in rank)) {
                printf "check_layers: %s or %s: folder not in ORDER (%s)\n", a, b, order > "/dev/stderr"
                bad = 1
                continue
            }
            if (rank[fa] < rank[fb]) {
                printf "check_layers: %s calls %s in %s: %s is below %s\n", a, s, b, fa, fb > "/dev/stderr"
                bad = 1
            }
            # a registry table naming its rows (descriptors: data, not code) is
            # no call: the rows call the shared code below it (solvers.c)
            if (fa == fb && (fa in tree) && code[s] && !((a, b) in edge)) {
                edge[a, b] = s
                files[fa] = files[fa] " " a " " b
            }
        }
        # circles: the transitive closure of each tree folder (a few dozen files)
        for (fo in files) {
            m = split(files[fo], l, " ")
            k = 0
            delete seen; delete node
            for (i = 1; i <= m; i++) if (!(l[i] in seen)) { seen[l[i]] = 1; node[++k] = l[i] }
            delete reach
            for (i = 1; i <= k; i++) for (j = 1; j <= k; j++) reach[i, j] = ((node[i], node[j]) in edge)
            for (x = 1; x <= k; x++) for (i = 1; i <= k; i++) if (reach[i, x])
                for (j = 1; j <= k; j++) if (reach[x, j]) reach[i, j] = 1
            for (i = 1; i <= k; i++) for (j = i + 1; j <= k; j++) if (reach[i, j] && reach[j, i]) {
                printf "check_layers: circle between %s and %s (%s folder is a tree)\n", node[i], node[j], fo > "/dev/stderr"
                bad = 1
            }
        }
        exit bad
    }' "$syms"
