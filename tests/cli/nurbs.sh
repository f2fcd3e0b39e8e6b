#!/usr/bin/env bash
# NuPatch and TrimCurve through `relight render`, the bake and the preview
# (the scenes are in tests/cli/nurbs/):
#
#   - a rational NuPatch sphere against Sphere 1 -1 1 360, and a square
#     NuPatch trimmed by a rational circle against Disk: per-pixel alpha
#     within 0.1 (10 % of the 8-bit range), mean alpha and colour within
#     0.1 % (`relight diff`);
#   - malformed NuPatch and TrimCurve requests: FILE:LINE errors, exit
#     status 1, only those primitives dropped (the image is the rest of the
#     frame's);
#   - shadow.rib, a trimmed NuPatch (an annulus of two loops) casting a
#     shadow-mapped spot light's shadow (the map from the RIB's own shadow
#     pass) on a floor: baked, previewed after light edits (intensity,
#     colour, a light's position) with --cpu and on the GPU, each against
#     `relight render --set` of the same edits: mean error <= 0.1 % and
#     maximum error <= 1 % of the 8-bit range, colour and alpha. Without an
#     EGL context the GPU part skips the script (exit 77) once the rest has
#     passed.
source "$(dirname "$0")/lib.sh"

cp "$source_dir"/tests/cli/nurbs/*.rib "$work/"

# same NAME: NAME.rib against NAME_ref.rib within the limits above.
same() {
	local name=$1
	run "$name: render" bash -c "cd '$work' && '$relight' render -q $name.rib && '$relight' render -q ${name}_ref.rib"
	expect_status 0
	expect_empty_stderr
	run "$name: diff" "$relight" diff --json "$work/${name}_ref.exr" "$work/$name.exr"
	checks=$((checks + 1))
	python3 - "$work/stdout" "$name" <<'PY' || fail "$name differs from its reference: $(cat "$work/stdout")"
import json, sys
d = json.load(open(sys.argv[1]))
a = d["alpha"]
print("%s: colour mean %.4f %% max %.3f %%, alpha mean %.4f %% max %.3f %%"
      % (sys.argv[2], d["mean_pct"], d["max_pct"], a["mean_pct"], a["max_pct"]))
assert a["max_pct"] <= 10.0 and a["mean_pct"] <= 0.1 and d["mean_pct"] <= 0.1
PY
}
same sphere
same disk

cat >"$work/bad.rib" <<'RIB'
Format 32 32 1
Display "bad.exr" "file" "rgba"
Translate 0 0 4
WorldBegin
  Sphere 0.5 -0.5 0.5 360
  NuPatch 2 2 [0 1 0 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [0 0 0 1 0 0 0 1 0 1 1 0]
  TrimCurve [1] [3] [0 0 0 1 1] [0] [1] [3] [0 1 1] [0 0 1] [1 1 1]
  NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [0 0 0 1 0 0 0 1 0 1 1 0]
WorldEnd
RIB
sed -e '/NuPatch\|TrimCurve/d' -e 's/bad.exr/good.exr/' "$work/bad.rib" >"$work/good.rib"
run "malformed" bash -c "cd '$work' && '$relight' render -q bad.rib"
expect_no_crash
expect_status 1
expect_stderr "^bad.rib:6: error: NuPatch: a knot vector decreases"
expect_stderr "^bad.rib:7: error: TrimCurve: knot has 5 values, expected 6"
expect_stderr "^bad.rib:8: error: NuPatch: its TrimCurve .line 7. is malformed"
run "the rest of the frame" bash -c "cd '$work' && '$relight' render -q good.rib && '$relight' diff --json good.exr bad.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["max_pct"] == 0 and d["alpha"]["max_pct"] == 0, d
' "$work/stdout" || fail "the malformed scene's image is not the rest of the frame's"

# The bake and the preview. Lights: ambient 1, shadowspot 2 (key.shd), point 3.
edits=(--set 2.intensity=60 --set 2.lightcolor=1,0.85,0.7 --set 3.from=-2,4,-1)
run "shadow: render --set" bash -c "cd '$work' && '$relight' render -q ${edits[*]} -o ref.exr shadow.rib"
expect_status 0
expect_empty_stderr
run "shadow: bake" bash -c "cd '$work' && '$relight' bake -q -o shadow.shot.exr shadow.rib"
expect_status 0
expect_true "the shadow map was made" test -s "$work/key.shd"
run "shadow: shadow geometry" "$relight" info --json "$work/shadow.shot.exr"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["shadow_quads"] > 0, d
' "$work/stdout" || fail "the shot has no shadow geometry"

run "shadow: preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu ${edits[*]} -o cpu.exr shadow.shot.exr"
expect_status 0
expect_no_crash
expect_matches_render "preview --cpu" ref.exr cpu.exr

run "shadow: preview (GPU)" bash -c "cd '$work' && '$relight' preview -q ${edits[*]} -o gpu.exr shadow.shot.exr"
skip_without_gpu
expect_status 0
expect_no_crash
expect_matches_render "preview (GPU)" ref.exr gpu.exr

finish
