#!/usr/bin/env bash
# The camera's lens and its motion through `relight render`, `relight bake`
# and `relight preview --cpu`:
#
#   - DepthOfField's bad arguments are errors at FILE:LINE (negative or zero
#     values, a focal distance not beyond the focal length, the wrong count,
#     the request inside the world); with an orthographic projection it is a
#     warning at its line and the frame renders in focus, exactly as without
#     it; DepthOfField alone, or an fstop of RI_INFINITY (1e38), is a pinhole;
#   - a depth-of-field scene and a moving-camera scene (with an object moving
#     too) bake and resolve on the CPU to the render within 0.1 % mean and
#     1 % maximum error of the 8-bit range, the acceptance line of every bake
#     (tests/cli/bake.sh): each pixel sample's hit, seen through its lens
#     position at its time, is what the indirect framebuffer records.
#
# The closed forms (the circle of confusion, the focal plane, a panning
# camera's ramp) are in tests/unit/test_lens.c; the GPU preview of these
# scenes is tests/cli/lens_gpu.sh.
source "$(dirname "$0")/lib.sh"

max_mean_pct=0.1
max_max_pct=1.0

# bad_dof NAME OPTIONS WORLD LINE MESSAGE: the scene fails with MESSAGE at LINE.
bad_dof() {
	printf 'Format 8 8 1\n%b\nDisplay "bad.exr" "file" "rgba"\nWorldBegin\n%b\nSphere 1 -1 1 360\nWorldEnd\n' \
		"$2" "$3" >"$work/bad.rib"
	run "$1" bash -c "cd '$work' && '$relight' render -q bad.rib"
	expect_status 1
	expect_no_crash
	expect_stderr "^bad.rib:$4: error: $5"
}
bad_dof "negative fstop" 'DepthOfField -2 0.5 4' '' 2 \
	"DepthOfField -2 0.5 4: fstop, focal length and focal distance must be positive"
bad_dof "zero focal length" 'DepthOfField 2 0 4' '' 2 "DepthOfField 2 0 4: .*must be positive"
bad_dof "negative focal distance" 'Projection "perspective"\nDepthOfField 2 0.5 -4' '' 3 \
	"DepthOfField 2 0.5 -4: .*must be positive"
bad_dof "focal distance inside the focal length" 'DepthOfField 2 0.5 0.4' '' 2 \
	"DepthOfField: a lens of focal length 0.5 cannot focus at 0.4"
bad_dof "two arguments" 'DepthOfField 2 0.5' '' 2 "DepthOfField expects 3 numbers, got 2"
bad_dof "a string argument" 'DepthOfField "wide" 0.5 4' '' 2 "DepthOfField expects 3 numbers, got 0"
bad_dof "inside the world" '' 'DepthOfField 2 0.5 4' 5 \
	"DepthOfField is an option: it must come before WorldBegin"

# The orthographic camera has no lens: a warning at the request, and the
# image equals the one without DepthOfField.
scene() {
	cat <<RIB
Format 32 24 1
PixelSamples 4 4
Projection "$1"
$2
Display "$3" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1 "from" [0 1 -1] "to" [0 0 0]
  Surface "plastic"
  Translate 0 0 5
  Sphere 0.8 -0.8 0.8 360
WorldEnd
RIB
}
scene orthographic "" plain.exr >"$work/plain.rib"
scene orthographic "DepthOfField 1 0.5 2" ortho.exr >"$work/ortho.rib"
run "orthographic: plain" bash -c "cd '$work' && '$relight' render -q plain.rib"
expect_status 0
run "orthographic with DepthOfField" bash -c "cd '$work' && '$relight' render -q ortho.rib"
expect_status 0
expect_stderr "^ortho.rib:4: warning: DepthOfField needs a perspective projection: the orthographic camera renders in focus"
run "orthographic: same image" "$relight" diff --json "$work/plain.exr" "$work/ortho.exr"
expect_status 0
expect_stdout '"max_pct": 0[,}]'

# DepthOfField alone and an infinite fstop are the pinhole camera.
scene perspective "" pin.exr >"$work/pin.rib"
scene perspective "DepthOfField" bare.exr >"$work/bare.rib"
scene perspective "DepthOfField 1e38 1 1" inf.exr >"$work/inf.rib"
scene perspective "DepthOfField 1 0.5 2" lens.exr >"$work/lens.rib"
for s in pin bare inf lens; do
	run "pinhole: $s" bash -c "cd '$work' && '$relight' render -q $s.rib"
	expect_status 0
	expect_empty_stderr
done
run "DepthOfField alone is a pinhole" "$relight" diff --json "$work/pin.exr" "$work/bare.exr"
expect_stdout '"max_pct": 0[,}]'
run "an infinite fstop is a pinhole" "$relight" diff --json "$work/pin.exr" "$work/inf.exr"
expect_stdout '"max_pct": 0[,}]'
run "a lens is not" "$relight" diff --json "$work/pin.exr" "$work/lens.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["max_pct"] > 10, d
' "$work/stdout" || fail "the lens does not blur"

# check_resolve NAME RIB: bake and CPU preview against the render.
check_resolve() {
	run "$1: render" bash -c "cd '$work' && '$relight' render -q -o ref.exr $2"
	expect_status 0
	expect_empty_stderr
	run "$1: bake" bash -c "cd '$work' && '$relight' bake -q -o r.shot.exr $2"
	expect_status 0
	run "$1: preview --cpu" bash -c "cd '$work' && '$relight' preview --cpu -o prev.exr r.shot.exr"
	expect_status 0
	expect_no_crash
	run "$1: diff" "$relight" diff --json "$work/ref.exr" "$work/prev.exr"
	expect_status 0
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("%s: preview --cpu vs render: mean %.4f %% max %.4f %%" % (sys.argv[2], d["mean_pct"], d["max_pct"]))
assert d["mean_pct"] < float(sys.argv[3]) and d["max_pct"] < float(sys.argv[4]), d
' "$work/stdout" "$1" "$max_mean_pct" "$max_max_pct" || fail "preview --cpu differs from the reference"
}

# tests/cli/lens/dof.rib: three spheres before, at and behind the focal plane
# (depth 4) on a floor, circles of confusion of about 4 pixels in front, 2.5
# at the back.
cp "$source_dir/tests/cli/lens/dof.rib" "$work/"
check_resolve "depth of field" dof.rib

# tests/cli/lens/pan.rib: a camera panning and turning over the shutter, a
# sphere moving against it.
cp "$source_dir/tests/cli/lens/pan.rib" "$work/"
check_resolve "camera motion" pan.rib

# Both at once: a moving camera with a lens.
sed -e 's/^Projection "perspective" "fov" 40$/Projection "perspective" "fov" 40\nDepthOfField 1 0.5 4/' \
    "$work/pan.rib" >"$work/both.rib"
checks=$((checks + 1))
grep -q DepthOfField "$work/both.rib" || fail "both.rib has no DepthOfField"
check_resolve "camera motion and depth of field" both.rib

finish
