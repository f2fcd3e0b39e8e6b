#!/usr/bin/env bash
# Scene semantics through render, bake and preview: a primitive variable
# bound to a shader parameter declared varying, and lights declared before
# WorldBegin and FrameBegin. Each renders without an error, and the bake
# resolved by `relight preview --cpu` (and by the GPU preview where there is
# an EGL context) matches `relight render` within 0.1 % mean and 1 % max of
# the 8-bit range (as tests/cli/bake.sh does for the examples). The closed
# forms are in tests/unit/test_render.c.
source "$(dirname "$0")/lib.sh"

# A lit surface whose colour is a varying parameter, and the same surface
# taking its colour from Cs: the same primitive variable under either name
# is the same image.
cat >"$work/vmatte.sl" <<'SL'
surface vmatte(varying color vc = 0)
{
	normal Nf = faceforward(normalize(N), I);
	Oi = Os;
	Ci = Os * vc * (0.2 + diffuse(Nf));
}
SL
cat >"$work/csmatte.sl" <<'SL'
surface csmatte()
{
	normal Nf = faceforward(normalize(N), I);
	Oi = Os;
	Ci = Os * Cs * (0.2 + diffuse(Nf));
}
SL
scene() { # NAME SURFACE VARIABLE
	cat >"$work/$1.rib" <<RIB
Option "searchpath" "shader" "$work:@"
Format 40 30 1
PixelSamples 4 4
Projection "perspective" "fov" 40
Display "$1.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1 "from" [1 1 -1] "to" [0 0 0]
  LightSource "pointlight" 2 "from" [0 2 2] "intensity" 4
  Translate 0 0 6
  Surface "$2"
  AttributeBegin
    Translate -1.2 0 0
    Polygon "P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0]
      "varying color $3" [1 0 0  0 1 0  0 0 1  1 1 1]
  AttributeEnd
  AttributeBegin
    Translate 1.2 0 0
    Rotate 60 1 0 0
    Patch "bilinear" "P" [-1 -1 0  1 -1 0  -1 1 0  1 1 0]
      "vertex color $3" [1 1 0  0 1 1  1 0 1  0.2 0.4 0.8]
  AttributeEnd
  Sphere 0.6 -0.6 0.6 360 "varying color $3" [1 0 0  0 1 0  0 0 1  1 1 0]
WorldEnd
RIB
}
scene varying vmatte vc
scene cs csmatte Cs

# Lights before FrameBegin and before WorldBegin, in camera space; the second
# frame has the first light alone.
cat >"$work/prelights.rib" <<'RIB'
Format 40 30 1
PixelSamples 4 4
Projection "perspective" "fov" 40
LightSource "distantlight" 1 "intensity" 0.8 "to" [0 -1 1]
FrameBegin 1
  LightSource "spotlight" 2 "from" [1 1 0] "to" [0 0 6] "intensity" 30 "coneangle" 0.4
  Rotate 20 0 1 0
  Translate 0 0 6
  WorldBegin
    Surface "plastic"
    Sphere 1.5 -1.5 1.5 360
    AttributeBegin
      Surface "matte"
      Translate 0 -1.5 0
      Rotate 90 1 0 0
      Disk 0 4 360
    AttributeEnd
  WorldEnd
FrameEnd
RIB

expect_same() { # WHAT A.exr B.exr
	run "$1: diff" "$relight" diff --json "$2" "$3"
	expect_status 0
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("%s: mean %.4f %%, max %.4f %%" % (sys.argv[2], d["mean_pct"], d["max_pct"]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
' "$work/stdout" "$1" || fail "the images differ: $(cat "$work/stdout")"
}

check_pipeline() { # WHAT SCENE
	run "$1: render" bash -c "cd '$work' && '$relight' render -o $1.ref.exr $2"
	expect_status 0
	expect_no_crash
	checks=$((checks + 1))
	grep -q "error:" "$work/stderr" && fail "render reports an error"
	run "$1: bake" bash -c "cd '$work' && '$relight' bake -q -o $1.shot.exr $2"
	expect_status 0
	expect_no_crash
	run "$1: preview --cpu" bash -c "cd '$work' && '$relight' preview --cpu -o $1.prev.exr $1.shot.exr"
	expect_status 0
	expect_no_crash
	expect_same "$1: preview against render" "$work/$1.ref.exr" "$work/$1.prev.exr"
}

check_pipeline varying varying.rib
check_pipeline prelights prelights.rib

# The GPU preview of the same shots, where an EGL context is available (it is
# llvmpipe on a machine without a GPU); the CPU checks above stand without it.
run "GPU: context" bash -c "cd '$work' && '$relight' preview -q -o varying.gpu.exr varying.shot.exr"
if [ "$status" -ne 0 ]; then
	echo "SKIP (GPU part only): no EGL/OpenGL context here: $(head -c 300 "$work/stderr")"
else
	expect_same "varying: GPU preview against render" "$work/varying.ref.exr" \
		"$work/varying.gpu.exr"
	run "prelights: GPU preview" bash -c \
		"cd '$work' && '$relight' preview -q -o prelights.gpu.exr prelights.shot.exr"
	expect_status 0
	expect_no_crash
	expect_same "prelights: GPU preview against render" "$work/prelights.ref.exr" \
		"$work/prelights.gpu.exr"
fi

run "Cs: render" bash -c "cd '$work' && '$relight' render -q -o cs.ref.exr cs.rib"
expect_status 0
expect_same "a varying parameter against Cs" "$work/varying.ref.exr" "$work/cs.ref.exr"

finish
