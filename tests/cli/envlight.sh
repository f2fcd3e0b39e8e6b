#!/usr/bin/env bash
# shaders/envlight.sl (solar() without arguments, Ns) through the whole
# pipeline: a scene lit by an environment map and a spot light is rendered,
# baked and previewed on the CPU, the preview within 0.1% mean and 1% max of
# the 8-bit range of the render; the same with the empty map name on the GPU
# (llvmpipe here); then the map on the GPU against the render, also after an
# intensity edit, a swap of envname to a second map (not constant: sky above,
# ground below) and a change of envspace to the light's shader space (turned
# 90 degrees from the world), each within 1e-4 relative of preview --cpu. The
# closed form (a matte plane under a constant environment) is
# tests/unit/test_render.c's.
source "$(dirname "$0")/lib.sh"

# A constant picture to make the map from: the renderer's own output.
cat >"$work/sky.rib" <<'RIB'
Format 32 16 1
Projection "orthographic"
ScreenWindow -1 1 -1 1
Display "sky.exr" "file" "rgba" "string type" "float"
WorldBegin
  Color [0.6 0.45 0.3]
  Surface "constant"
  Translate 0 0 5
  Polygon "P" [-2 -2 0  2 -2 0  2 2 0  -2 2 0]
WorldEnd
RIB
run "sky picture" bash -c "cd '$work' && '$relight' render -q sky.rib"
expect_status 0
# The second map's picture: blue above, orange below.
cat >"$work/ground.rib" <<'RIB'
Format 32 16 1
Projection "orthographic"
ScreenWindow -1 1 -1 1
Display "ground.exr" "file" "rgba" "string type" "float"
WorldBegin
  Surface "constant"
  Translate 0 0 5
  Color [0.2 0.5 0.9]
  Polygon "P" [-2 0 0  2 0 0  2 2 0  -2 2 0]
  Color [0.9 0.6 0.1]
  Polygon "P" [-2 -2 0  2 -2 0  2 0 0  -2 0 0]
WorldEnd
RIB
run "ground picture" bash -c "cd '$work' && '$relight' render -q ground.rib"
expect_status 0

scene() { # scene ENVNAME > RIB
	cat <<RIB
MakeLatLongEnvironment "sky.exr" "sky.env" "box" 1 1
MakeLatLongEnvironment "ground.exr" "other.env" "box" 1 1
Format 40 30 1
PixelSamples 4 4
Display "env.exr" "file" "rgba"
Projection "perspective" "fov" 40
WorldBegin
  TransformBegin
    Rotate 90 1 0 0
    LightSource "envlight" 1 "string envname" "$1" "float intensity" 0.7 "float samples" 16
  TransformEnd
  LightSource "spotlight" 2 "from" [1 2 0] "to" [0 0 6] "intensity" 12 "coneangle" 0.5
  AttributeBegin
    Surface "plastic" "Kd" 0.6 "Ks" 0.3
    Color [0.9 0.5 0.3]
    Translate -0.7 0 6
    Sphere 1 -1 1 360
  AttributeEnd
  AttributeBegin
    Surface "matte"
    Translate 0.9 0.2 5
    Rotate 40 1 1 0
    Polygon "P" [-0.8 -0.8 0  0.8 -0.8 0  0.8 0.8 0  -0.8 0.8 0]
  AttributeEnd
WorldEnd
RIB
}

# relight diff --json on stdout: within 0.1% mean and 1% max of the 8-bit range.
within_8bit() {
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
print("%s: mean %.4f%%, max %.4f%% of the 8-bit range" % (sys.argv[2], d["mean_pct"], d["max_pct"]))
' "$work/stdout" "$1" || fail "$1: preview differs from the render"
}

scene sky.env >"$work/env.rib"
run "map: render" bash -c "cd '$work' && '$relight' render -q -o ref.exr env.rib"
expect_status 0
expect_no_crash
run "map: the map lights the scene" bash -c "cd '$work' && sed 's/\"float intensity\" 0.7/\"float intensity\" 0/' env.rib >off.rib && '$relight' render -q -o off.exr off.rib && '$relight' diff --json off.exr ref.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["max_pct"] > 10, d
' "$work/stdout" || fail "envlight adds nothing to the render"
run "map: bake" bash -c "cd '$work' && '$relight' bake -q -o env.shot.exr env.rib"
expect_status 0
run "map: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu -o cpu.exr env.shot.exr"
expect_status 0
expect_no_crash
run "map: cpu vs render" "$relight" diff --json "$work/ref.exr" "$work/cpu.exr"
expect_status 0
within_8bit "map, preview --cpu"

# An edit of the environment light's intensity, previewed against its render.
run "map: edited preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu --set 1.intensity=1.4 -o cpued.exr env.shot.exr && sed 's/\"float intensity\" 0.7/\"float intensity\" 1.4/' env.rib >ed.rib && '$relight' render -q -o refed.exr ed.rib && '$relight' diff --json refed.exr cpued.exr"
expect_status 0
within_8bit "map, intensity edited, preview --cpu"

# The empty name: a constant environment of radiance 1; GPU and CPU previews.
scene "" >"$work/sky0.rib"
run "no map: render" bash -c "cd '$work' && '$relight' render -q -o ref0.exr sky0.rib"
expect_status 0
run "no map: bake" bash -c "cd '$work' && '$relight' bake -q -o sky0.shot.exr sky0.rib"
expect_status 0
run "no map: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu -o cpu0.exr sky0.shot.exr && '$relight' diff --json ref0.exr cpu0.exr"
expect_status 0
within_8bit "no map, preview --cpu"
run "no map: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q -o gpu0.exr sky0.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	[ "$failures" -eq 0 ] && exit 77
	finish
fi
expect_status 0
expect_no_crash
run "no map: gpu vs render" "$relight" diff --json "$work/ref0.exr" "$work/gpu0.exr"
expect_status 0
within_8bit "no map, GPU preview"

# GPU and CPU previews of the same edits: within 1e-4 relative.
close_to_cpu() {
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["max_rel"] < 1e-4, d
print("%s: GPU vs --cpu max_rel %.3g" % (sys.argv[2], d["max_rel"]))
' "$work/stdout" "$1" || fail "$1: the GPU preview differs from preview --cpu"
}

# map_case LABEL REF.exr OUT SETS...: the GPU preview of env.shot.exr with
# SETS against the render REF.exr and against preview --cpu.
map_case() {
	local label=$1 ref=$2 out=$3
	shift 3
	run "$label: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q $* -o $out.exr env.shot.exr"
	expect_status 0
	expect_no_crash
	checks=$((checks + 1))
	if grep -v "renders in SOFTWARE" "$work/stderr" | grep -q warning; then
		fail "$label: the GPU preview warns: $(grep -v 'renders in SOFTWARE' "$work/stderr" | head -c 400)"
	fi
	run "$label: gpu vs render" "$relight" diff --json "$work/$ref" "$work/$out.exr"
	expect_status 0
	within_8bit "$label, GPU preview"
	run "$label: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $* -o $out-cpu.exr env.shot.exr"
	expect_status 0
	run "$label: gpu vs cpu" "$relight" diff --json "$work/$out-cpu.exr" "$work/$out.exr"
	expect_status 0
	close_to_cpu "$label"
}

map_case "map" ref.exr gpu ""
map_case "map, intensity edited" refed.exr gpued "--set 1.intensity=1.4"
sed 's/"string envname" "sky.env"/"string envname" "other.env"/' "$work/env.rib" >"$work/other.rib"
sed 's/"string envname" "sky.env"/"string envname" "other.env" "string envspace" "shader"/' \
	"$work/env.rib" >"$work/shader.rib"
run "second map: renders" bash -c "cd '$work' && '$relight' render -q -o refo.exr other.rib && '$relight' render -q -o refs.exr shader.rib && '$relight' diff --json refo.exr refs.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["max_pct"] > 10, d
' "$work/stdout" || fail "envspace changes nothing in the render: the test cannot tell spaces apart"
map_case "envname swapped" refo.exr gpuo "--set 1.envname=other.env"
map_case "envname swapped, envspace shader" refs.exr gpus "--set 1.envname=other.env --set 1.envspace=shader"

# A space the preview does not know: a warning naming it, the identity as on the CPU.
run "unknown space: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q --set 1.envname=other.env --set 1.envspace=nowhere -o gpun.exr env.shot.exr"
expect_status 0
expect_stderr "light '1' names coordinate system 'nowhere'"
run "unknown space: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu --set 1.envname=other.env --set 1.envspace=nowhere -o gpun-cpu.exr env.shot.exr"
expect_status 0
run "unknown space: gpu vs cpu" "$relight" diff --json "$work/gpun-cpu.exr" "$work/gpun.exr"
expect_status 0
close_to_cpu "unknown space"

finish
