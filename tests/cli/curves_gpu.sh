#!/usr/bin/env bash
# Curves and Points through the bake and the preview: tests/cli/curves/hair.rib
# (150 tapered b-spline hairs and three points, one moving, two half-opaque,
# casting a shadow map onto a floor from a shadow pass; plastic, three
# lights) is baked; its shadow geometry must hold the hairs; it is previewed
# after light edits (intensity, colour, position) with `--cpu` and on the
# GPU, each against `relight render` of the RIB edited the same way: mean
# error <= 0.1 % and maximum error <= 1 % of the 8-bit range, colour and
# alpha; the GPU against the CPU resolver within a relative 1e-4. Without an
# EGL context the GPU part skips (exit 77) once the CPU part has passed.
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0

cp "$source_dir/tests/cli/curves/hair.rib" "$source_dir/tests/cli/curves/hairs.rib" "$work/"

# compare NAME REF IMG LIMIT-KIND: relight diff REF IMG, colour and alpha
# within the limits (render) or the relative limit (cpu).
compare() {
	run "$1" "$relight" diff --json "$work/$2" "$work/$3"
	expect_status 0
	checks=$((checks + 1))
	python3 - "$work/stdout" "$1" "$4" "$max_mean_pct" "$max_max_pct" "$max_rel" <<'PY' || fail "$1 differs"
import json, sys
d = json.load(open(sys.argv[1]))
name, kind, mean, mx, rel = sys.argv[2], sys.argv[3], float(sys.argv[4]), float(sys.argv[5]), float(sys.argv[6])
a = d["alpha"]
if kind == "render":
	print("%s: colour mean %.4f %% max %.4f %%, alpha mean %.4f %% max %.4f %% (limits %g %%, %g %%)"
	      % (name, d["mean_pct"], d["max_pct"], a["mean_pct"], a["max_pct"], mean, mx))
	assert d["mean_pct"] <= mean and d["max_pct"] <= mx and a["mean_pct"] <= mean and a["max_pct"] <= mx
else:
	print("%s: max relative %.3g (limit %g)" % (name, d["max_rel"], rel))
	assert d["max_rel"] <= rel
PY
}

run "render" bash -c "cd '$work' && '$relight' render -q -o ref.exr hair.rib"
expect_status 0
expect_empty_stderr
run "bake" bash -c "cd '$work' && '$relight' bake -q -o hair.shot.exr hair.rib"
expect_status 0
expect_empty_stderr
# the same scene without hairs and points: what the floor alone casts
# (in a folder of its own: its shadow pass writes a map of the same name)
mkdir -p "$work/floor"
grep -v 'ReadArchive\|Points\|MotionBegin\|MotionEnd' "$work/hair.rib" >"$work/floor/floor.rib"
run "bake the floor alone" bash -c "cd '$work/floor' && '$relight' bake -q -o ../floor.shot.exr floor.rib"
expect_status 0
run "info" "$relight" info --json "$work/hair.shot.exr"
cp "$work/stdout" "$work/hair.info"
run "info floor" "$relight" info --json "$work/floor.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
h, f = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
print("shadow geometry: %d micropolygons, the floor alone %d" % (h["shadow_quads"], f["shadow_quads"]))
assert h["shadow_quads"] >= f["shadow_quads"] + 300  # 150 hairs and 3 disks
' "$work/hair.info" "$work/stdout" || fail "the hairs are not in the shadow geometry"
run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu -o cpu.exr hair.shot.exr"
expect_status 0
compare "preview --cpu vs render" ref.exr cpu.exr render

# The edits: the spot's intensity and colour, the point light's position.
edits=(2.intensity=30 2.lightcolor=1,0.8,0.6 3.from=-3,4,-1)
sets=()
for e in "${edits[@]}"; do sets+=(--set "$e"); done
set_light_params "$work/hair.rib" "$work/edited.rib" "${edits[@]}" || fail "cannot edit hair.rib"
run "render edited" bash -c "cd '$work' && '$relight' render -q -o edited.exr edited.rib"
expect_status 0
run "preview --cpu edited" bash -c "cd '$work' && '$relight' preview -q --cpu ${sets[*]} -o cpu_edit.exr hair.shot.exr"
expect_status 0
compare "edited: preview --cpu vs render" edited.exr cpu_edit.exr render
run "the edits changed the image" "$relight" diff --json "$work/ref.exr" "$work/edited.exr"
checks=$((checks + 1))
python3 -c 'import json, sys; assert json.load(open(sys.argv[1]))["max_pct"] > 5' "$work/stdout" ||
	fail "the edits made no difference"

run "EGL context" bash -c "cd '$work' && '$relight' preview -q -o probe.exr hair.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	finish >/dev/null || { finish; exit 1; }
	exit 77
fi
expect_status 0
run "preview gpu edited" bash -c "cd '$work' && '$relight' preview -q ${sets[*]} -o gpu_edit.exr hair.shot.exr"
expect_status 0
expect_no_crash
compare "edited: GPU vs render" edited.exr gpu_edit.exr render
compare "edited: GPU vs CPU" cpu_edit.exr gpu_edit.exr cpu

finish
