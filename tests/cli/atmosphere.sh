#!/usr/bin/env bash
# Volume shaders from the command line (the closed forms are in
# tests/unit/test_atmosphere.c, the GPU preview in atmosphere_gpu.sh):
#   - fog and depthcue compile as volume shaders, fog joins plastic (`compile
#     --atmosphere`: its d is cached); a volume shader that reads a surface's
#     global (N) is an error at its line;
#   - Interior and Exterior render with a warning at their line, an error
#     under --strict;
#   - an atmosphere that is no sum over the lights (Ci * Ci) bakes with a
#     warning at its line, and fails under --strict;
#   - an atmosphere parameter named like one of the surface's keeps its own
#     value (the image is the one of a surface without the clash);
#   - examples/fog, baked and previewed on the CPU after two light edits,
#     against `relight render` of the RIB edited the same way: mean error
#     <= 0.1 %, maximum <= 1 % of the 8-bit range; the atmosphere changes the
#     render by a mean of 1 % or more.
source "$(dirname "$0")/lib.sh"

max_mean_pct=0.1
max_max_pct=1.0

run "compile fog" "$relight" compile --emit report "$source_dir/shaders/fog.sl"
expect_status 0
expect_stdout '"type": "volume"'
run "compile depthcue" "$relight" compile "$source_dir/shaders/depthcue.sl"
expect_status 0
expect_empty_stderr
run "compile a surface with an atmosphere" "$relight" compile --atmosphere fog --emit report plastic
expect_status 0
expect_stdout '"name": "plastic\+fog"'
expect_stdout '"name": "d", "type": "float"'
run "compile --atmosphere of a surface" "$relight" compile --atmosphere plastic plastic
expect_status 1
expect_stderr "'plastic' a surface shader"
printf 'volume v()\n{\n\tfloat x = N . N;\n\tCi = x;\n}\n' >"$work/v.sl"
run "a volume shader reads N" "$relight" compile "$work/v.sl"
expect_status 1
expect_stderr "^$work/v.sl:3:[0-9]+: error: 'N' is not available in a volume shader"

cat >"$work/plane.rib" <<'RIB'
Format 16 16 1
Projection "perspective" "fov" 30
Display "plane.exr" "file" "rgba"
WorldBegin
  Color [0.8 0.3 0.1]
  Surface "constant"
  Interior "fog"
  Exterior "fog"
  Polygon "P" [-10 -10 5  10 -10 5  10 10 5  -10 10 5]
WorldEnd
RIB
run "Interior, Exterior" bash -c "cd '$work' && '$relight' render plane.rib"
expect_status 0
expect_stderr "plane.rib:7: warning: Interior shaders act on traced rays, which relight does not trace: no effect"
expect_stderr "plane.rib:8: warning: Exterior shaders act on traced rays"
run "Interior, Exterior, --strict" bash -c "cd '$work' && '$relight' render --strict plane.rib"
expect_status 1
expect_stderr "plane.rib:7: .*error under --strict"

cat >"$work/square.sl" <<'SL'
volume square()
{
	Ci = Ci * Ci;
}
SL
cat >"$work/lit.rib" <<RIB
Option "searchpath" "shader" "$work:@"
Format 32 24 1
Projection "perspective" "fov" 40
Display "lit.exr" "file" "rgba"
WorldBegin
  LightSource "pointlight" 1 "intensity" 6 "from" [1 1 2]
  LightSource "pointlight" 2 "intensity" 3 "from" [-1 1 2]
  Surface "plastic"
  Atmosphere "square"
  Polygon "P" [-10 -10 5  10 -10 5  10 10 5  -10 10 5]
WorldEnd
RIB
run "bake a non-additive atmosphere" bash -c "cd '$work' && '$relight' bake -q -o lit.shot.exr lit.rib"
expect_status 0
expect_stderr "^$work/square.sl:3: warning: atmosphere 'square' after surface 'plastic': .* no sum over the lights"
run "bake a non-additive atmosphere, --strict" bash -c "cd '$work' && '$relight' bake -q --strict -o lit2.shot.exr lit.rib"
expect_status 1
expect_stderr "^$work/square.sl:3: error: atmosphere 'square'"

cat >"$work/clash.sl" <<'SL'
surface clash(float distance = 0.5)
{
	Oi = Os;
	Ci = Os * Cs * distance;
}
SL
cat >"$work/noclash.sl" <<'SL'
surface noclash(float k = 0.5)
{
	Oi = Os;
	Ci = Os * Cs * k;
}
SL
for s in clash noclash; do
	cat >"$work/$s.rib" <<RIB
Option "searchpath" "shader" "$work:@"
Format 32 24 1
Projection "perspective" "fov" 40
Display "$s.exr" "file" "rgba" "string type" "float"
WorldBegin
  Color [0.8 0.3 0.1]
  Surface "$s"
  Atmosphere "fog" "distance" 4 "background" [0.2 0.4 0.9]
  Polygon "P" [-10 -10 5  10 -10 5  10 10 5  -10 10 5]
WorldEnd
RIB
	run "render $s" bash -c "cd '$work' && '$relight' render -q $s.rib"
	expect_status 0
done
run "a parameter name in both shaders" "$relight" diff --json "$work/noclash.exr" "$work/clash.exr"
expect_status 0
expect_stdout '"max_rel": 0[,}]'

cp "$source_dir/examples/fog/"* "$work/"
for name in fog glow; do
	edits="--set 1.intensity=2.5 --set 2.intensity=20"
	run "$name: bake" bash -c "cd '$work' && '$relight' bake -q -o $name.shot.exr $name.rib"
	expect_status 0
	run "$name: cpu" bash -c "cd '$work' && '$relight' preview -q --cpu $edits -o $name.cpu.exr $name.shot.exr"
	expect_status 0
	sed -e 's/^\(    LightSource "pointlight" 1 "intensity"\) 6 /\1 2.5 /' \
	    -e 's/^\(    LightSource "spotlight" 2 "intensity"\) 12 /\1 20 /' \
	    "$work/$name.rib" >"$work/$name.edited.rib"
	run "$name: render" bash -c "cd '$work' && '$relight' render -q -o $name.ref.exr $name.edited.rib"
	expect_status 0
	grep -v '^    Atmosphere ' "$work/$name.edited.rib" >"$work/$name.clear.rib"
	run "$name: render without the atmosphere" bash -c "cd '$work' && '$relight' render -q -o $name.clear.exr $name.clear.rib"
	expect_status 0
	run "$name: the atmosphere's effect" "$relight" diff --json "$work/$name.clear.exr" "$work/$name.ref.exr"
	checks=$((checks + 1))
	python3 -c "import json, sys; m = json.load(open(sys.argv[1]))['mean_pct']; print('$name: the atmosphere changes the render by %.2f %% mean (at least 1)' % m); sys.exit(m < 1)" "$work/stdout" ||
		fail "the atmosphere has no effect"
	run "$name: cpu vs render" "$relight" diff --json "$work/$name.ref.exr" "$work/$name.cpu.exr"
	checks=$((checks + 1))
	python3 - "$work/stdout" "$name" "$max_mean_pct" "$max_max_pct" <<'PY' || fail "the CPU preview differs"
import json, sys
r = json.load(open(sys.argv[1]))
print("%s: CPU preview after the edits vs edited render: mean %.4f %% max %.4f %% (limits %s, %s)"
      % (sys.argv[2], r["mean_pct"], r["max_pct"], sys.argv[3], sys.argv[4]))
assert r["mean_pct"] <= float(sys.argv[3]) and r["max_pct"] <= float(sys.argv[4])
PY
done

finish
