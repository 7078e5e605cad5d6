#!/bin/sh
# The public boundary: libsepbrdf.so exports exactly the functions the
# public headers declare with SB_API (include/sepbrdf/*.h, stable, and
# include/sepbrdf/experimental/*.h), nothing more and nothing less.
#   scripts/check_exports.sh build/libsepbrdf.so [include/sepbrdf]
# Prints the difference and exits 1 when the two lists differ.
set -eu
lib=${1:?usage: check_exports.sh LIBRARY [HEADER_DIR]}
dir=${2:-$(dirname "$0")/../include/sepbrdf}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Declared: every SB_API prototype (SB_API, the return type and the name
# start one line), comments dropped first.
cat "$dir"/*.h "$dir"/experimental/*.h |
    sed -e 's|/\*.*\*/||g' | grep -v '^ *#' |
    grep -o 'SB_API[^(]*(' |
    sed -e 's/($//' -e 's/.*[ *]//' | sort -u >"$tmp/declared"
# A prototype without SB_API is a mistake too: the library would hide it.
cat "$dir"/*.h "$dir"/experimental/*.h | sed -e 's|/\*.*\*/||g' |
    grep -E '^[A-Za-z_][A-Za-z0-9_ *]*[ *]sb_[a-z0-9_]+\(' |
    grep -vE '^(SB_API|typedef|static|#)' >"$tmp/unmarked" || true
# Exported: the library's defined dynamic symbols (the loader's own _init,
# _fini and version nodes aside).
nm -D --defined-only "$lib" | awk '$2 ~ /^[TDBRVWi]$/ {print $3}' | sed 's/@.*//' |
    grep -vE '^(_init|_fini|_edata|_end|__bss_start)$' | sort -u >"$tmp/exported"

status=0
if [ -s "$tmp/unmarked" ]; then
    echo "check_exports: prototypes without SB_API in $dir:" >&2
    cat "$tmp/unmarked" >&2
    status=1
fi
if ! cmp -s "$tmp/declared" "$tmp/exported"; then
    echo "check_exports: exported but not declared (+), declared but not exported (-):" >&2
    comm -13 "$tmp/declared" "$tmp/exported" | sed 's/^/+ /' >&2
    comm -23 "$tmp/declared" "$tmp/exported" | sed 's/^/- /' >&2
    status=1
fi
[ $status -eq 0 ] && echo "check_exports: $(wc -l <"$tmp/exported") functions exported, as declared"
exit $status
