#!/usr/bin/env bash
# Matte objects and DetailRange cross-fades through the bake: a scene with a
# matte disk in front of a lit wall and a sphere whose two representations
# (plastic red, matte green) cross-fade at its detail is rendered, baked and
# previewed. The CPU resolver must match the render within 0.1 % mean and
# 1 % max of the 8-bit range, colour and alpha alike (the matte's hole and
# the dissolve are recorded in the indirect framebuffer as the renderer
# hides them); the GPU preview must match the CPU resolver within a relative
# 1e-4 (`relight diff --fail-rel`). Without an EGL context the GPU part skips
# the script (exit 77) once the CPU part has passed.
source "$(dirname "$0")/lib.sh"

# The sphere's Detail bound, a cube of side 2 at distance 5 seen with a
# 40-degree field of view on 48x36 pixels, covers about 611 square pixels:
# between 300 and 900, where red fades out and green in.
cat >"$work/holdout.rib" <<'RIB'
Format 48 36 1
PixelSamples 4 4
Projection "perspective" "fov" 40
Display "holdout.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1
  LightSource "pointlight" 2 "from" [0 2 2] "intensity" 4
  AttributeBegin
    Surface "matte"
    Translate 0 0 8
    Polygon "P" [-5 -5 0  5 -5 0  5 5 0  -5 5 0]
  AttributeEnd
  AttributeBegin
    Translate -0.8 0 5
    Detail [-1 1 -1 1 -1 1]
    AttributeBegin
      DetailRange 0 0 300 900
      Surface "plastic"
      Color [1 0.2 0.2]
      Sphere 1 -1 1 360
    AttributeEnd
    AttributeBegin
      DetailRange 300 900 1e38 1e38
      Surface "matte"
      Color [0.2 1 0.2]
      Sphere 1 -1 1 360
    AttributeEnd
  AttributeEnd
  AttributeBegin
    Matte 1
    Surface "plastic"
    Translate 1 0 4
    Disk 0 0.7 360
  AttributeEnd
WorldEnd
RIB

run "render" bash -c "cd '$work' && '$relight' render -q -o ref.exr holdout.rib"
expect_status 0
expect_empty_stderr
run "bake" bash -c "cd '$work' && '$relight' bake -q -o holdout.shot.exr holdout.rib"
expect_status 0
run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu -o cpu.exr holdout.shot.exr"
expect_status 0
expect_no_crash
run "preview --cpu vs render" "$relight" diff --json "$work/ref.exr" "$work/cpu.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
a = d["alpha"]
assert a is not None, "no alpha compared"
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
assert a["mean_pct"] < 0.1 and a["max_pct"] < 1.0, a
' "$work/stdout" || fail "preview --cpu differs from the render: $(cat "$work/stdout")"

run "EGL context" bash -c "cd '$work' && '$relight' preview -q -o gpu.exr holdout.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: the GPU part: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	[ "$failures" -eq 0 ] || { finish; exit 1; }
	exit 77
fi
expect_status 0
run "preview vs preview --cpu" "$relight" diff --fail-rel 1e-4 "$work/cpu.exr" "$work/gpu.exr"
expect_status 0
finish
