#!/bin/bash
# The README's two renders, regenerated with the commands its caption names:
#   bench/readme_figures.sh [BUILD]      (default ./build)
# docs/render_J01.png:    sepbrdf render -J 1 -s 192 --exposure peak (the default gold)
# docs/render_io_J04.png: the same on the lecture's plain theta-phi grid at J = 4
#                         (--param io --form f --unweighted)
# Prints each render's table (PSNR in dB, as the caption quotes it).
set -eu
root=$(cd "$(dirname "$0")/.." && pwd)
build=${1:-$root/build}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$build/sepbrdf" render -J 1 -s 192 --exposure peak -o "$work/j1"
"$build/sepbrdf" render --param io --form f --unweighted -J 4 -s 192 --exposure peak -o "$work/io4"
cp "$work/j1/render_J01.png" "$root/docs/render_J01.png"
cp "$work/io4/render_J04.png" "$root/docs/render_io_J04.png"
echo "wrote docs/render_J01.png and docs/render_io_J04.png"
