#!/usr/bin/env bash
# The reference renderer on every example scene: render time, micropolygons
# shaded, subpixel samples and peak memory, from `relight render`'s summary.
#   bench_render.sh RELIGHT_BINARY SOURCE_DIR [THREADS]
set -euo pipefail
relight=${1:?usage: bench_render.sh RELIGHT SOURCE_DIR [THREADS]}
src=${2:?usage: bench_render.sh RELIGHT SOURCE_DIR [THREADS]}
threads=${3:-0}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
targs=()
[ "$threads" != 0 ] && targs=(--threads "$threads")
printf '%-10s %-6s %10s %8s %14s %16s %10s\n' example frame seconds grids micropolygons \
	subpixel-samples "peak MB"
for rib in "$src"/examples/*/*.rib; do
	name=$(basename "$rib" .rib)
	mkdir -p "$work/$name"
	out=$(cd "$work/$name" && "$relight" render "${targs[@]}" "$rib" 2>&1) || {
		printf '%s\n' "$out" >&2
		echo "bench_render: $name failed" >&2
		exit 1
	}
	printf '%s\n' "$out" | sed -n 's/^frame \([0-9]*\): \([0-9.]*\) s, \([0-9]*\) grids, \([0-9]*\) micropolygons shaded, \([0-9]*\) subpixel samples, peak memory \([0-9.]*\) MB$/\1 \2 \3 \4 \5 \6/p' |
	while read -r frame secs grids mp samples mem; do
		printf '%-10s %-6s %10s %8s %14s %16s %10s\n' "$name" "$frame" "$secs" "$grids" "$mp" \
			"$samples" "$mem"
	done
done
