#!/usr/bin/env bash
# The error policy of relight render and relight bake (docs/renderer.md,
# "Errors and warnings"): what relight does not support is a warning with
# FILE:LINE and the frame renders (exit 0); a malformed primitive is an error
# that drops it, the rest renders (exit 1); --strict makes every warning an
# error; each message is printed once per place, the repeats counted in the
# last line; shading warnings from many threads come as whole lines, once.
source "$(dirname "$0")/lib.sh"

scenes="$source_dir/tests/cli/error_policy"
cp "$scenes/unsupported.rib" "$scenes/sphere.rib" "$work/"

# identical A.exr B.exr: relight diff finds no difference in colour or alpha.
identical() {
	"$relight" diff "$work/$1" "$work/$2" >"$work/diff.txt" 2>&1 &&
		grep -qE '^  PSNR \(sRGB\) +identical' "$work/diff.txt" &&
		grep -qE '^  alpha +RMSE 0,' "$work/diff.txt"
}

# ---- every unsupported request of RiSpec 3.2: one warning each, the rest renders ----
requests="10:ColorSamples 12:ClippingPlane 14:ErrorHandler
15:Perspective 19:AreaLightSource 21:Resource 22:Shader 23:DisplayChannel 24:Bound
25:Deformation 26:ArchiveRecord 27:ScopedCoordinateSystem 28:MakeBump"
nrequests=$(echo $requests | wc -w)

run "sphere alone" bash -c "cd '$work' && '$relight' render sphere.rib"
expect_status 0
expect_stderr '^relight render: 1 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 0 errors$'

run "unsupported requests" bash -c "cd '$work' && '$relight' render unsupported.rib"
expect_no_crash
expect_status 0
for r in $requests; do
	expect_stderr "^unsupported.rib:${r%%:*}: warning: ${r#*:} is not supported: ignored$"
done
checks=$((checks + 1))
n=$(grep -c 'warning:' "$work/stderr")
[ "$n" -eq "$nrequests" ] || fail "$n warnings, expected one per request: $nrequests"
checks=$((checks + 1))
! grep -q ': error:' "$work/stderr" || fail "an error among the warnings"
expect_stderr "^relight render: 1 of 1 frame rendered, $nrequests warnings \(0 repeats not shown\), 0 errors$"
expect_true "the image differs from sphere.rib's" identical sphere.exr unsupported.exr

rm -f "$work/unsupported.exr"
run "unsupported requests, --strict" bash -c "cd '$work' && '$relight' render --strict unsupported.rib"
expect_no_crash
expect_status 1
expect_stderr '^unsupported.rib:10: error: ColorSamples is not supported: ignored \(an error under --strict\)$'
checks=$((checks + 1))
! grep -q 'warning:' "$work/stderr" || fail "a warning under --strict"
checks=$((checks + 1))
[ ! -e "$work/unsupported.exr" ] || fail "--strict wrote the image"

# ---- a shader parameter the shader does not declare, and a misspelt request ----
sed -e 's/^  Surface "plastic"$/  Surface "plastic" "Kdd" 0.3 "Ks" 0.5/' \
	-e 's/^WorldEnd$/  Sphre 1 -1 1 360\nWorldEnd/' \
	-e 's/sphere.exr/param.exr/' "$work/sphere.rib" >"$work/param.rib"
sed -e 's/^  Surface "plastic"$/  Surface "plastic" "Ks" 0.5/' \
	-e 's/sphere.exr/ks.exr/' "$work/sphere.rib" >"$work/ks.rib"
run "ks" bash -c "cd '$work' && '$relight' render -q ks.rib"
expect_status 0
run "undeclared shader parameter" bash -c "cd '$work' && '$relight' render param.rib"
expect_no_crash
expect_status 0
expect_stderr "^param.rib:10: warning: shader 'plastic' has no parameter 'Kdd': ignored$"
expect_stderr "^param.rib:12: warning: unknown request 'Sphre' ignored; did you mean 'Sphere'\?$"
expect_stderr '^relight render: 1 of 1 frame rendered, 2 warnings \(0 repeats not shown\), 0 errors$'
expect_true "the image differs from the one without the parameter" identical ks.exr param.exr

# ---- a malformed primitive among good ones: dropped, the rest renders, exit 1 ----
cat >"$work/polys.rib" <<'RIB'
Format 40 30 1
PixelSamples 2 2
Projection "perspective" "fov" 40
Display "polys.exr" "file" "rgba"
WorldBegin
  Translate 0 0 5
  Surface "constant"
  Polygon "P" [-2 -1 0  -1 -1 0  -1 1 0  -2 1 0]
  Polygon "P" [-0.5 -1 0  0.5 -1 0  0.5 1 0  -0.5]
  Polygon "P" [1 -1 0  2 -1 0  2 1 0  1 1 0]
WorldEnd
RIB
sed -e '9d' -e 's/polys.exr/good.exr/' "$work/polys.rib" >"$work/good.rib"
run "good polygons" bash -c "cd '$work' && '$relight' render -q good.rib"
expect_status 0
run "malformed polygon" bash -c "cd '$work' && '$relight' render polys.rib"
expect_no_crash
expect_status 1
expect_stderr '^polys.rib:9: error: Polygon: "P" has 10 values, not a multiple of 3$'
expect_stderr '^wrote polys.exr$'
expect_stderr '^relight render: 1 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 1 error, 1 primitive dropped$'
expect_true "the others did not render as without it" identical good.exr polys.exr

# Primitives whose arguments the reader refuses (too few numbers, an array
# for a number, a motion sample short of its numbers, a parameter list cut
# off): each dropped, and the rest renders as without them.
cat >"$work/args.rib" <<'RIB'
Format 40 30 1
PixelSamples 2 2
Projection "perspective" "fov" 40
Display "args.exr" "file" "rgba"
WorldBegin
  Translate 0 0 5
  Surface "constant"
  Polygon "P" [-2 -1 0  -1 -1 0  -1 1 0  -2 1 0]
  Sphere 1 -1
  Cone 1 [1 2] 3
  MotionBegin [0 1]
    Sphere 0.5 -0.5 0.5 360
    Sphere 0.5 -0.5
  MotionEnd
  Polygon "P" [1 -1 0  2 -1 0  2 1 0  1 1 0]
  Polygon "P" [-0.5 -1 0  0.5 -1 0
WorldEnd
RIB
sed -e '9,14d' -e '16d' -e 's/args.exr/args_good.exr/' "$work/args.rib" >"$work/args_good.rib"
run "good primitives" bash -c "cd '$work' && '$relight' render -q args_good.rib"
expect_status 0
run "malformed arguments" bash -c "cd '$work' && '$relight' render args.rib"
expect_no_crash
expect_status 1
expect_stderr '^args.rib:9: error: Sphere expects 4 numbers before its parameter list, got 2$'
expect_stderr '^args.rib:10: error: Cone expects 3 numbers'
expect_stderr '^args.rib:13: error: Sphere expects 4 numbers before its parameter list, got 2$'
expect_stderr '^args.rib:17: error: .*inside an array'
expect_stderr '^relight render: 1 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 4 errors, 4 primitives dropped$'
expect_true "the others did not render as without them" identical args_good.exr args.exr

# ---- one line per cause and place: an archive read 10000 times ----
mkdir -p "$work/loop"
printf 'Shader "plastic" "co"\nSurface "plastic" "Kdd" 1\n' >"$work/loop/fog.rib"
{
	printf 'Format 16 16 1\nDisplay "loop.exr" "file" "rgba"\nWorldBegin\nTranslate 0 0 5\n'
	for i in $(seq 10000); do printf 'ReadArchive "fog.rib"\n'; done
	printf 'Sphere 1 -1 1 360\nWorldEnd\n'
} >"$work/loop/loop.rib"
run "repeats" bash -c "cd '$work/loop' && '$relight' render loop.rib"
expect_no_crash
expect_status 0
checks=$((checks + 1))
n=$(grep -c 'warning:' "$work/stderr")
[ "$n" -eq 2 ] || fail "$n warning lines, expected 2 (one per place)"
expect_stderr '^(\./)?fog.rib:1: warning: Shader is not supported: ignored$'
expect_stderr "^(\./)?fog.rib:2: warning: shader 'plastic' has no parameter 'Kdd': ignored$"
expect_stderr '^relight render: 1 of 1 frame rendered, 2 warnings \(19998 repeats not shown\), 0 errors$'

# ---- a primitive variable that does not fit its shader parameter: a warning at it ----
sed -e 's/^  Sphere 1 -1 1 360$/  Sphere 1 -1 1 360 "uniform color Kd" [1 0 0]/' \
	-e 's/sphere.exr/kd.exr/' "$work/sphere.rib" >"$work/kd.rib"
run "primitive variable of another type" bash -c "cd '$work' && '$relight' render -t 4 kd.rib"
expect_no_crash
expect_status 0
expect_stderr "^kd.rib:11: warning: Sphere: primitive variable 'Kd' \(color\) does not fit parameter 'Kd' of shader 'plastic' \(float\): ignored$"
checks=$((checks + 1))
! grep -q ': error:' "$work/stderr" || fail "the shading executor refused it"
expect_true "the image differs from the one without it" identical sphere.exr kd.exr

# ---- shading warnings from many threads: whole lines, each place once ----
cat >"$work/warnme.sl" <<'SL'
surface warnme(float Kd = 1)
{
	float x = comp(Cs, 3 + floor(s));
	Oi = Os;
	Ci = Os * Kd * color(x, x, x);
}
SL
{
	printf 'Option "searchpath" "shader" "%s:@"\n' "$work"
	printf 'Format 64 64 1\nPixelSamples 1 1\nProjection "perspective" "fov" 40\n'
	printf 'Display "warn.exr" "file" "rgba"\nWorldBegin\nTranslate 0 0 12\n'
	# 400 shader instances: every thread's executor of each warns at the same place
	for i in $(seq 0 399); do
		printf 'AttributeBegin\nTranslate %s %s 0\nSurface "warnme" "Kd" %s\n' \
			"$(((i % 20 - 10) * 5))e-1" "$((((i / 20) - 10) * 5))e-1" "1.$i"
		printf 'Sphere 0.2 -0.2 0.2 360\nAttributeEnd\n'
	done
	printf 'WorldEnd\n'
} >"$work/warn.rib"
whole='^(.*/warnme.sl:3:[0-9]+: warning: comp: index out of range \(clamped\)|wrote warn.exr|frame 1: .*|relight render: .*)$'
for k in 1 2 3; do
	run "threads, run $k" bash -c "cd '$work' && '$relight' render -t 64 --bucket 4 warn.rib"
	expect_no_crash
	expect_status 0
	checks=$((checks + 1))
	! grep -vqE "$whole" "$work/stderr" || fail "a partial or interleaved line: $(grep -vE "$whole" "$work/stderr" | head -1)"
	checks=$((checks + 1))
	n=$(grep -c 'warning: comp' "$work/stderr")
	[ "$n" -eq 1 ] || fail "the shading warning printed $n times, expected once"
	expect_stderr '^relight render: 1 of 1 frame rendered, 1 warning \([0-9]+ repeats not shown\), 0 errors$'
done
run "shading warning, --strict" bash -c "cd '$work' && '$relight' render -q -t 4 --strict warn.rib"
expect_status 1
expect_stderr '^relight render: error: the shaders warned 1 time: an error under --strict$'

# ---- what would change the meaning of the rest is refused ----
sed -e 's/^  Sphere 1 -1 1 360$/  IfBegin "false"\n  Sphere 1 -1 1 360\n  IfEnd/' \
	-e 's/sphere.exr/if.exr/' "$work/sphere.rib" >"$work/if.rib"
run "conditional RIB" bash -c "cd '$work' && '$relight' render if.rib"
expect_status 1
expect_stderr '^if.rib:11: error: IfBegin is not supported, and the frame would be wrong without it$'
expect_stderr '^relight render: 0 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 2 errors$'
checks=$((checks + 1))
[ ! -e "$work/if.exr" ] || fail "the frame was rendered"

# ---- relight bake: warnings bake, --strict does not ----
run "bake with warnings" bash -c "cd '$work' && '$relight' bake -o warned.shot.exr unsupported.rib"
expect_no_crash
expect_status 0
expect_stderr '^unsupported.rib:21: warning: Resource is not supported: ignored$'
expect_stderr "^unsupported.rib: $nrequests warnings \(0 repeats not shown\), 0 errors, 0 primitives dropped$"
checks=$((checks + 1))
[ -s "$work/warned.shot.exr" ] || fail "no shot written"
run "bake --strict" bash -c "cd '$work' && '$relight' bake --strict -o strict.shot.exr unsupported.rib"
expect_no_crash
expect_status 1
expect_stderr '^unsupported.rib:21: error: Resource is not supported: ignored \(an error under --strict\)$'
checks=$((checks + 1))
[ ! -e "$work/strict.shot.exr" ] || fail "--strict baked the shot"

run "bake --strict, a shading warning" bash -c "cd '$work' && '$relight' bake -q -t 4 --strict -o warn.shot.exr warn.rib"
expect_no_crash
expect_status 1
expect_stderr '^relight bake: error: the shaders warned 1 time: an error under --strict$'

run "bake, a malformed polygon" bash -c "cd '$work' && '$relight' bake -o polys.shot.exr polys.rib"
expect_no_crash
expect_status 1
expect_stderr '^polys.rib:9: error: Polygon: "P" has 10 values, not a multiple of 3$'
expect_stderr '^polys.rib: 0 warnings \(0 repeats not shown\), 1 error, 1 primitive dropped$'
checks=$((checks + 1))
[ -s "$work/polys.shot.exr" ] || fail "the rest was not baked"

# ---- the renderer's own warnings: counted, and errors under --strict ----
# A polygon through the eye: the pieces of it that cross the eye plane there
# cannot be projected and are left out, with a warning.
cat >"$work/eye.rib" <<'RIB'
Format 32 24 1
Display "eye.exr" "file" "rgba"
Projection "perspective" "fov" 60
WorldBegin
  Surface "constant"
  Polygon "P" [-1 -1 -1  1 -1 -1  1 1 1  -1 1 1]
  Sphere 1 -1 1 360
WorldEnd
RIB
run "eye plane" bash -c "cd '$work' && '$relight' render eye.rib"
expect_no_crash
expect_status 0
expect_stderr '^relight: warning: [0-9]+ pieces crossing the eye plane were dropped$'
expect_stderr '^relight render: 1 of 1 frame rendered, 1 warning \(0 repeats not shown\), 0 errors$'
run "eye plane, --strict" bash -c "cd '$work' && '$relight' render --strict eye.rib"
expect_status 1
expect_stderr 'an error under --strict$'
run "eye plane, bake --strict" bash -c "cd '$work' && '$relight' bake --strict -o eye.shot.exr eye.rib"
expect_status 1
expect_stderr 'an error under --strict$'

# ---- documented ----
run "render --help" "$relight" render --help
expect_stdout '--strict'
expect_stdout '^Exit status: 0 when every frame rendered, warnings or not'
run "bake --help" "$relight" bake --help
expect_stdout '--strict'

finish
