#!/usr/bin/env bash
# Atmospheres in the GPU runtime (`relight preview` without --cpu), on the
# scenes of examples/fog/: RISpec's fog over lit surfaces (its mix runs on
# the GPU after the surface's lighting) and glow.sl, an atmosphere that reads
# the lights itself. Each is baked, then previewed with two light edits: on
# the GPU against the CPU resolver (largest relative difference at most
# 1e-4, as tests/cli/gpu.sh), and against `relight render` of the RIB edited
# the same way (mean error <= 0.1 %, maximum <= 1 % of the 8-bit range). The
# edits must change the image (a mean of 1 % or more), or the comparison
# would not show that the atmosphere relights, and so must the atmosphere
# (against the render of the scene without it). Without an EGL context the
# script skips (exit 77).
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0
min_change_pct=1.0

cp "$source_dir/examples/fog/"* "$work/"

run "bake fog.rib" bash -c "cd '$work' && '$relight' bake -q -o fog.shot.exr fog.rib"
expect_status 0
run "EGL context" bash -c "cd '$work' && '$relight' preview -q -o probe.exr fog.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi
expect_status 0

# gpu_case NAME: NAME.rib baked, previewed on the GPU and on the CPU with the
# point light dimmed and the spot brightened, against the edited RIB's render.
gpu_case() {
	local name=$1 edits="--set 1.intensity=2.5 --set 2.intensity=20"
	run "$name: bake" bash -c "cd '$work' && '$relight' bake -q -o $name.shot.exr $name.rib"
	expect_status 0
	expect_empty_stderr
	run "$name: gpu" bash -c "cd '$work' && '$relight' preview -q $edits -o $name.gpu.exr $name.shot.exr"
	expect_status 0
	expect_no_crash
	run "$name: cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $edits -o $name.cpu.exr $name.shot.exr"
	expect_status 0
	sed -e 's/^\(    LightSource "pointlight" 1 "intensity"\) 6 /\1 2.5 /' \
	    -e 's/^\(    LightSource "spotlight" 2 "intensity"\) 12 /\1 20 /' \
	    "$work/$name.rib" >"$work/$name.edited.rib"
	checks=$((checks + 1))
	[ "$(grep -c '"intensity" 2.5 \|"intensity" 20 ' "$work/$name.edited.rib")" -eq 2 ] ||
		fail "cannot edit $name.rib"
	run "$name: render" bash -c "cd '$work' && '$relight' render -q -o $name.ref.exr $name.edited.rib"
	expect_status 0
	run "$name: render before the edits" bash -c "cd '$work' && '$relight' render -q -o $name.before.exr $name.rib"
	expect_status 0
	grep -v '^    Atmosphere ' "$work/$name.rib" >"$work/$name.clear.rib"
	run "$name: render without the atmosphere" bash -c "cd '$work' && '$relight' render -q -o $name.clear.exr $name.clear.rib"
	expect_status 0
	run "$name: the atmosphere's effect" "$relight" diff --json "$work/$name.clear.exr" "$work/$name.before.exr"
	cp "$work/stdout" "$work/$name.atmosphere.json"
	run "$name: gpu vs cpu" "$relight" diff --json "$work/$name.cpu.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_cpu.json"
	run "$name: gpu vs render" "$relight" diff --json "$work/$name.ref.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_render.json"
	run "$name: the edits' effect" "$relight" diff --json "$work/$name.before.exr" "$work/$name.ref.exr"
	cp "$work/stdout" "$work/$name.change.json"
	checks=$((checks + 1))
	python3 - "$work/$name" "$max_rel" "$max_mean_pct" "$max_max_pct" "$min_change_pct" <<'PY' || fail "the GPU preview differs"
import json, sys
p, max_rel, max_mean, max_max, min_change = sys.argv[1], *map(float, sys.argv[2:])
c = json.load(open(p + ".vs_cpu.json"))
r = json.load(open(p + ".vs_render.json"))
e = json.load(open(p + ".change.json"))
a = json.load(open(p + ".atmosphere.json"))
print("%s: GPU vs CPU max_rel %.2g (limit %g); GPU vs edited render mean %.4f %% max %.4f %% "
      "(limits %g, %g); the edits change the render by %.2f %% mean, the atmosphere by %.2f %% "
      "(at least %g)"
      % (p.rsplit("/", 1)[1], c["max_rel"], max_rel, r["mean_pct"], r["max_pct"], max_mean,
         max_max, e["mean_pct"], a["mean_pct"], min_change))
assert c["max_rel"] <= max_rel and r["mean_pct"] <= max_mean and r["max_pct"] <= max_max
assert e["mean_pct"] >= min_change and a["mean_pct"] >= min_change
PY
}

gpu_case fog
gpu_case glow

finish
