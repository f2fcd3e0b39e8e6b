#!/usr/bin/env bash
# `relight render`: its help, its options, a small scene end to end, and bad
# scenes ending in `FILE:LINE: error:` with exit status 1 (never a crash), and
# what relight ignores ending in `FILE:LINE: warning:` with exit status 0.
source "$(dirname "$0")/lib.sh"

run "help" "$relight" render --help
expect_status 0
expect_stdout "^usage: relight render \[OPTIONS\] SCENE.rib"
expect_stdout "--crop X0 X1 Y0 Y1"

run "listed in relight --help" "$relight" --help
expect_stdout "render +Render a RIB scene"

run "no scene" "$relight" render
expect_status 2
expect_stderr "no scene file"

run "unknown option" "$relight" render --frobnicate x.rib
expect_status 2
expect_stderr "unknown option '--frobnicate'"

run "bad threads" "$relight" render --threads 0 x.rib
expect_status 2
expect_stderr "--threads needs a number"

run "bad crop" "$relight" render --crop 10 5 0 4 x.rib
expect_status 2
expect_stderr "is empty"

run "missing scene" "$relight" render "$work/none.rib"
expect_status 1
expect_stderr "cannot read '$work/none.rib'"

cat >"$work/ok.rib" <<'RIB'
Format 32 24 1
PixelSamples 2 2
Display "ok.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1
  Surface "plastic"
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
RIB
run "renders" bash -c "cd '$work' && '$relight' render ok.rib"
expect_no_crash
expect_status 0
expect_stderr "^wrote ok.exr"
expect_stderr "micropolygons shaded, [0-9]+ subpixel samples, peak memory"
checks=$((checks + 1))
[ -s "$work/ok.exr" ] || fail "ok.exr not written"
if command -v exrheader >/dev/null 2>&1; then
	run "exrheader reads it" exrheader "$work/ok.exr"
	expect_status 0
	expect_stdout "worldToCamera"
fi

run "-o overrides the display" bash -c "cd '$work' && '$relight' render -q -o other.exr ok.rib"
expect_status 0
expect_empty_stdout
checks=$((checks + 1))
[ -s "$work/other.exr" ] || fail "other.exr not written"

# -o names the image of the beauty frame; a shadow pass keeps its map's name.
cat >"$work/pass.rib" <<'RIB'
FrameBegin 1
  Format 16 16 1
  Display "pass.z" "zfile" "z"
  WorldBegin
    Translate 0 0 5
    Sphere 1 -1 1 360
  WorldEnd
FrameEnd
FrameBegin 2
  Format 16 16 1
  Display "beauty.exr" "file" "rgba"
  WorldBegin
    Translate 0 0 5
    Sphere 1 -1 1 360
  WorldEnd
FrameEnd
RIB
run "-o with a shadow pass" bash -c "cd '$work' && '$relight' render -q -o image.exr pass.rib"
expect_status 0
checks=$((checks + 1))
[ -s "$work/pass.z" ] && [ -s "$work/image.exr" ] && [ ! -e "$work/beauty.exr" ] ||
	fail "-o renamed the shadow pass's map or missed the image"

run "--crop" bash -c "cd '$work' && '$relight' render -q --crop 0 8 0 8 -o crop.exr ok.rib"
expect_status 0

# check_bad DESCRIPTION LINE MESSAGE RIB-TEXT: exit 1, FILE:LINE: error: MESSAGE.
check_bad() {
	printf '%s' "$4" >"$work/bad.rib"
	run "$1" bash -c "cd '$work' && '$relight' render -q bad.rib"
	expect_no_crash
	expect_status 1
	expect_stderr "bad.rib:$2: error: .*$3"
}

check_bad "argument count" 2 "Sphere" \
	$'WorldBegin\nSphere 1 -1\nWorldEnd\n'
check_bad "unbalanced block" 3 "AttributeEnd" \
	$'WorldBegin\nTransformBegin\nAttributeEnd\nWorldEnd\n'
check_bad "missing shader" 2 "cannot find shader 'nosuchshader'" \
	$'WorldBegin\nSurface "nosuchshader"\nSphere 1 -1 1 360\nWorldEnd\n'
check_bad "NaN" 2 "" \
	$'WorldBegin\nSphere nan -1 1 360\nWorldEnd\n'
check_bad "truncated" 2 "" \
	$'WorldBegin\nPolygon "P" [0 0 1  1 0 1\n'

# check_warned DESCRIPTION LINE MESSAGE RIB-TEXT: exit 0, FILE:LINE: warning: MESSAGE
# (what relight ignores; tests/cli/error_policy.sh has the policy).
check_warned() {
	printf '%s' "$4" >"$work/warned.rib"
	run "$1" bash -c "cd '$work' && '$relight' render -q -o warned.exr warned.rib"
	expect_no_crash
	expect_status 0
	expect_stderr "warned.rib:$2: warning: .*$3"
}

check_warned "unknown request" 2 "unknown request 'Sphree' ignored; did you mean 'Sphere'" \
	$'WorldBegin\nSphree 1 -1 1 360\nWorldEnd\n'
check_warned "unknown shader parameter" 2 "no parameter 'Kdd'" \
	$'WorldBegin\nSurface "plastic" "Kdd" 1\nSphere 1 -1 1 360\nWorldEnd\n'

# Garbage and a huge array: clean errors.
python3 -c '
import random, sys
r = random.Random(7)
sys.stdout.buffer.write(bytes(r.randrange(256) for _ in range(65536)))
' >"$work/garbage.rib"
run "garbage" "$relight" render -q "$work/garbage.rib"
expect_no_crash
expect_status 1

finish
