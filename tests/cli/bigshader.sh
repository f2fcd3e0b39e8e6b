#!/usr/bin/env bash
# A production-sized surface shader (tests/bench/gen_bigshader.py: 120
# pattern layers, over 20,000 IR instructions after inlining) through the
# whole pipeline: it specializes with a small cache and a small GPU kernel,
# and a scene using it relights: the CPU and GPU previews within 0.1% mean
# and 1% max of the 8-bit range of the render, with only the lights dynamic
# and with four material parameters dynamic too. Correctness only: the
# timings are tests/bench/bench_bigshader's.
source "$(dirname "$0")/lib.sh"
limit=${RELIGHT_CLI_TIMEOUT:-300}

checks=$((checks + 1))
what="generate"
python3 "$source_dir/tests/bench/gen_bigshader.py" --layers 120 >"$work/bigsurface.sl" ||
	fail "gen_bigshader.py failed"

# report FIELD...: the report's numbers, one a line.
report() {
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print(d["instructions"]["total"], d["cached_scalars"], d["glsl_lines"], d["dynamic_instructions"])
' "$work/stdout"
}

run "compile, lights dynamic" "$relight" compile --emit report "$work/bigsurface.sl"
expect_status 0
read -r total cached lines dyn <<<"$(report)"
echo "lights dynamic: $total IR instructions, $dyn dynamic, $cached cached scalars, $lines GLSL lines"
checks=$((checks + 1))
[ "${total:-0}" -ge 20000 ] || fail "only ${total:-?} IR instructions"
# The dynamic part is a few dozen instructions: its kernel declares what it
# uses, not every register of the shader.
checks=$((checks + 1))
[ "${lines:-99999}" -lt 2000 ] || fail "the lights' kernel has ${lines:-?} GLSL lines"

run "compile, the pattern stack dynamic" "$relight" compile --dynamic layerscale --emit report "$work/bigsurface.sl"
expect_status 0
read -r total cached lines dyn <<<"$(report)"
echo "layerscale dynamic: $dyn dynamic instructions, $cached cached scalars, $lines GLSL lines"
# What the dynamic part reads that is computed from constants alone (the
# inlined helpers' arguments and locals) is computed again, not cached.
checks=$((checks + 1))
[ "${cached:-99999}" -lt 100 ] || fail "${cached:-?} scalars cached per sample"

cat >"$work/big.rib" <<'RIB'
Option "searchpath" "shader" [".:@"]
Format 48 36 1
PixelSamples 2 2
Display "big.exr" "file" "rgba"
Projection "perspective" "fov" 40
WorldBegin
  LightSource "spotlight" 1 "from" [1 2 0] "to" [0 0 6] "intensity" 14 "coneangle" 0.5
  LightSource "pointlight" 2 "from" [-2 1 2] "intensity" 6
  LightSource "ambientlight" 3 "intensity" 0.1
  AttributeBegin
    Surface "bigsurface"
    Color [0.8 0.6 0.4]
    Translate -0.6 0 6
    Sphere 1.2 -1.2 1.2 360
  AttributeEnd
  AttributeBegin
    Surface "bigsurface" "float layerscale" 2 "float roughness" 0.1
    Translate 1.2 0.2 5
    Rotate 40 1 1 0
    Polygon "P" [-0.8 -0.8 0  0.8 -0.8 0  0.8 0.8 0  -0.8 0.8 0]
  AttributeEnd
WorldEnd
RIB

within_8bit() {
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
print("%s: mean %.4f%%, max %.4f%% of the 8-bit range" % (sys.argv[2], d["mean_pct"], d["max_pct"]))
' "$work/stdout" "$1" || fail "$1: preview differs from the render"
}

run "render" bash -c "cd '$work' && '$relight' render -q -o ref.exr big.rib"
expect_status 0
expect_no_crash

gpu=1
for dyn in "" "roughness,Ks,sheen,wrap"; do
	name="${dyn:-lights}"
	opt=()
	[ -n "$dyn" ] && opt=(--dynamic-surface "$dyn")
	run "$name: bake" bash -c "cd '$work' && '$relight' bake -q ${opt[*]} -o big.shot.exr big.rib"
	expect_status 0
	run "$name: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu -o cpu.exr big.shot.exr && '$relight' diff --json ref.exr cpu.exr"
	expect_status 0
	within_8bit "$name dynamic, preview --cpu"
	[ "$gpu" -eq 1 ] || continue
	run "$name: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q -o gpu.exr big.shot.exr"
	if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
		echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
		gpu=0
		continue
	fi
	expect_status 0
	expect_no_crash
	run "$name: gpu vs render" "$relight" diff --json "$work/ref.exr" "$work/gpu.exr"
	expect_status 0
	within_8bit "$name dynamic, GPU preview"
done
[ "$gpu" -eq 1 ] || { [ "$failures" -eq 0 ] && exit 77; }
finish
