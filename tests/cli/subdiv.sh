#!/usr/bin/env bash
# SubdivisionMesh through the whole pipeline, and its bad input.
#
# Bad input: each malformed mesh (a vertex index out of range, a face of 2
# vertices, tags whose argument counts disagree, a negative sharpness, a NaN
# point, a crease between vertices no edge joins) is an error naming its file
# and line, and only that mesh is dropped: the sphere beside it still
# renders, the image the same as the sphere's alone. An unsupported
# scheme or tag is a warning at its line (the frame renders), an error with
# --strict.
#
# Bake and preview: a Catmull-Clark cube (creased on one edge, one face a
# hole, Cs facevarying) over a ground plane, lit by a shadow-mapped spot
# light whose map it casts, a distant light and a point light, is rendered,
# baked and previewed after light edits (the spot's intensity and colour,
# the point light's position) with --cpu and on the GPU; both match
# `relight render` of the RIB edited the same way within 0.1 % mean and 1 %
# max of the 8-bit range, colour and alpha alike (and the mesh shows: the
# image without it differs by more than 1 % mean). The shot's shadow geometry
# holds the mesh's micropolygons (at least 50 more than the shot without it;
# 159 at the default --shadow-rate 4). Without an EGL context the GPU part skips
# (exit 77) after the rest has passed.
source "$(dirname "$0")/lib.sh"

# bad NAME MESH-LINES: a scene with MESH-LINES (at line 8 on) and a sphere.
bad() {
	{
		printf 'Format 64 64 1\nPixelSamples 4 4\nPixelFilter "box" 1 1\n'
		printf 'Projection "orthographic"\nScreenWindow -2 2 -2 2\n'
		printf 'Display "%s.exr" "file" "rgba"\nWorldBegin\n' "$1"
		printf '%s\n' "$2"
		printf 'Translate 0 0 5\nSurface "constant"\nSphere 1 -1 1 360\nWorldEnd\n'
	} >"$work/$1.rib"
}
quad='[-1 -1 0  1 -1 0  1 1 0  -1 1 0]'
bad index "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 4] \"P\" $quad"
bad nverts "SubdivisionMesh \"catmull-clark\" [2 2] [0 1 2 3] \"P\" $quad"
bad nargs "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"crease\"] [3 1] [0 1] [5] \"P\" $quad"
bad sharp "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"crease\"] [2 1] [0 1] [-2] \"P\" $quad"
bad nan "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] \"P\" [-1 -1 0  1 -1 0  1 1 nan  -1 1 0]"
bad noedge "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"crease\"] [2 1] [0 2] [3] \"P\" $quad"
bad corner "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"corner\"] [2 2] [0 9] [1 1] \"P\" $quad"
bad hole "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"hole\"] [1 0] [1] [] \"P\" $quad"
bad sphere ""
run "sphere alone" bash -c "cd '$work' && '$relight' render -q sphere.rib"
expect_status 0
for name in index nverts nargs sharp nan noedge corner hole; do
	run "bad $name" bash -c "cd '$work' && '$relight' render -q $name.rib"
	expect_no_crash
	checks=$((checks + 1))
	grep -q "^$name.rib:8: error: " "$work/stderr" ||
		fail "$name: no error at $name.rib:8: $(head -c 400 "$work/stderr")"
	run "bad $name vs the sphere alone" "$relight" diff --json "$work/sphere.exr" "$work/$name.exr"
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
a = d["alpha"]
assert a is not None and d["max_pct"] == 0 and a["max_pct"] == 0, d
' "$work/stdout" || fail "$name: the frame is not the sphere alone: $(head -c 300 "$work/stdout")"
done

# Unsupported schemes and tags: warnings, errors with --strict.
bad loop "SubdivisionMesh \"loop\" [3] [0 1 2] \"P\" [0 0 0  1 0 0  0 1 0]"
bad tag "SubdivisionMesh \"catmull-clark\" [4] [0 1 2 3] [\"stitch\"] [0 0] [] [] \"P\" $quad"
for name in loop tag; do
	run "warn $name" bash -c "cd '$work' && '$relight' render -q $name.rib"
	expect_status 0
	checks=$((checks + 1))
	grep -q "^$name.rib:8: warning: SubdivisionMesh" "$work/stderr" ||
		fail "$name: no warning at $name.rib:8: $(head -c 400 "$work/stderr")"
	run "strict $name" bash -c "cd '$work' && '$relight' render -q --strict $name.rib"
	checks=$((checks + 1))
	[ "$status" -ne 0 ] && grep -q "^$name.rib:8: error: " "$work/stderr" ||
		fail "$name: --strict did not make it an error: $(head -c 400 "$work/stderr")"
done

# ---- bake and preview ----
# The cube: 8 points, 6 quads; a crease (sharpness 3) along its top front
# edge, the face towards -x a hole, facevarying Cs with a seam per face.
cube='SubdivisionMesh "catmull-clark" [4 4 4 4 4 4]
      [0 1 3 2  2 3 5 4  4 5 7 6  6 7 1 0  1 7 5 3  6 0 2 4]
      ["crease" "hole" "interpolateboundary"] [2 1  1 0  0 0] [2 3  5] [3]
      "P" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  -1 1 -1  1 1 -1  -1 -1 -1  1 -1 -1]
      "facevarying color Cs" [1 0.3 0.2  1 0.3 0.2  1 0.3 0.2  1 0.3 0.2
                              0.3 1 0.3  0.3 1 0.3  0.3 1 0.3  0.3 1 0.3
                              0.3 0.4 1  0.3 0.4 1  0.3 0.4 1  0.3 0.4 1
                              1 1 0.3  1 1 0.3  1 1 0.3  1 1 0.3
                              1 0.5 1  1 0.5 1  1 0.5 1  1 0.5 1
                              0.6 1 1  0.6 1 1  0.6 1 1  0.6 1 1]'
world() {
	cat <<RIB
    AttributeBegin
      Color [0.8 0.8 0.75]
      Polygon "P" [-4 0 -4  -4 0 4  4 0 4  4 0 -4]
    AttributeEnd
    AttributeBegin
      Translate 0 0.9 2
      Rotate 30 0 1 0
      Scale 0.6 0.6 0.6
      $cube
    AttributeEnd
RIB
}
# scene_rib: the two frames around $(world).
scene_rib() {
cat <<RIB
FrameBegin 1
  Format 256 256 1
  PixelSamples 1 1
  PixelFilter "box" 1 1
  Hider "hidden" "depthfilter" "midpoint"
  Projection "perspective" "fov" 50
  Display "key.z" "zfile" "z"
  Transform [0.780869 -0.407041 -0.473879 0 -0 0.758577 -0.651584 0 0.624695 0.508801 0.592349 0 -1.24939 -1.39689 7.58207 1]
  WorldBegin
    Surface "constant"
$(world)
  WorldEnd
FrameEnd
MakeShadow "key.z" "key.shd"
FrameBegin 2
  Format 96 64 1
  PixelSamples 4 4
  Projection "perspective" "fov" 40
  Display "scene.exr" "file" "rgba"
  Transform [1 0 0 0 0 0.960195 -0.27933 0 -0 0.27933 0.960195 0 -0 -1.13478 3.97521 1]
  WorldBegin
    LightSource "distantlight" 1 "intensity" 0.3 "from" [0 1 -1] "to" [0 0 0]
    LightSource "shadowspot" 2 "intensity" 60 "from" [4 6 -3] "to" [0 0.5 2]
        "coneangle" 0.45 "conedeltaangle" 0.08 "shadowname" "key.shd"
        "samples" 16 "blur" 0.004
    LightSource "pointlight" 3 "intensity" 6 "from" [-4 3 -2]
    Surface "plastic" "Kd" 0.7 "Ks" 0.4 "roughness" 0.08
$(world)
  WorldEnd
FrameEnd
RIB
}
scene_rib >"$work/scene.rib"
# The same without the mesh: the mesh must show (and shadow) in the image.
cube="" scene_rib | sed -e 's/"scene.exr"/"nomesh.exr"/' -e 's/key\./nokey./g' >"$work/nomesh.rib"
sed -e 's/"shadowspot" 2 "intensity" 60/"shadowspot" 2 "intensity" 35 "lightcolor" [1 0.8 0.6]/' \
    -e 's/"pointlight" 3 "intensity" 6 "from" \[-4 3 -2\]/"pointlight" 3 "intensity" 6 "from" [-2 4 0]/' \
    "$work/scene.rib" >"$work/edited.rib"
checks=$((checks + 1))
grep -q '"intensity" 35 "lightcolor"' "$work/edited.rib" && grep -q 'from" \[-2 4 0\]' "$work/edited.rib" ||
	fail "cannot edit scene.rib"
sets="--set 2.intensity=35 --set 2.lightcolor=1,0.8,0.6 --set 3.from=-2,4,0"

run "render" bash -c "cd '$work' && '$relight' render -q scene.rib && '$relight' render -q -o ref.exr edited.rib"
expect_status 0
expect_empty_stderr
run "render without the mesh" bash -c "cd '$work' && '$relight' render -q nomesh.rib"
expect_status 0
run "the mesh shows" "$relight" diff --json "$work/nomesh.exr" "$work/scene.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] > 1, d
' "$work/stdout" || fail "the image without the mesh is the same: $(head -c 300 "$work/stdout")"
run "bake" bash -c "cd '$work' && '$relight' bake -q -o scene.shot.exr scene.rib"
expect_status 0
run "info" "$relight" info --json "$work/scene.shot.exr"
cp "$work/stdout" "$work/info.json"
run "bake without the mesh" bash -c "cd '$work' && '$relight' bake -q -o nomesh.shot.exr nomesh.rib"
expect_status 0
run "info without the mesh" "$relight" info --json "$work/nomesh.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
a = json.load(open(sys.argv[1]))["shadow_quads"]
b = json.load(open(sys.argv[2]))["shadow_quads"]
print("shadow geometry: %d micropolygons, %d without the mesh" % (a, b))
assert a - b >= 50, (a, b)
' "$work/info.json" "$work/stdout" || fail "the shot has no shadow geometry of the mesh"

run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $sets -o cpu.exr scene.shot.exr"
expect_status 0
expect_matches_render "preview --cpu" ref.exr cpu.exr

run "EGL context" bash -c "cd '$work' && '$relight' preview -q $sets -o gpu.exr scene.shot.exr"
skip_without_gpu
expect_status 0
expect_no_crash
expect_matches_render "preview (GPU)" ref.exr gpu.exr
finish
