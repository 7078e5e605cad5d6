#!/bin/sh
# Sizes, as STYLE.md sets them: no C source or header of src/ and include/
# over 600 lines, no function over 80 lines (from the first line of its
# signature to its closing brace).  The function scan relies on the
# repository's .clang-format (bodies close with "}" in column 0; checked
# beside this in CI), so plain awk is enough: no compiler, no ctags.
#   scripts/check_sizes.sh            check; list what is over and fail
#   scripts/check_sizes.sh --report   also print the ten longest functions
set -eu
cd "$(dirname "$0")/.."
MAX_FILE=600
MAX_FUNC=80
files=$(git ls-files 'src/*.c' 'src/*.h' 'include/*.h' 2>/dev/null || find src include -name '*.[ch]')
bad=0
for f in $files; do
    n=$(wc -l <"$f")
    if [ "$n" -gt "$MAX_FILE" ]; then
        echo "check_sizes: $f: $n lines (at most $MAX_FILE)" >&2
        bad=1
    fi
done
# One line per function: "lines file:line name".
# shellcheck disable=SC2086
funcs=$(awk '
    FNR == 1 { pending = 0; inbody = 0 }
    inbody {
        if ($0 ~ /^}/) {
            inbody = 0
            if ($0 ~ /^}[ \t]*$/ && sig ~ /\(/ && sig !~ /=/) {
                name = sig; sub(/\(.*/, "", name); sub(/.*[ *]/, "", name)
                print FNR - start + 1, FILENAME ":" start, name
            }
        }
        next
    }
    /^[A-Za-z_]/ && !pending { pending = 1; start = FNR; sig = "" }
    pending {
        sig = sig $0 " "
        if ($0 ~ /;[ \t]*$/ || $0 ~ /}[ \t;]*$/) { pending = 0; next }
        if ($0 ~ /{[ \t]*$/) { pending = 0; inbody = 1 }
    }
' $files)
over=$(printf '%s\n' "$funcs" | awk -v m="$MAX_FUNC" '$1 > m')
if [ -n "$over" ]; then
    printf '%s\n' "$over" | while read -r n at name; do
        echo "check_sizes: $at: $name is $n lines (at most $MAX_FUNC)" >&2
    done
    bad=1
fi
if [ "${1:-}" = "--report" ]; then
    printf '%s\n' "$funcs" | sort -rn | head -10
fi
[ "$bad" = 0 ] || exit 1
