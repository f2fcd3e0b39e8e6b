#!/usr/bin/env bash
# Ray-traced shadows that follow an edited light, on the GPU (raytrace/shadows.rib:
# a spot light whose shadow name is "raytrace", an opaque sphere, a half
# transparent one and an open box casting onto an occlusionplastic floor).
# No shadow map exists anywhere: the bake keeps the shadow geometry (diced as
# the renderer dices what its rays see), the GPU traces its hierarchy; the
# floor's occlusion is baked.
# Checks, each against `relight render --set` of the same edits, within 0.1 %
# mean and 1 % max of the 8-bit range (colour and alpha):
#  - the preview of the shot as baked;
#  - the light moved (from and to), recoloured and brighter: its shadows move;
#  - the shot holds no shadow map, the preview reports the hierarchy it built
#    (its bytes, nodes and two triangles per shadow micropolygon).
# Without an EGL context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"

rib="$source_dir/tests/cli/raytrace/shadows.rib"
cd "$work" || exit 1
cp "$rib" shadows.rib

run "bake" "$relight" bake -q -o shadows.shot.exr shadows.rib
expect_status 0
expect_empty_stderr
checks=$((checks + 1))
[ -z "$(ls ./*.tex ./*.shad ./*.z ./*.dsm 2>/dev/null)" ] || fail "a shadow map was written"
run "info" "$relight" info --json shadows.shot.exr
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("shot: %d shadow micropolygons, %d bytes of shadow geometry; hierarchy at most %d bytes"
      % (d["shadow_quads"], d["shadow_bytes"], d["shadow_bvh_bytes_max"]))
assert d["shadow_quads"] > 1000 and d["shadow_bvh_bytes_max"] > 0
' "$work/stdout" || fail "relight info: $(head -c 400 "$work/stdout")"

# case NAME EDIT...: render the edited RIB, preview the shot with the same edits, compare
case_() {
	local name=$1
	shift
	local sets=()
	for e in "$@"; do
		sets+=(--set "$e")
	done
	run "render $name" "$relight" render -q -o "$name.ref.exr" "${sets[@]}" shadows.rib
	expect_status 0
	run "preview $name" "$relight" preview -q --json -o "$name.gpu.exr" "${sets[@]}" shadows.shot.exr
	skip_without_gpu
	expect_status 0
	expect_no_crash
	cp "$work/stdout" "$name.json"
	expect_matches_render "$name" "$name.ref.exr" "$name.gpu.exr"
}

case_ baked
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("preview: hierarchy of %d bytes, %d nodes, %d triangles" %
      (d["shadow_bvh_bytes"], d["shadow_bvh_nodes"], d["shadow_bvh_triangles"]))
assert d["shadow_bvh_bytes"] > 0 and d["shadow_bvh_triangles"] > 2000 and d["shadow_bvh_nodes"] > 0
' baked.json || fail "the preview built no hierarchy: $(head -c 400 baked.json)"

case_ moved 1.from=-2,4.5,1.5 1.to=0.3,0,-0.2 1.lightcolor=1,0.8,0.6 1.intensity=40

# the moved light's shadow is not where the baked one was
run "moved vs baked" "$relight" diff --json "$work/moved.gpu.exr" "$work/baked.gpu.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("moved light vs baked: mean %.3f %%, %d pixels over 1 %%" % (d["mean_pct"], d["over_1pct"]))
assert d["mean_pct"] > 1
' "$work/stdout" || fail "moving the light changed nothing: $(head -c 300 "$work/stdout")"

finish
