#!/bin/sh
# Apply the repository's .clang-format to every tracked C source and header,
# or, with --check, list the files that differ and fail.
set -eu
cd "$(dirname "$0")/.."
files=$(git ls-files '*.c' '*.h' 2>/dev/null || find src include tests bench fuzz examples -name '*.[ch]')
if [ "${1:-}" = "--check" ]; then
    # shellcheck disable=SC2086
    clang-format --dry-run --Werror $files
else
    # shellcheck disable=SC2086
    clang-format -i $files
fi
