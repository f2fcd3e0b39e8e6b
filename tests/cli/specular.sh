#!/usr/bin/env bash
# The specular model, Option "shading" "string specularmodel": PRMan's
# highlight (exponent 8 / roughness, the default) or the RenderMan Interface
# Specification's (1 / roughness). A plastic sphere under a distant light,
# roughness 0.1:
#
#   - with no option the render is PRMan's model's, bit for bit;
#   - the two models' renders differ (mean error over 1 % of the 8-bit
#     range: the RiSpec highlight is broader and brighter);
#   - a value other than "prman" or "rispec" is an error at the option's
#     FILE:LINE;
#   - each model's shot records it (relight info), and its previews follow
#     it: the CPU resolver (`relight preview --cpu`) and the GPU runtime
#     against the render of the same RIB within the limits of gpu.sh (mean
#     error <= 0.1 %, maximum <= 1 % of the 8-bit range, after sRGB), the
#     GPU against the CPU within a largest relative difference of 1e-4.
#     Without an EGL context the GPU part skips (exit 77) after the rest.
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0

cd "$work" || exit 1

# scene NAME OPTION-LINE: NAME.rib, displaying NAME.exr
scene() {
	cat >"$1.rib" <<EOF
$2
Format 96 96 1
PixelSamples 2 2
Projection "perspective" "fov" 30
Display "$1.exr" "file" "rgba"
Translate 0 0 5
WorldBegin
LightSource "distantlight" 1 "intensity" 1 "from" [1 1 -1] "to" [0 0 0]
LightSource "ambientlight" 2 "intensity" 0.05
Surface "plastic" "roughness" 0.1 "Ks" 0.8
Sphere 1 -1 1 360
WorldEnd
EOF
}

scene prman 'Option "shading" "string specularmodel" ["prman"]'
scene rispec 'Option "shading" "string specularmodel" ["rispec"]'
scene default '# no option: the default model'

for m in prman rispec default; do
	run "render $m" "$relight" render -q "$m.rib"
	expect_status 0
	expect_empty_stderr
done

# diff_field A B KEY: one number of `relight diff --json A B`
diff_field() {
	"$relight" diff --json "$1" "$2" | python3 -c "import json, sys; print(json.load(sys.stdin)['$3'])"
}

what="the default is PRMan's model"
checks=$((checks + 1))
rmse=$(diff_field prman.exr default.exr rmse)
[ "$rmse" = "0" ] || [ "$rmse" = "0.0" ] || fail "default vs prman: RMSE $rmse, expected 0"

what="the models differ"
checks=$((checks + 1))
mean=$(diff_field prman.exr rispec.exr mean_pct)
python3 -c "import sys; sys.exit(0 if $mean > 1.0 else 1)" ||
	fail "prman vs rispec: mean error $mean %, expected over 1 %"
echo "prman vs rispec render: mean error $mean % of the 8-bit range"

scene bad 'Option "shading" "string specularmodel" ["blinn"]'
run "unknown model" "$relight" render -q bad.rib
expect_no_crash
expect_stderr '^bad\.rib:1: .*specularmodel.*"prman" or "rispec"'

# Each model through the bake and both previews.
gpu_skipped=""
for m in prman rispec; do
	run "bake $m" "$relight" bake -q "$m.rib"
	expect_status 0
	run "info $m" "$relight" info --json "$m.shot.exr"
	expect_status 0
	expect_stdout "\"specular_model\":[[:space:]]*\"$m\""
	run "cpu preview $m" "$relight" preview -q --cpu -o "$m.cpu.exr" "$m.shot.exr"
	expect_status 0
	what="cpu preview $m vs render"
	checks=$((checks + 1))
	"$relight" diff --json "$m.exr" "$m.cpu.exr" >"$m.vs_cpu.json"
	python3 - "$m.vs_cpu.json" "$max_mean_pct" "$max_max_pct" >"$work/verdict" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
print("mean %.4f %% max %.4f %%" % (r["mean_pct"], r["max_pct"]))
if not (r["mean_pct"] <= float(sys.argv[2]) and r["max_pct"] <= float(sys.argv[3])):
	print("FAIL")
PY
	echo "$m: CPU preview vs render: $(head -1 "$work/verdict")"
	grep -q FAIL "$work/verdict" && fail "$(head -1 "$work/verdict")"

	[ -n "$gpu_skipped" ] && continue
	run "gpu preview $m" "$relight" preview -q -o "$m.gpu.exr" "$m.shot.exr"
	if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
		gpu_skipped="$(head -c 300 "$work/stderr")"
		continue
	fi
	expect_status 0
	what="gpu preview $m"
	checks=$((checks + 1))
	"$relight" diff --json "$m.exr" "$m.gpu.exr" >"$m.vs_render.json"
	"$relight" diff --json "$m.cpu.exr" "$m.gpu.exr" >"$m.vs_cpuimg.json"
	python3 - "$m.vs_render.json" "$m.vs_cpuimg.json" "$max_mean_pct" "$max_max_pct" \
		"$max_rel" >"$work/verdict" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
c = json.load(open(sys.argv[2]))
print("vs render mean %.4f %% max %.4f %%; vs cpu max_rel %.2g"
      % (r["mean_pct"], r["max_pct"], c["max_rel"]))
if not (r["mean_pct"] <= float(sys.argv[3]) and r["max_pct"] <= float(sys.argv[4])):
	print("FAIL: against the render")
if not (c["max_rel"] <= float(sys.argv[5])):
	print("FAIL: against the CPU preview")
PY
	echo "$m: GPU preview $(head -1 "$work/verdict")"
	grep -q FAIL "$work/verdict" && fail "$(tr '\n' ' ' <"$work/verdict")"
done

if [ -n "$gpu_skipped" ]; then
	finish || exit 1
	echo "SKIP: the GPU part: no EGL/OpenGL 4.3 context here: $gpu_skipped"
	exit 77
fi
finish
