#!/usr/bin/env bash
# examples/geometry, the shot of every production primitive (a subdivision
# surface, a CSG difference, a trimmed NuPatch, a Blobby, the teapot through a
# DelayedReadArchive, Curves and Points), all casting the shadow-mapped spot
# light's shadow: rendered, baked, and previewed after light edits (the spot's
# intensity and colour, the point light's position and intensity) on the CPU
# and on the GPU. Each preview matches `relight render --set` of the same edits
# within 0.1 % mean and 1 % max of the 8-bit range, colour and alpha; the GPU
# matches the CPU within 1e-4 relative. The shot holds shadow geometry of every
# primitive kind. Without an EGL context the GPU part skips (exit 77).
source "$(dirname "$0")/lib.sh"
# A hang guard: the scene renders and bakes in seconds, several times that
# under AddressSanitizer on a loaded machine.
limit=${RELIGHT_CLI_TIMEOUT:-300}

cp -r "$source_dir/examples/geometry/"* "$work/"
sets="--set 2.intensity=30 --set 2.lightcolor=1,0.8,0.6 --set 3.from=-1,4,1 --set 3.intensity=8"

run "render" bash -c "cd '$work' && '$relight' render -q -o plain.exr geometry.rib"
expect_status 0
expect_empty_stderr
run "render --set" bash -c "cd '$work' && '$relight' render -q $sets -o ref.exr geometry.rib"
expect_status 0
run "the edits show" "$relight" diff --json "$work/plain.exr" "$work/ref.exr"
checks=$((checks + 1))
python3 -c 'import json, sys; assert json.load(open(sys.argv[1]))["max_pct"] > 5' "$work/stdout" ||
	fail "the edits made no difference"

run "bake" bash -c "cd '$work' && '$relight' bake -q -o geometry.shot.exr geometry.rib"
expect_status 0
expect_no_crash
# The solid's warning (the GPU's own maps hold it uncut) is the one message expected.
checks=$((checks + 1))
n=$(grep -vc 'warning: the GPU.s shadow maps of this "difference" solid' "$work/stderr")
[ "$n" -eq 0 ] || fail "the bake said more than the solid's warning"
run "info" "$relight" info --json "$work/geometry.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("shot: %d shadow micropolygons" % d["shadow_quads"])
assert d["shadow_quads"] > 10000, d
' "$work/stdout" || fail "the shot has little or no shadow geometry"

run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $sets -o cpu.exr geometry.shot.exr"
expect_status 0
expect_no_crash
expect_matches_render "preview --cpu" ref.exr cpu.exr

run "preview (GPU)" bash -c "cd '$work' && '$relight' preview -q $sets -o gpu.exr geometry.shot.exr"
skip_without_gpu
expect_status 0
expect_no_crash
expect_matches_render "preview (GPU)" ref.exr gpu.exr
run "GPU vs CPU" "$relight" diff --json "$work/cpu.exr" "$work/gpu.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("GPU vs CPU: max relative %.3g (limit 1e-4)" % d["max_rel"])
assert d["max_rel"] <= 1e-4, d
' "$work/stdout" || fail "the GPU and CPU previews differ"
finish
