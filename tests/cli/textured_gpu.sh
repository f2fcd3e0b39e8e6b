#!/usr/bin/env bash
# Lights that read texture and environment maps, on the GPU: the
# textured_lights example (an uberlight slide, a cookie, a slide projector, a
# light coloured by a lat-long environment map, an environment light, under
# fog, through a background imager) baked, then previewed on the GPU after
# edits of intensity, colour, position, of the maps themselves (the slides
# swapped, the cookie replaced), of the environment light and of the imager, each against `relight render
# --set` of the same edits (mean error <= 0.1 %, maximum <= 1 % of the 8-bit
# range) and against the CPU resolver (largest relative difference <= 1e-4,
# as tests/cli/gpu.sh). A swap of maps compiles no program. The swap is also
# checked against the RIB edited the same way; a missing map is the fill,
# with a warning naming it and exit status 3, as on the CPU. Without an EGL
# context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0
# the example's shaders, whatever the binary's own library holds
export RELIGHT_SHADER_PATH="$source_dir/shaders"

cp -R "$source_dir/examples/textured_lights/." "$work/"
run "bake" bash -c "cd '$work' && '$relight' bake -q textured_lights.rib"
expect_status 0
# The first load compiles every kernel of the shot: on llvmpipe with cold
# caches about a minute on a quiet machine (uberlight's and envlight's kernels
# are large), so this one command may take longer than the others.
limit_before=$limit
limit=$((limit * 5))
run "EGL context" bash -c "cd '$work' && '$relight' preview -q -o probe.exr textured_lights.shot.exr"
limit=$limit_before
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi
expect_status 0
expect_no_crash

# compare NAME REF: NAME.gpu.exr against NAME.cpu.exr and REF.
compare() {
	local name=$1 ref=$2
	run "$name: gpu vs cpu" "$relight" diff --json "$work/$name.cpu.exr" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_cpu.json"
	run "$name: gpu vs render" "$relight" diff --json "$work/$ref" "$work/$name.gpu.exr"
	cp "$work/stdout" "$work/$name.vs_render.json"
	checks=$((checks + 1))
	python3 - "$work/$name" "$max_rel" "$max_mean_pct" "$max_max_pct" <<'PY' || fail "$name: the GPU preview differs"
import json, sys
p, max_rel, max_mean, max_max = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4])
c = json.load(open(p + ".vs_cpu.json"))
r = json.load(open(p + ".vs_render.json"))
g = json.load(open(p + ".gpu.json"))
print("%s: GPU vs CPU max_rel %.2g (limit %g); GPU vs render mean %.4f %% max %.4f %% (limits %g, %g); "
      "edit %.0f ms, %d programs made by the edit, %d maps in %d bytes"
      % (p.rsplit("/", 1)[1], c["max_rel"], max_rel, r["mean_pct"], r["max_pct"], max_mean, max_max,
         g["edit_ms"], g.get("programs_by_edits", -1), g.get("texture_maps", -1),
         g.get("texture_map_bytes", -1)))
assert c["max_rel"] <= max_rel and r["mean_pct"] <= max_mean and r["max_pct"] <= max_max
PY
}

# edit_case NAME EDIT...: the GPU and CPU previews with the edits, against
# `relight render --set` of the same edits.
edit_case() {
	local name=$1
	shift
	local sets=() e
	for e in "$@"; do
		sets+=(--set "$e")
	done
	run "$name: gpu" bash -c "cd '$work' && '$relight' preview -q --json ${sets[*]} -o $name.gpu.exr textured_lights.shot.exr"
	expect_status 0
	expect_no_crash
	cp "$work/stdout" "$work/$name.gpu.json"
	run "$name: cpu" bash -c "cd '$work' && '$relight' preview -q --cpu ${sets[*]} -o $name.cpu.exr textured_lights.shot.exr"
	expect_status 0
	run "$name: render" bash -c "cd '$work' && '$relight' render -q ${sets[*]} -o $name.ref.exr textured_lights.rib"
	expect_status 0
	compare "$name" "$name.ref.exr"
}

edit_case intensity 2.intensity=0.9 4.intensity=9
edit_case colour 4.lightcolor=1,0.7,0.5 3.lightcolor=0.6,0.8,1
edit_case position 3.from=3,5,1 5.from=0.4,1.3,2.2
edit_case slides 2.slidename=slide_b.tx 4.slidename=slide_a.tx
edit_case cookie 3.cookiename=slide_a.tx 3.blur=0.02
edit_case environment 5.blur=0.05 5.intensity=2
edit_case envlight 6.intensity=0.3 6.lightcolor=1,0.9,0.7
edit_case imager imager.bgcolor=0.3,0.2,0.1 2.intensity=1.1

# a map swap is a binding: no program is compiled or read for it
checks=$((checks + 1))
python3 - "$work/slides.gpu.json" "$work/cookie.gpu.json" <<'PY' || fail "swapping maps made GPU programs"
import json, sys
for p in sys.argv[1:]:
	j = json.load(open(p))
	assert j["programs_at_load"] > 0 and j["programs_by_edits"] == 0, (p, j["programs_by_edits"])
PY

# the slide swap against the RIB edited the same way
sed -e 's/"uberlight" 2 "intensity" 1.5 "slidename" "slide_a.tx"/"uberlight" 2 "intensity" 1.5 "slidename" "slide_b.tx"/' \
	-e 's/"fov" 0.5 "aspect" 1.5 "slidename" "slide_b.tx"/"fov" 0.5 "aspect" 1.5 "slidename" "slide_a.tx"/' \
	"$work/textured_lights.rib" >"$work/swapped.rib"
checks=$((checks + 1))
[ "$(grep -c 'slidename" "slide_b.tx"\|slidename" "slide_a.tx"' "$work/swapped.rib")" -eq 2 ] &&
	! diff -q "$work/textured_lights.rib" "$work/swapped.rib" >/dev/null || fail "cannot edit the RIB"
run "swapped RIB: render" bash -c "cd '$work' && '$relight' render -q -o swapped.exr swapped.rib"
expect_status 0
cp "$work/slides.gpu.exr" "$work/swapped_rib.gpu.exr"
cp "$work/slides.cpu.exr" "$work/swapped_rib.cpu.exr"
cp "$work/slides.gpu.json" "$work/swapped_rib.gpu.json"
compare swapped_rib swapped.exr

# a missing map: the fill, a warning naming it, exit status 3, on both sides
run "missing slide: gpu" bash -c "cd '$work' && '$relight' preview -q --set 2.slidename=nothere.tx -o missing.gpu.exr textured_lights.shot.exr"
expect_no_crash
expect_status 3
expect_stderr "light '2': nothere.tx: not found"
expect_stderr "^relight preview: error: missing.gpu.exr is not the shot's image"
run "missing slide: cpu" bash -c "cd '$work' && '$relight' preview -q --cpu --set 2.slidename=nothere.tx -o missing.cpu.exr textured_lights.shot.exr"
expect_status 3
expect_stderr "texture 'nothere.tx' not found"
run "missing slide: gpu vs cpu" "$relight" diff --json "$work/missing.cpu.exr" "$work/missing.gpu.exr"
cp "$work/stdout" "$work/missing.json"
checks=$((checks + 1))
python3 -c "import json,sys; j=json.load(open(sys.argv[1])); assert j['max_rel'] <= 1e-4, j['max_rel']" \
	"$work/missing.json" || fail "the fill of a missing map differs between the GPU and the CPU"

# values of the wrong kind are refused, naming the parameter's type
run "numbers for a string" bash -c "cd '$work' && '$relight' preview -q --set 2.slidename=1 -o bad.exr textured_lights.shot.exr"
expect_status 1
expect_stderr "parameter 'slidename' is a string"
run "a string for a float" bash -c "cd '$work' && '$relight' preview -q --set 2.intensity=bright -o bad.exr textured_lights.shot.exr"
expect_status 1
expect_stderr "parameter 'intensity' needs numbers, not 'bright'"

finish
