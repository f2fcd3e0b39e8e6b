#!/usr/bin/env bash
# `relight bake` and `relight info`: help and usage errors, a small scene baked
# end to end (the shot file is multi-part OpenEXR that exrheader reads), its
# figures, and bad input ending in a clear error, never a crash.
source "$(dirname "$0")/lib.sh"

run "help" "$relight" bake --help
expect_status 0
expect_stdout "^usage: relight bake \[OPTIONS\] SCENE.rib"
expect_stdout "--dynamic-surface"

run "info help" "$relight" info --help
expect_status 0
expect_stdout "^usage: relight info \[--json\] SHOT.exr"

run "listed in relight --help" "$relight" --help
expect_stdout "bake +Bake a RIB scene"
expect_stdout "info +Describe a shot file"

run "no scene" "$relight" bake
expect_status 2
expect_stderr "no scene file"

run "bad compression" "$relight" bake --compress lzma x.rib
expect_status 2
expect_stderr "--compress needs none, rle, zips or zip"

run "missing scene" "$relight" bake "$work/none.rib"
expect_status 1
expect_stderr "cannot read '$work/none.rib'"

# Two spheres, one half transparent in front of the other, two lights that
# reach different objects.
cat >"$work/two.rib" <<'RIB'
Format 40 30 1
PixelSamples 8 8
Display "two.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1
  LightSource "pointlight" 2 "from" [0 2 2] "intensity" 4
  AttributeBegin
    Illuminate 2 0
    Surface "plastic"
    Translate 0 0 6
    Sphere 1.5 -1.5 1.5 360
  AttributeEnd
  AttributeBegin
    Surface "matte"
    Opacity [0.5 0.5 0.5]
    Translate 0.6 0 4
    Sphere 0.8 -0.8 0.8 360
  AttributeEnd
WorldEnd
RIB
run "bakes" bash -c "cd '$work' && '$relight' bake two.rib"
expect_no_crash
expect_status 0
expect_stderr "^wrote two.shot.exr: 40x30, [0-9]+ shading samples kept of [0-9]+ shaded"
checks=$((checks + 1))
[ -s "$work/two.shot.exr" ] || fail "two.shot.exr not written"
checks=$((checks + 1))
ls "$work"/*.tmp.* >/dev/null 2>&1 && fail "a temporary file was left behind"

if command -v exrheader >/dev/null 2>&1; then
	run "exrheader reads the shot" exrheader "$work/two.shot.exr"
	expect_status 0
	expect_stdout "samples.plastic"
	expect_stdout "samples.matte"
	expect_stdout "deepscanline"
fi

run "info --json" "$relight" info --json "$work/two.shot.exr"
expect_status 0
expect_no_crash
checks=$((checks + 1))
python3 - "$work/stdout" <<'PY' || fail "info --json figures are wrong"
import json, sys
d = json.load(open(sys.argv[1]))
assert d["width"] == 40 and d["height"] == 30, d
assert d["lights"] == ["1", "2"], d["lights"]
assert sorted(d["surfaces"]) == ["matte", "plastic"], d["surfaces"]
assert d["subpixel_samples"] == 40 * 30 * 64, d
# every kept sample was shaded; entries are merged per pixel
assert 0 < d["shading_samples"] <= d["shaded_points"], d
assert 0 < d["indirect_entries"] < d["subpixel_samples"], d
ch = d["channels"]
assert ch["dynamic"] >= ch["varying"] >= ch["unique"] > 0, ch
assert d["bytes"]["ifb"] > 0 and d["total_bytes"] >= sum(d["bytes"].values()) - 1, d
PY

run "info text" "$relight" info "$work/two.shot.exr"
expect_status 0
expect_stdout "^shading samples: [0-9]+ kept of [0-9]+ shaded"
expect_stdout "^indirect entries: [0-9]+ for 76800 subpixel samples"

# The CPU resolver against the reference renderer: within 0.1% mean and 1%
# max of the 8-bit range (transparency, two light sets; then motion blur).
check_resolve() {
	run "$1: render" bash -c "cd '$work' && '$relight' render -q -o ref.exr $2"
	expect_status 0
	run "$1: bake" bash -c "cd '$work' && '$relight' bake -q -o r.shot.exr $2"
	expect_status 0
	run "$1: preview --cpu" bash -c "cd '$work' && '$relight' preview --cpu -o prev.exr r.shot.exr"
	expect_status 0
	expect_no_crash
	expect_stderr "^wrote prev.exr: 40x30, [0-9]+ samples shaded"
	run "$1: diff" "$relight" diff --json "$work/ref.exr" "$work/prev.exr"
	expect_status 0
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
' "$work/stdout" || fail "preview --cpu differs from the reference"
}
check_resolve "transparency" two.rib
sed -e 's/^Format 40 30 1$/Format 40 30 1\nShutter 0 1/' \
    -e 's/^    Translate 0.6 0 4$/    MotionBegin [0 1]\n      Translate 0.6 0 4\n      Translate 1.2 0.3 4\n    MotionEnd/' \
    "$work/two.rib" >"$work/motion.rib"
checks=$((checks + 1))
grep -q MotionBegin "$work/motion.rib" || fail "motion.rib has no motion"
check_resolve "motion blur" motion.rib

# Refinement levels (lightspeed §5.2): each coarser level shades fewer
# samples and resolves fewer entries; the coarse levels are previews, so only
# a loose bound holds for them (PSNR at least 20 dB on this scene), and the
# error falls from the coarsest to the final level.
for level in 0 1 2 3; do
	run "level $level" bash -c "cd '$work' && '$relight' preview --cpu --level $level --json -o l$level.exr r.shot.exr"
	expect_status 0
	expect_no_crash
	cp "$work/stdout" "$work/level$level.json"
	run "level $level: diff" "$relight" diff --json "$work/ref.exr" "$work/l$level.exr"
	cp "$work/stdout" "$work/diff$level.json"
done
checks=$((checks + 1))
python3 - "$work" <<'PY' || fail "refinement levels are wrong"
import json, sys
w = sys.argv[1]
lv = [json.load(open(f"{w}/level{i}.json")) for i in range(4)]
df = [json.load(open(f"{w}/diff{i}.json")) for i in range(4)]
for a, b in zip(lv, lv[1:]):
    assert a["samples"] <= b["samples"] and a["entries"] <= b["entries"], (a, b)
assert lv[0]["samples"] < lv[3]["samples"], lv
assert lv[0]["entries"] == 10 * 8 and lv[1]["entries"] == 20 * 15, lv
assert lv[2]["entries"] == 40 * 30, lv[2]
for d in df[:3]:
    assert d["psnr_db"] >= 20, d
assert df[0]["rmse"] >= df[3]["rmse"] and df[2]["rmse"] >= df[3]["rmse"], df
assert df[3]["mean_pct"] < 0.1 and df[3]["max_pct"] < 1.0, df[3]
PY
run "bad level" "$relight" preview --cpu --level 7 "$work/r.shot.exr"
expect_status 2
expect_stderr "--level needs 0, 1, 2, 3 or final"

# Tiles: under a tiny budget the frame is cut into tiles, each with its own
# samples; every level resolves exactly as from one tile.
run "tiled bake" bash -c "cd '$work' && '$relight' bake -q --tile-budget 0.1 -o tiled.shot.exr motion.rib"
expect_status 0
run "tiled info" "$relight" info --json "$work/tiled.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["tiles"] > 1 and d["tile_size"] % 4 == 0, d
assert d["sample_rows"] > d["shading_samples"], d
' "$work/stdout" || fail "the tiny budget did not tile the frame"
for level in 0 3; do
	run "tiled level $level" bash -c "cd '$work' && '$relight' preview -q --cpu --level $level -o t$level.exr tiled.shot.exr"
	expect_status 0
	run "tiled level $level: same" "$relight" diff --json "$work/l$level.exr" "$work/t$level.exr"
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["rmse"] == 0, d
' "$work/stdout" || fail "tiles change level $level"
done
run "bad tile budget" "$relight" bake --tile-budget 0 "$work/two.rib"
expect_status 2
expect_stderr "--tile-budget needs megabytes"
run "bad shadow rate" "$relight" bake --shadow-rate nan "$work/two.rib"
expect_status 2
expect_stderr "--shadow-rate needs a number"

# Shadow geometry: written when a light casts shadows (a shadowspot with a
# map; the map need not exist for the geometry), at the rate asked for.
sed -e 's/LightSource "distantlight" 1/LightSource "shadowspot" 1 "from" [0 3 0] "to" [0 0 5] "shadowname" "none.shd"/' \
    "$work/two.rib" >"$work/caster.rib"
for rate in 4 16; do
	run "shadow geometry at rate $rate" bash -c "cd '$work' && '$relight' bake -q --shadow-rate $rate -o caster$rate.shot.exr caster.rib 2>/dev/null && '$relight' info --json caster$rate.shot.exr"
	expect_status 0
	cp "$work/stdout" "$work/caster$rate.json"
done
checks=$((checks + 1))
python3 - "$work/caster4.json" "$work/caster16.json" "$work/level3.json" <<'PY' || fail "shadow geometry figures are wrong"
import json, sys
a, b = (json.load(open(p)) for p in sys.argv[1:3])
assert a["shadow_quads"] > 0 and a["bytes"]["shadow.quads"] > 0, a
# a quarter of the area per micropolygon: about four times as many
assert 2.5 < a["shadow_quads"] / b["shadow_quads"] < 5.5, (a["shadow_quads"], b["shadow_quads"])
PY
run "no caster, no shadow geometry" "$relight" info --json "$work/r.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["shadow_quads"] == 0 and "shadow.quads" not in d["bytes"], d
' "$work/stdout" || fail "a shot without shadow-casting lights has shadow geometry"

# Editable surface parameters keep each object's own values: two spheres
# whose plastic has different Kd and Ks, both marked editable.
cat >"$work/kd.rib" <<'RIB'
Format 40 30 1
PixelSamples 2 2
Display "kd.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1
  AttributeBegin
    Surface "plastic" "Kd" 0.2 "Ks" 0.1
    Translate -1 0 6
    Sphere 1.2 -1.2 1.2 360
  AttributeEnd
  AttributeBegin
    Surface "plastic" "Kd" 0.9
    Translate 1.2 0 6
    Sphere 1.2 -1.2 1.2 360
  AttributeEnd
WorldEnd
RIB
run "per-object editable values" bash -c "cd '$work' && '$relight' render -q -o kdref.exr kd.rib && '$relight' bake -q --dynamic-surface Kd,Ks -o kd.shot.exr kd.rib && '$relight' preview -q --cpu -o kdprev.exr kd.shot.exr && '$relight' diff --json kdref.exr kdprev.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
' "$work/stdout" || fail "editable parameters lost their per-object values"

# Half channels: the default stores some channels as half, --full-float none;
# both resolve within the tolerance above.
run "full float" bash -c "cd '$work' && '$relight' bake -q --full-float -o ff.shot.exr motion.rib && '$relight' info --json ff.shot.exr"
expect_status 0
cp "$work/stdout" "$work/ff.json"
run "default info" "$relight" info --json "$work/r.shot.exr"
checks=$((checks + 1))
python3 - "$work/ff.json" "$work/stdout" <<'PY' || fail "half channels are not used as they should be"
import json, sys
ff, hf = (json.load(open(p)) for p in sys.argv[1:3])
assert ff["channels"]["half"] == 0 and ff["channels"]["float"] == ff["channels"]["unique"], ff
assert hf["channels"]["half"] > 0, hf["channels"]
assert hf["channels"]["half"] + hf["channels"]["float"] == hf["channels"]["unique"], hf
assert sum(v for k, v in hf["bytes"].items() if k.startswith("samples.")) < \
       sum(v for k, v in ff["bytes"].items() if k.startswith("samples.")), (hf["bytes"], ff["bytes"])
PY

# Light edits: the CPU preview of the shot with --set edits against a render
# of the RIB edited the same way, within the same tolerance.
run "edited bake" bash -c "cd '$work' && '$relight' bake -q -o edit.shot.exr two.rib"
expect_status 0
sed -e 's/LightSource "distantlight" 1/LightSource "distantlight" 1 "lightcolor" [1 0.5 0.25] "from" [1 -1 1]/' \
    -e 's/"from" \[0 2 2\] "intensity" 4/"from" [-1 1 3] "intensity" 9.5/' \
    "$work/two.rib" >"$work/edited.rib"
checks=$((checks + 1))
grep -q '9.5' "$work/edited.rib" && grep -q '0.25' "$work/edited.rib" || fail "the RIB edit did not apply"
run "edited render" bash -c "cd '$work' && '$relight' render -q -o edref.exr edited.rib"
expect_status 0
run "preview --set" bash -c "cd '$work' && '$relight' preview -q --cpu --set 1.lightcolor=1,0.5,0.25 --set 1.from=1,-1,1 --set 2.from=-1,1,3 --set 2.intensity=9.5 -o edprev.exr edit.shot.exr"
expect_status 0
expect_empty_stderr
run "preview --set matches the edited render" "$relight" diff --json "$work/edref.exr" "$work/edprev.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] < 0.1 and d["max_pct"] < 1.0, d
' "$work/stdout" || fail "an edited preview differs from the edited render"
run "unedited preview" bash -c "cd '$work' && '$relight' preview -q --cpu -o noedit.exr edit.shot.exr"
expect_status 0
run "the edit changed the picture" "$relight" diff --json "$work/noedit.exr" "$work/edprev.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
assert json.load(open(sys.argv[1]))["mean_pct"] > 1.0
' "$work/stdout" || fail "the --set edits had no effect"
run "--set unknown light" "$relight" preview --cpu --set 7.intensity=1 "$work/edit.shot.exr"
expect_status 1
expect_stderr "no light named '7'; the shot's lights are: 1 2"
run "--set unknown parameter" "$relight" preview --cpu --set 2.nope=1 "$work/edit.shot.exr"
expect_status 1
expect_stderr "light '2' \(shader 'pointlight'\) has no parameter 'nope'"
run "--set wrong count" "$relight" preview --cpu --set 2.from=1,2 "$work/edit.shot.exr"
expect_status 1
expect_stderr "takes 3 values, not 2"
run "--set not finite" "$relight" preview --cpu --set 2.intensity=inf "$work/edit.shot.exr"
expect_status 1
expect_stderr "needs finite values"
run "--set malformed" "$relight" preview --cpu --set 2.intensity "$work/edit.shot.exr"
expect_status 2
expect_stderr "--set needs LIGHT.PARAM=V"

run "preview on the GPU" "$relight" preview -q -o "$work/r.gpu.exr" "$work/r.shot.exr"
checks=$((checks + 1))
if [ "$status" -ne 0 ] && ! grep -q "no GPU context" "$work/stderr"; then
	fail "the GPU preview failed without saying there is no GPU context (status $status)"
fi
run "GPU preview of junk" "$relight" preview "$work/two.rib"
expect_status 1
expect_stderr "relight: error: "
run "preview of junk" "$relight" preview --cpu "$work/two.rib"
expect_status 1
expect_no_crash

# -o, and an unwritable output leaves no file and says why.
run "-o" bash -c "cd '$work' && '$relight' bake -q -o other.exr two.rib"
expect_status 0
expect_empty_stderr
run "unwritable output" bash -c "cd '$work' && '$relight' bake -q -o /nonexistent/dir/x.exr two.rib"
expect_status 1
expect_no_crash
expect_stderr "/nonexistent/dir/x.exr"

# A scene with only a shadow pass has nothing to bake.
cat >"$work/shadowonly.rib" <<'RIB'
Format 16 16 1
Display "d.z" "zfile" "z"
WorldBegin
  Sphere 1 -1 1 360
WorldEnd
RIB
run "shadow pass only" bash -c "cd '$work' && '$relight' bake -q shadowonly.rib"
expect_status 1
expect_stderr "no frame to bake"

# Not shot files.
run "info on a missing file" "$relight" info "$work/none.exr"
expect_status 1
expect_stderr "none.exr"
printf 'not an exr' >"$work/junk.exr"
run "info on junk" "$relight" info "$work/junk.exr"
expect_status 1
expect_no_crash
expect_stderr "junk.exr"

# Deforming primitives (tests/cli/deform/deform.rib).
cp "$source_dir/tests/cli/deform/deform.rib" "$work/"
check_resolve "deforming primitives" deform.rib

# Primitives with no Surface are shaded by the default surface, which the
# bake compiles itself: its program must outlive the render, since the shot
# names it (under AddressSanitizer a use after free, before).
cat >"$work/nosurface.rib" <<'RIB'
Format 40 30 1
PixelSamples 2 2
Display "nosurface.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1 "from" [1 1 -1] "to" [0 0 0]
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
RIB
check_resolve "the default surface" nosurface.rib

finish
