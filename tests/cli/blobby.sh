#!/usr/bin/env bash
# Blobby (and Geometry "teapot") through render, bake and preview, and
# Blobby's bad input.
#
# tests/cli/blobby/blobby.rib: three blended leaves (two ellipsoids, a
# segment) with per-leaf colours, casting a shadow-mapped spot light's shadow
# (frame 1 renders the map with the blobby in it), a half-transparent blob
# and a teapot. It renders with no diagnostic, is baked, and previewed after light
# edits (the spot's intensity and colour, the point light's position) on the
# CPU and on the GPU: each against `relight render --set` with the same
# edits, mean error <= 0.1 % and maximum error <= 1 % of the 8-bit range,
# colour and alpha. Without an EGL context the GPU part skips the script
# (exit 77) once the rest has passed.
#
# Bad input: a malformed Blobby is an error at its FILE:LINE that drops it
# alone (the sphere beside it renders); a repelling plane is a warning, an
# error with --strict; Blobby inside MotionBegin is refused at its line.
source "$(dirname "$0")/lib.sh"

max_mean_pct=0.1
max_max_pct=1.0
cp "$source_dir/tests/cli/blobby/blobby.rib" "$work/"
edits=(--set 2.intensity=45 --set 2.lightcolor=1,0.85,0.7 --set 3.from=-3,4,-1)

run "render" bash -c "cd '$work' && '$relight' render -q -o ref.exr blobby.rib"
expect_status 0
expect_empty_stderr
# the blobby is in the image: without it, the frame is another; the teapot too
python3 - "$work/blobby.rib" "$work/none.rib" <<'PY'
import re, sys
out, skip = [], False
for line in open(sys.argv[1]):
	s = line.strip()
	if s.startswith("Blobby") or s.startswith("Geometry"):
		skip = True
	elif skip and re.match(r"[A-Z]", s):
		skip = False
	if not skip:
		out.append(line)
open(sys.argv[2], "w").write("".join(out))
PY
run "render without the blobby" bash -c "cd '$work' && '$relight' render -q -o none.exr none.rib && '$relight' diff --json ref.exr none.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["mean_pct"] > 2, d
' "$work/stdout" || fail "the blobby is not in the image: $(cat "$work/stdout")"
run "render --set" bash -c "cd '$work' && '$relight' render -q -o edited.exr ${edits[*]} blobby.rib"
expect_status 0
run "bake" bash -c "cd '$work' && '$relight' bake -q -o blobby.shot.exr blobby.rib"
expect_status 0
expect_no_crash

# against NAME.exr: the edited render within the limits, colour and alpha
against_render() {
	run "$1 vs render --set" "$relight" diff --json "$work/edited.exr" "$work/$1.exr"
	expect_status 0
	checks=$((checks + 1))
	python3 - "$work/stdout" "$1" "$max_mean_pct" "$max_max_pct" <<'PY' || fail "$1 differs from the edited render: $(cat "$work/stdout")"
import json, sys
d = json.load(open(sys.argv[1]))
mean, mx = float(sys.argv[3]), float(sys.argv[4])
a = d["alpha"]
print("%s vs render --set: mean %.4f %% max %.4f %%, alpha mean %.4f %% max %.4f %% (limits %g, %g)"
      % (sys.argv[2], d["mean_pct"], d["max_pct"], a["mean_pct"], a["max_pct"], mean, mx))
assert d["mean_pct"] <= mean and d["max_pct"] <= mx
assert a["mean_pct"] <= mean and a["max_pct"] <= mx
PY
}

run "preview --cpu" bash -c "cd '$work' && '$relight' preview -q --cpu ${edits[*]} -o cpu.exr blobby.shot.exr"
expect_status 0
expect_no_crash
against_render cpu

# ---- bad input ----
cat >"$work/bad.rib" <<'RIB'
Format 64 48 1
Display "bad.exr" "file" "rgba"
Projection "perspective" "fov" 40
WorldBegin
  Translate 0 0 5
  Sphere 1 -1 1 360
  Blobby 2 [1001 0 1001 99] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] [""]
  Blobby 1 [1001 0 0 2 0 5] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] [""]
  Blobby 1 [1001 0 1007] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] [""]
  Blobby 1 [1001 0] [0 0 0 0 0 0 0 0 0 0 0 0 0 0 0 1] [""]
  Blobby 1 [1001 0] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] [""] "vertex color Cs" [1 0]
WorldEnd
RIB
run "malformed Blobby" bash -c "cd '$work' && '$relight' render -o bad.exr bad.rib"
expect_status 1
expect_no_crash
expect_stderr "bad.rib:7: error: Blobby: code\[3\] = 99: float index out of range \(16 available\)"
expect_stderr "bad.rib:8: error: Blobby: code\[5\] = 5: operand \(an earlier instruction\) index out of range"
expect_stderr "bad.rib:9: error: Blobby: code\[2\] = 1007 is not a Blobby opcode"
expect_stderr "bad.rib:10: error: Blobby: the matrix at float 0 is singular"
expect_stderr "bad.rib:11: error: Blobby: primitive variable \"Cs\" \(vertex color\) needs 3 values, got 2"
expect_stderr "1 of 1 frame rendered"
expect_true "the rest of the frame rendered" test -s "$work/bad.exr"

cat >"$work/plane.rib" <<'RIB'
Format 64 48 1
Display "plane.exr" "file" "rgba"
Projection "perspective" "fov" 40
WorldBegin
  Translate 0 0 5
  Blobby 2 [1001 0 1003 0 16 0 2 0 1] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1 0.5 1 1 1] ["ground.z"]
WorldEnd
RIB
run "repelling plane" bash -c "cd '$work' && '$relight' render -o plane.exr plane.rib"
expect_status 0
expect_stderr "plane.rib:6: warning: Blobby: repelling planes \(opcode 1003\) are not supported"
run "repelling plane --strict" bash -c "cd '$work' && '$relight' render --strict -o plane.exr plane.rib"
expect_status 1
expect_stderr "plane.rib:6: error: Blobby: repelling planes"

cat >"$work/motion.rib" <<'RIB'
Format 64 48 1
Display "motion.exr" "file" "rgba"
Shutter 0 1
WorldBegin
  Translate 0 0 5
  MotionBegin [0 1]
    Blobby 1 [1001 0] [1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1] [""]
    Blobby 1 [1001 0] [1 0 0 0 0 1 0 0 0 0 1 0 0.5 0 0 1] [""]
  MotionEnd
WorldEnd
RIB
run "deforming Blobby" bash -c "cd '$work' && '$relight' render -o motion.exr motion.rib"
expect_no_crash
expect_stderr "motion.rib:7: error: Blobby cannot be inside the MotionBegin at line 6"

# ---- the GPU ----
run "EGL context" bash -c "cd '$work' && '$relight' preview -q ${edits[*]} -o gpu.exr blobby.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: the GPU part: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	[ "$failures" -eq 0 ] || { finish; exit 1; }
	exit 77
fi
expect_status 0
expect_no_crash
against_render gpu
finish
