#!/usr/bin/env bash
# The GPU runtime (`relight preview` without --cpu) on the lens scenes of
# tests/cli/lens/ (depth of field; a panning, turning camera with a moving
# sphere; both at once), with a light edit: against the CPU resolver, the
# largest relative difference at most 1e-4 (as tests/cli/gpu.sh), and against
# `relight render` of the RIB edited the same way, mean error <= 0.1 % and
# maximum error <= 1 % of the 8-bit range. Without an EGL context the script
# skips (exit 77).
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0

cp "$source_dir/tests/cli/lens/dof.rib" "$source_dir/tests/cli/lens/pan.rib" "$work/"
sed -e 's/^Projection "perspective" "fov" 40$/Projection "perspective" "fov" 40\nDepthOfField 1 0.5 4/' \
    "$work/pan.rib" >"$work/both.rib"
checks=$((checks + 1))
grep -q DepthOfField "$work/both.rib" || fail "both.rib has no DepthOfField"

run "bake dof.rib" bash -c "cd '$work' && '$relight' bake -q -o dof.shot.exr dof.rib"
expect_status 0
run "EGL context" bash -c "cd '$work' && '$relight' preview -q -o probe.exr dof.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi
expect_status 0

# gpu_case NAME: NAME.rib baked, previewed on the GPU and on the CPU with
# light 1 at half intensity, against the render of the edited RIB.
gpu_case() {
	local name=$1
	run "$name: bake" bash -c "cd '$work' && '$relight' bake -q -o $name.shot.exr $name.rib"
	expect_status 0
	run "$name: gpu" bash -c "cd '$work' && '$relight' preview -q --set 1.intensity=0.45 -o $name.gpu.exr $name.shot.exr"
	expect_status 0
	expect_no_crash
	run "$name: cpu" bash -c "cd '$work' && '$relight' preview -q --cpu --set 1.intensity=0.45 -o $name.cpu.exr $name.shot.exr"
	expect_status 0
	sed -e 's/^\(  LightSource "distantlight" 1 "intensity"\) 0.9/\1 0.45/' "$work/$name.rib" >"$work/$name.edited.rib"
	checks=$((checks + 1))
	grep -q '"distantlight" 1 "intensity" 0.45' "$work/$name.edited.rib" || fail "cannot edit $name.rib"
	run "$name: render" bash -c "cd '$work' && '$relight' render -q -o $name.ref.exr $name.edited.rib"
	expect_status 0
	run "$name: gpu vs cpu" "$relight" diff --json "$work/$name.cpu.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_cpu.json"
	run "$name: gpu vs render" "$relight" diff --json "$work/$name.ref.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_render.json"
	checks=$((checks + 1))
	python3 - "$work/$name" "$max_rel" "$max_mean_pct" "$max_max_pct" <<'PY' || fail "the GPU preview differs"
import json, sys
p, max_rel, max_mean, max_max = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
c = json.load(open(p + ".vs_cpu.json"))
r = json.load(open(p + ".vs_render.json"))
print("%s: GPU vs CPU max_rel %.2g (limit %g); GPU vs edited render mean %.4f %% max %.4f %% (limits %g, %g)"
      % (p.rsplit("/", 1)[1], c["max_rel"], max_rel, r["mean_pct"], r["max_pct"], max_mean, max_max))
assert c["max_rel"] <= max_rel and r["mean_pct"] <= max_mean and r["max_pct"] <= max_max
PY
}

gpu_case dof
gpu_case pan
gpu_case both

finish
