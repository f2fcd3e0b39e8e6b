#!/usr/bin/env bash
# Solids (SolidBegin/SolidEnd) through the bake and the preview, and their
# malformed nesting.
#
# csg/solid.rib: a plastic sphere with a bite (a "difference" with a second
# sphere of its own plastic shader and colour, whose inner side is the cut
# face the camera sees) on a floor, lit by a shadow-mapped spot light (its
# map from the scene's own shadow pass, so it holds the cut solid) and a
# point light. It is rendered, baked and previewed after edits of the spot
# light's intensity and colour and of the point light's position, on the
# CPU and on the GPU; both must match `relight render --set` of the same
# edits within 0.1 % mean and 1 % max of the 8-bit range (the solid's
# visibility is recorded in the indirect framebuffer as the renderer hides
# it). The bake warns, at the solid, that the GPU's own shadow maps (when
# the spot light moves) hold the solid without its cut, and leaves the
# subtracted sphere out of the shadow geometry. Without an EGL
# context the GPU part skips (exit 77) once the rest has passed.
source "$(dirname "$0")/lib.sh"

max_mean_pct=0.1
max_max_pct=1.0
edits="--set key.intensity=35 --set key.lightcolor=1,0.7,0.5 --set fill.from=3,2,-3"

cp "$source_dir/tests/cli/csg/solid.rib" "$source_dir/tests/cli/csg/world.rib" \
	"$source_dir/tests/cli/csg/bad.rib" "$work/"

run "render" bash -c "cd '$work' && '$relight' render -q -o plain.exr solid.rib"
expect_status 0
expect_empty_stderr

# The solid is not its two spheres: without SolidBegin/SolidEnd the bite is
# a ball (in a folder of its own: its shadow pass writes its own map).
mkdir -p "$work/balls"
grep -v "Solid" "$work/world.rib" >"$work/balls/world.rib"
cp "$work/solid.rib" "$work/balls/"
run "render without the solid" bash -c "cd '$work/balls' && '$relight' render -q -o balls.exr solid.rib"
expect_status 0
run "the cut shows" "$relight" diff --json "$work/plain.exr" "$work/balls/balls.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["over_1pct"] > 100, d
' "$work/stdout" || fail "the difference renders as its two spheres: $(cat "$work/stdout")"

run "edited render" bash -c "cd '$work' && '$relight' render -q $edits -o ref.exr solid.rib"
expect_status 0
run "bake" bash -c "cd '$work' && '$relight' bake -q -o solid.shot.exr solid.rib"
expect_status 0
expect_stderr '^\./world\.rib:7: warning: the GPU.s shadow maps of this "difference" solid hold its surfaces without the cuts'

# The subtracted sphere casts no shadow geometry: fewer micropolygons than the two balls'.
run "bake without the solid" bash -c "cd '$work/balls' && '$relight' bake -q -o balls.shot.exr solid.rib"
expect_status 0
run "info" "$relight" info --json "$work/solid.shot.exr"
cp "$work/stdout" "$work/solid.info.json"
run "info without the solid" "$relight" info --json "$work/balls/balls.shot.exr"
checks=$((checks + 1))
python3 - "$work/solid.info.json" "$work/stdout" <<'PY' || fail "the subtracted sphere is in the shadow geometry"
import json, sys
a, b = (json.load(open(f))["shadow_quads"] for f in sys.argv[1:3])
print("shadow geometry: %d micropolygons with the solid, %d with both balls" % (a, b))
assert 0 < a < b, (a, b)
PY

run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $edits -o cpu.exr solid.shot.exr"
expect_status 0
expect_no_crash
expect_matches_render "preview --cpu" ref.exr cpu.exr "$max_mean_pct" "$max_max_pct"

# Malformed nesting: each a warning at its place, and the frame renders.
run "malformed" bash -c "cd '$work' && '$relight' render bad.rib"
expect_status 0
expect_no_crash
expect_stderr '^bad\.rib:5: warning: SolidEnd without a SolidBegin: ignored'
expect_stderr "^bad\.rib:7: warning: SolidBegin: unknown operation 'subtract'"
expect_stderr '^bad\.rib:11: warning: a primitive directly inside a "difference" solid \(SolidBegin at line 10\) is taken as a "primitive" solid of its own'
expect_stderr '^bad\.rib:14: warning: SolidBegin "union" inside a "primitive" solid'
expect_stderr '^bad\.rib:18: warning: SolidBegin is not closed by a SolidEnd before line 19'
expect_stderr '^bad\.rib:10: warning: SolidBegin is not closed by a SolidEnd before line 19'
expect_true "the frame is written" test -s "$work/bad.exr"
run "malformed, --strict" bash -c "cd '$work' && '$relight' render --strict -o strict.exr bad.rib"
expect_status 1
expect_stderr '^bad\.rib:5: error: SolidEnd without a SolidBegin: ignored \(an error under --strict\)'

run "EGL context" bash -c "cd '$work' && '$relight' preview -q $edits -o gpu.exr solid.shot.exr"
skip_without_gpu
expect_status 0
expect_no_crash
expect_matches_render "preview (GPU)" ref.exr gpu.exr "$max_mean_pct" "$max_max_pct"
finish
