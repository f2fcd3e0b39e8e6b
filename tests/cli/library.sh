#!/usr/bin/env bash
# Every shader of shaders/, and every test shader that runs, through the whole chain: a small scene that uses it
# (a surface on a sphere and a wall, a light lighting plastic, a displacement
# under plastic, a volume shader as the atmosphere, an imager on the frame) is
# rendered, baked and previewed after an edit (a light's intensity, or the
# imager's colour), on the CPU and on the GPU. Each preview against
# `relight render` of the RIB edited the same way: mean error <= 0.1 % and
# maximum error <= 1 % of the 8-bit range; the GPU against the CPU preview:
# largest relative difference <= 1e-4. A shader added to shaders/ is in this
# test without anything to write. Without an EGL context the GPU half is not
# run and the script skips (exit 77) after the CPU half.
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0
gpu=1

# scene NAME KIND SETTING INTENSITY: the RIB of the scene for shader NAME of
# KIND, with SETTING the parameters of the light or imager under test ("" for
# its defaults) and INTENSITY that of the point light lighting the others.
scene() {
	local name=$1 kind=$2 setting=$3 intensity=$4
	local surface='Surface "plastic"' lights atmosphere="" displacement="" imager=""
	lights='  LightSource "pointlight" 1 "from" [1 2 0] "intensity" '"$intensity"'
  LightSource "distantlight" 2 "from" [-1 1 -1] "to" [0 0 0] "intensity" 0.4'
	case $kind in
	surface) surface="Surface \"$name\"" ;;
	light)
		lights="  TransformBegin
    Translate 0.3 0.4 0
    LightSource \"$name\" 1 $setting
  TransformEnd
  LightSource \"distantlight\" 2 \"from\" [-1 1 -1] \"to\" [0 0 0] \"intensity\" 0.3" ;;
	displacement) displacement="Displacement \"$name\"
    Attribute \"displacementbound\" \"sphere\" [0.2]" ;;
	volume) atmosphere="Atmosphere \"$name\"" ;;
	imager) imager="Imager \"$name\" $setting" ;;
	esac
	cat <<RIB
Format 64 48 1
PixelSamples 2 2
ShadingRate 1
Projection "perspective" "fov" 40
$imager
Display "$name.exr" "file" "rgba"
WorldBegin
$lights
  AttributeBegin
    $surface
    $displacement
    $atmosphere
    Color [0.8 0.5 0.3]
    Translate 0 0 5
    Sphere 1 -1 1 360
  AttributeEnd
  AttributeBegin
    $surface
    $atmosphere
    Color [0.4 0.6 0.8]
    Translate 0 0 8
    Polygon "P" [-3 -2 0  3 -2 0  3 2 0  -3 2 0]
  AttributeEnd
WorldEnd
RIB
}

# within NAME WHAT JSON: the diff of the render and a preview within the limits.
within() {
	checks=$((checks + 1))
	python3 - "$1: $2" "$3" "$max_mean_pct" "$max_max_pct" <<'PY' || fail "$1: $2 differs from the render"
import json, sys
what, path, max_mean, max_max = sys.argv[1], sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
d = json.load(open(path))
print("%s: mean %.4f %%, max %.4f %% of the 8-bit range (limits %g, %g)"
      % (what, d["mean_pct"], d["max_pct"], max_mean, max_max))
assert d["nonfinite"] == [0, 0], d["nonfinite"]
assert d["mean_pct"] <= max_mean and d["max_pct"] <= max_max
PY
}

nshaders=0
export RMAN_SHADERPATH="$work:$source_dir/shaders"
# The library, and the test shaders that run (the golden run_ shaders, the
# fog example's glow), copied beside the scenes so that they are found.
for sl in "$source_dir"/shaders/*.sl "$source_dir"/tests/golden/run_*.sl \
	"$source_dir"/examples/fog/glow.sl; do
	name=$(basename "$sl" .sl)
	case $sl in "$source_dir"/shaders/*) ;; *) cp "$sl" "$work/" ;; esac
	kind=$(grep -m1 -oE '^[[:space:]]*(surface|light|displacement|volume|imager)\b' "$sl" | tr -d '[:space:]')
	checks=$((checks + 1))
	[ -n "$kind" ] || { fail "$name: no shader kind found in $sl"; continue; }
	nshaders=$((nshaders + 1))
	# The edit: a light's intensity where the shader has one (the scene's
	# point light otherwise), the imager's colour; a light without an
	# intensity is previewed as baked.
	case $kind in
	light)
		if grep -qE '\bintensity\b' "$sl"; then
			set_arg="1.intensity=0.6" setting='"intensity" 0.6'
		else
			set_arg="" setting=""
		fi ;;
	imager) set_arg="imager.bgcolor=0.2,0.3,0.4" setting='"color bgcolor" [0.2 0.3 0.4]' ;;
	*) set_arg="1.intensity=7" setting="" ;;
	esac
	scene "$name" "$kind" "" 20 >"$work/$name.rib"
	if [ "$kind" = light ] || [ "$kind" = imager ]; then
		scene "$name" "$kind" "$setting" 20 >"$work/$name.edited.rib"
	else
		scene "$name" "$kind" "" 7 >"$work/$name.edited.rib"
	fi
	run "$name: render the edited scene" bash -c "cd '$work' && '$relight' render -q -o $name.ref.exr $name.edited.rib"
	expect_status 0
	expect_no_crash
	# The edit is seen: the scene as baked renders otherwise (but where
	# nothing can change: the null shaders, a light with no intensity, a
	# surface that reads no light).
	reads_lights=1
	case $sl in "$source_dir"/shaders/*) ;; *) reads_lights=0 ;; esac
	if [ "$kind" = surface ] && ! grep -qE '\b(illuminance|diffuse|specular|phong|ambient)\b' "$sl"; then
		reads_lights=0
	fi
	if [ -n "$set_arg" ] && [ "${name#null_}" = "$name" ] && [ "$reads_lights" = 1 ]; then
		run "$name: render the scene as baked" bash -c "cd '$work' && '$relight' render -q -o $name.base.exr $name.rib && '$relight' diff --json $name.base.exr $name.ref.exr"
		checks=$((checks + 1))
		python3 -c 'import json, sys; d = json.load(open(sys.argv[1])); assert d["mean_pct"] > 0.1, d["mean_pct"]' \
			"$work/stdout" || fail "$name: the edit $set_arg changes less than 0.1 % mean of the 8-bit range"
	fi
	run "$name: bake" bash -c "cd '$work' && '$relight' bake -q -o $name.shot.exr $name.rib"
	expect_status 0
	expect_no_crash
	set_opts=()
	[ -n "$set_arg" ] && set_opts=(--set "$set_arg")
	run "$name: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu ${set_opts[*]} -o $name.cpu.exr $name.shot.exr"
	expect_status 0
	run "$name: cpu vs render" "$relight" diff --json "$work/$name.ref.exr" "$work/$name.cpu.exr"
	cp "$work/stdout" "$work/$name.cpu.json"
	within "$name ($kind)" "CPU preview" "$work/$name.cpu.json"
	[ "$gpu" = 1 ] || continue
	run "$name: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q ${set_opts[*]} -o $name.gpu.exr $name.shot.exr"
	if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
		echo "no EGL/OpenGL 4.3 context here: the GPU half is not run: $(head -c 300 "$work/stderr")"
		gpu=0
		continue
	fi
	expect_status 0
	expect_no_crash
	run "$name: gpu vs render" "$relight" diff --json "$work/$name.ref.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.gpu.json"
	within "$name ($kind)" "GPU preview" "$work/$name.gpu.json"
	run "$name: gpu vs cpu" "$relight" diff --json "$work/$name.cpu.exr" "$work/$name.gpu.exr"
	checks=$((checks + 1))
	python3 - "$name" "$work/stdout" "$max_rel" <<'PY' || fail "$name: the GPU preview differs from the CPU's"
import json, sys
d = json.load(open(sys.argv[2]))
print("%s: GPU vs CPU max_rel %.2g (limit %s)" % (sys.argv[1], d["max_rel"], sys.argv[3]))
assert d["max_rel"] <= float(sys.argv[3])
PY
done

checks=$((checks + 1))
[ "$nshaders" -ge 30 ] || fail "only $nshaders shaders found"
if [ "$gpu" = 0 ]; then
	finish
	[ "$failures" -eq 0 ] && exit 77
	exit 1
fi
finish
