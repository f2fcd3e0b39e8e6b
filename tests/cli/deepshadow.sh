#!/usr/bin/env bash
# Deep shadow maps through render, bake and preview. The scene
# (deepshadow/stack.rib): a deepshad shadow pass of three planes of
# opacities 0.3, 0.5 and 0.2 over the receiver, then the receiver lit by a
# shadowspot through the deep map. Checks:
#  - the render equals the unshadowed spot at 0.28 of the intensity (the
#    product of the transparencies) within 1 % relative, pixel by pixel;
#  - the deep map is readable by exrheader-style tools as an OpenEXR
#    (relight diff reads it) and a depth map of the same stack is not what
#    the deep map gives;
#  - the bake's CPU and GPU previews after a light intensity, colour and
#    position edit match `relight render --set` of the same edits within
#    0.1 % mean and 1 % max of the 8-bit range;
#  - a malformed deep map: shadow() gives the fill with a warning naming
#    the file; the frame still renders.
# Without an EGL context the GPU part skips the script (exit 77) once the
# rest has passed.
source "$(dirname "$0")/lib.sh"

cp "$source_dir/tests/cli/deepshadow/stack.rib" "$work/"
cd "$work" || exit 1

run "render" "$relight" render -q stack.rib
expect_status 0
expect_empty_stderr
expect_true "the deep map was written" test -s stack.dsm

# The unshadowed spot at 0.28 of the intensity (and no deep map to read).
sed -e 's/"shadowname" "stack.dsm"//' -e 's/"intensity" 40/"intensity" 11.2/' \
	-e 's/"stack.exr"/"open.exr"/' stack.rib >open.rib
checks=$((checks + 1))
grep -q '"intensity" 11.2' open.rib || fail "cannot edit stack.rib"
run "render without the map at 0.28 of the light" "$relight" render -q open.rib
expect_status 0
run "the product of the transparencies" "$relight" diff --json open.exr stack.exr
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("deep shadow vs 0.28 x unshadowed: max relative %.3g (limit 0.01)" % d["max_rel"])
assert d["max_rel"] <= 0.01, d
' "$work/stdout" || fail "the stack does not let 0.28 through: $(cat "$work/stdout")"

# A depth map of the same stack: all or nothing, so not the deep answer.
sed -e 's/"stack.dsm" "deepshad" "deepopacity"/"stack.z" "zfile" "z"/' \
	-e 's/^FrameBegin 2$/MakeShadow "stack.z" "stack.shd"\nFrameBegin 2/' \
	-e 's/"shadowname" "stack.dsm"/"shadowname" "stack.shd"/' \
	-e 's/"stack.exr"/"depth.exr"/' stack.rib >depth.rib
run "render with a depth map" "$relight" render -q depth.rib
expect_status 0
run "depth map vs deep map" "$relight" diff --json depth.exr stack.exr
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("depth map vs deep map: max relative %.3g (must differ)" % d["max_rel"])
assert d["max_rel"] > 0.5, d
' "$work/stdout" || fail "a depth map gives the deep answer: $(cat "$work/stdout")"

run "bake" "$relight" bake -q -o stack.shot.exr stack.rib
expect_status 0
expect_empty_stderr

edits=(--set 1.intensity=25 --set 1.lightcolor=1,0.6,0.4 --set 1.from=0.3,6,0.2)
run "render the edits" "$relight" render -q -o ref.exr "${edits[@]}" stack.rib
expect_status 0

run "preview --cpu" "$relight" preview -q --cpu -o cpu.exr "${edits[@]}" stack.shot.exr
expect_status 0
expect_empty_stderr
expect_matches_render "preview --cpu" ref.exr cpu.exr

# A malformed deep map (its version changed): a warning naming the file, the
# frame renders with the fill (no shadow).
python3 - stack.dsm bad.dsm <<'PY'
import sys
data = open(sys.argv[1], "rb").read()
assert data.count(b"relight-dsm 1 ") == 1, "no deepshadow attribute"
open(sys.argv[2], "wb").write(data.replace(b"relight-dsm 1 ", b"relight-dsm 7 "))
PY
sed -n '/^FrameBegin 2$/,$p' stack.rib | sed -e 's/"stack.dsm"/"bad.dsm"/' -e 's/"stack.exr"/"bad.exr"/' >bad.rib
run "render with a malformed deep map" "$relight" render -q bad.rib
expect_no_crash
expect_stderr "bad.dsm: error: not a valid deep shadow map: an unknown version"
expect_true "the frame is still written" test -s bad.exr

run "EGL context" "$relight" preview -q -o gpu.exr "${edits[@]}" stack.shot.exr
skip_without_gpu
expect_status 0
expect_no_crash
expect_matches_render "preview (GPU)" ref.exr gpu.exr
run "GPU vs CPU preview" "$relight" diff --fail-rel 1e-4 cpu.exr gpu.exr
expect_status 0
finish
