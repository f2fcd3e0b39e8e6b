#!/usr/bin/env bash
# Curves and Points against closed forms (docs/renderer.md, "Curves and
# Points"). Every scene is 200x200 pixels at 8x8 samples through an
# orthographic camera over [-1, 1]^2, so a pixel is 1e-4 square units; the
# coverage of a frame is the sum of its alpha (an 8-bit PNG: rounding moves
# a sum by far less than the tolerance) in pixels, against the area the
# closed form gives. Tolerance: 1 % of the expected area (sampling noise at
# 8x8 and the diced ribbons' chords are well inside it; an alpha of 0.5 is
# stored as 128/255, 0.4 % over).
#
#   - a straight linear curve of width w and length l covers w l;
#   - a straight B-spline of 6 points (3 segments, vstep 1), a Bezier arc
#     (arc length integrated here) and a closed periodic B-spline (ditto)
#     cover width x length;
#   - a varying width tapers (trapezoid), also across two cubic segments;
#   - a ribbon facing "N" at 60 degrees from the view covers w l |cos 60|;
#   - n disjoint points of radius r cover n pi r^2;
#   - a half-opaque curve and points: alpha 0.5 over their area;
#   - motion blur: a moving point and a deforming curve keep their area, a
#     growing point covers its time-averaged area;
#   - one-sided curves and points, mirrored or reversed, are not culled;
#   - a periodic linear square loop of side s covers 4 s w - w^2;
#   - malformed Curves and Points: FILE:LINE errors, that primitive dropped,
#     the rest rendered (exit 1); --strict makes their warnings errors.
source "$(dirname "$0")/lib.sh"

tol_pct=1.0

header='Format 200 200 1
PixelSamples 8 8
Projection "orthographic"
ScreenWindow -1 1 -1 1
Shutter 0 1
Display "out.png" "file" "rgba"
WorldBegin
  Translate 0 0 5
  Surface "constant"'

# scene NAME BODY: NAME.rib, the header, BODY and WorldEnd.
scene() {
	printf '%s\n%s\nWorldEnd\n' "$header" "$2" >"$work/$1.rib"
}

# alpha_sum PNG: the sum of the alpha channel over the image, in pixels.
alpha_sum() {
	python3 - "$1" <<'PY'
import struct, sys, zlib
d = open(sys.argv[1], "rb").read()
assert d[:8] == b"\x89PNG\r\n\x1a\n"
pos, idat = 8, b""
while pos < len(d):
	n, = struct.unpack(">I", d[pos:pos + 4])
	kind, body = d[pos + 4:pos + 8], d[pos + 8:pos + 8 + n]
	if kind == b"IHDR":
		w, h, depth, ctype = struct.unpack(">IIBB", body[:10])
		nch = {0: 1, 4: 2, 2: 3, 6: 4}[ctype]
		assert depth == 8 and nch in (2, 4)
	elif kind == b"IDAT":
		idat += body
	pos += 12 + n
raw = zlib.decompress(idat)
row = w * nch + 1
total = 0
for y in range(h):
	r = raw[y * row:(y + 1) * row]
	assert r[0] == 0  # relight's rows are unfiltered
	total += sum(r[1 + nch - 1::nch])
print("%.3f" % (total / 255.0))
PY
}

# coverage NAME AREA: render NAME.rib, its alpha sum against AREA (square
# units; a python expression) within tol_pct.
coverage() {
	run "$1: render" bash -c "cd '$work' && '$relight' render -q -o $1.png $1.rib"
	expect_status 0
	expect_empty_stderr
	checks=$((checks + 1))
	local sum
	sum=$(alpha_sum "$work/$1.png") || { fail "cannot read $1.png"; return; }
	python3 - "$1" "$sum" "$2" "$tol_pct" <<'PY' || fail "coverage differs from the closed form"
import math, sys
name, got, want, tol = sys.argv[1], float(sys.argv[2]), eval(sys.argv[3], vars(math)) * 1e4, float(sys.argv[4])
err = 100.0 * (got - want) / want
print("%s: coverage %.2f pixels, closed form %.2f: %+.3f %% (tolerance %g %%)" % (name, got, want, err, tol))
assert abs(err) <= tol
PY
}

# arc LENGTH-OF: the length of a cubic curve by its basis, integrated.
# Arguments: basis name, vstep, "periodic" or not, then x y pairs.
arc() {
	python3 - "$@" <<'PY'
import math, sys
bases = {
	"bezier": [-1, 3, -3, 1, 3, -6, 3, 0, -3, 3, 0, 0, 1, 0, 0, 0],
	"b-spline": [x / 6 for x in [-1, 3, -3, 1, 3, -6, 3, 0, -3, 0, 3, 0, 1, 4, 1, 0]],
}
B, step, periodic = bases[sys.argv[1]], int(sys.argv[2]), sys.argv[3] == "periodic"
xy = list(map(float, sys.argv[4:]))
pts = [(xy[i], xy[i + 1]) for i in range(0, len(xy), 2)]
n = len(pts)
nseg = n // step if periodic else (n - 4) // step + 1
total = 0.0
for s in range(nseg):
	g = [pts[(s * step + k) % n] for k in range(4)]
	def at(t):
		T = [t ** 3, t * t, t, 1]
		w = [sum(T[r] * B[r * 4 + k] for r in range(4)) for k in range(4)]
		return (sum(w[k] * g[k][0] for k in range(4)), sum(w[k] * g[k][1] for k in range(4)))
	steps = 4000
	prev = at(0.0)
	for i in range(1, steps + 1):
		p = at(i / steps)
		total += math.hypot(p[0] - prev[0], p[1] - prev[1])
		prev = p
print("%.9g" % total)
PY
}

# ---- straight ribbons ----
scene linear '  Curves "linear" [2] "nonperiodic" "P" [-0.6 -0.3 0  0.6 0.3 0] "constantwidth" [0.1]'
coverage linear "0.1 * hypot(1.2, 0.6)"

# six points 0.3 apart on a line through a b-spline: segments from the 2nd to the 5th point
scene bspline '  Basis "b-spline" 1 "b-spline" 1
  Curves "cubic" [6] "nonperiodic" "P" [-0.75 0 0  -0.45 0 0  -0.15 0 0  0.15 0 0  0.45 0 0  0.75 0 0] "constantwidth" [0.08]'
coverage bspline "0.08 * 0.9"

# ---- a curved Bezier arc and a closed b-spline ----
bez="-0.7 -0.6  -0.3 0.8  0.3 0.8  0.7 -0.6"
len_bez=$(arc bezier 3 nonperiodic $bez)
scene bezier "  Basis \"bezier\" 3 \"bezier\" 3
  Curves \"cubic\" [4] \"nonperiodic\" \"P\" [$(echo $bez | awk '{for (i = 1; i <= NF; i += 2) printf "%s %s 0  ", $i, $(i + 1)}')] \"constantwidth\" [0.05]"
coverage bezier "0.05 * $len_bez"

loop="-0.6 -0.6  0.6 -0.6  0.6 0.6  -0.6 0.6"
len_loop=$(arc b-spline 1 periodic $loop)
scene bloop "  Basis \"b-spline\" 1 \"b-spline\" 1
  Curves \"cubic\" [4] \"periodic\" \"P\" [$(echo $loop | awk '{for (i = 1; i <= NF; i += 2) printf "%s %s 0  ", $i, $(i + 1)}')] \"constantwidth\" [0.04]"
coverage bloop "0.04 * $len_loop"

# ---- widths ----
scene taper '  Curves "linear" [2] "nonperiodic" "P" [-0.6 0 0  0.6 0 0] "width" [0.2 0.05]'
coverage taper "1.2 * (0.2 + 0.05) / 2"

# two b-spline segments of 0.5 each (a straight line, points 0.5 apart): widths 0.2 0.1 0.0
scene taper_cubic '  Basis "b-spline" 1 "b-spline" 1
  Curves "cubic" [5] "nonperiodic" "P" [-1 0 0  -0.5 0 0  0 0 0  0.5 0 0  1 0 0] "width" [0.2 0.1 0]'
coverage taper_cubic "0.5 * (0.2 + 0.1) / 2 + 0.5 * 0.1 / 2"

# ---- a ribbon facing N, 60 degrees from the view direction ----
scene oriented '  Curves "linear" [2] "nonperiodic" "P" [-0.6 0 0  0.6 0 0] "constantwidth" [0.2] "N" [0 0.8660254 -0.5  0 0.8660254 -0.5]'
coverage oriented "0.2 * 1.2 * cos(radians(60))"

# ---- points ----
scene points '  Points "P" [-0.5 -0.5 0  0.5 -0.5 0  0 0 0  -0.5 0.5 0  0.5 0.5 0] "width" [0.3 0.3 0.3 0.2 0.2]
  Points "P" [0 0.75 0  0 -0.75 0  0.75 0 0] "constantwidth" [0.04]'
coverage points "pi * (3 * 0.15 ** 2 + 2 * 0.1 ** 2 + 3 * 0.02 ** 2)"

# ---- transparency ----
scene half '  Opacity [0.5 0.5 0.5]
  Curves "linear" [2] "nonperiodic" "P" [-0.6 0.5 0  0.6 0.5 0] "constantwidth" [0.2]
  Points "P" [-0.4 -0.4 0  0.4 -0.4 0] "constantwidth" [0.4]'
coverage half "0.5 * (0.2 * 1.2 + 2 * pi * 0.2 ** 2)"

# ---- motion blur ----
scene moving '  MotionBegin [0 1]
    Points "P" [-0.5 0.4 0] "constantwidth" [0.4]
    Points "P" [0.1 0.4 0] "constantwidth" [0.4]
  MotionEnd
  MotionBegin [0 1]
    Curves "linear" [2] "nonperiodic" "P" [-0.6 -0.6 0  0.6 -0.6 0] "constantwidth" [0.1]
    Curves "linear" [2] "nonperiodic" "P" [-0.6 -0.2 0  0.6 -0.2 0] "constantwidth" [0.1]
  MotionEnd'
coverage moving "pi * 0.2 ** 2 + 0.1 * 1.2"
# a point growing from radius 0.1 to 0.3 over the shutter: pi (r0^2 + r0 r1 + r1^2) / 3
scene growing '  MotionBegin [0 1]
    Points "P" [0 0 0] "constantwidth" [0.2]
    Points "P" [0 0 0] "constantwidth" [0.6]
  MotionEnd'
coverage growing "pi * (0.1 ** 2 + 0.1 * 0.3 + 0.3 ** 2) / 3"
# the streak is wider than the point: it really moved
checks=$((checks + 1))
python3 - "$work/moving.png" <<'PY' || fail "the moving point left no streak"
import struct, sys, zlib
d = open(sys.argv[1], "rb").read()
pos, idat = 8, b""
while pos < len(d):
	n, = struct.unpack(">I", d[pos:pos + 4])
	if d[pos + 4:pos + 8] == b"IDAT":
		idat += d[pos + 8:pos + 8 + n]
	pos += 12 + n
raw = zlib.decompress(idat)
row = raw[60 * 801:61 * 801]   # y = 0.4 in pixel row 60 of 200 (RGBA)
lit = [x for x in range(200) if row[1 + 4 * x + 3] > 0]
print("moving point: row 60 covered from pixel %d to %d" % (lit[0], lit[-1]))
assert lit[-1] - lit[0] > 90  # 0.6 of travel plus 0.4 of disk: 100 pixels
PY

# ---- one-sided, mirrored, reversed: a ribbon or disk faces the camera, never culled ----
scene onesided '  Sides 1
  AttributeBegin
    ReverseOrientation
    Curves "linear" [2] "nonperiodic" "P" [-0.6 0.5 0  0.6 0.5 0] "constantwidth" [0.1]
  AttributeEnd
  AttributeBegin
    Scale -1 1 1
    Curves "linear" [2] "nonperiodic" "P" [-0.6 0 0  0.6 0 0] "constantwidth" [0.1]
    Points "P" [0.5 -0.5 0] "constantwidth" [0.2]
    ReverseOrientation
    Points "P" [-0.5 -0.5 0] "constantwidth" [0.2]
  AttributeEnd'
coverage onesided "2 * 0.1 * 1.2 + 2 * pi * 0.1 ** 2"

# ---- periodic wrap ----
scene square '  Curves "linear" [4] "periodic" "P" [-0.3 -0.3 0  0.3 -0.3 0  0.3 0.3 0  -0.3 0.3 0] "constantwidth" [0.1]'
coverage square "4 * 0.6 * 0.1 - 0.1 ** 2"

# ---- malformed input: that primitive is dropped, the rest renders ----
good='  Curves "linear" [2] "nonperiodic" "P" [-0.6 0 0  0.6 0 0] "constantwidth" [0.1]'
bad_case() {
	local name=$1 body=$2 line=$3 msg=$4
	scene "$name" "$good
$body"
	run "$name" bash -c "cd '$work' && '$relight' render -q -o $name.png $name.rib"
	expect_no_crash
	expect_status 1
	expect_stderr "^$name.rib:$line: error: $msg"
	checks=$((checks + 1))
	local sum
	sum=$(alpha_sum "$work/$name.png") || { fail "no image"; return; }
	python3 -c "import sys; s = float(sys.argv[1]); assert abs(s - 1200) <= 12, s" "$sum" ||
		fail "the rest of the frame did not render as without the bad primitive ($sum)"
}
bad_case bad_count '  Curves "linear" [2 2] "nonperiodic" "P" [0 0 0  1 1 0  0 1 0]' 11 \
	'Curves: nvertices add up to 4, but "P" has 3 points'
bad_case bad_cubic '  Basis "bezier" 3 "bezier" 3
  Curves "cubic" [5] "nonperiodic" "P" [0 0 0  1 0 0  1 1 0  0 1 0  0 0 0]' 12 \
	'Curves: curve 0 has 5 vertices, too few or not whole cubic segments \(nonperiodic, vstep 3\)'
bad_case bad_width '  Curves "linear" [2] "nonperiodic" "P" [0 0 0  1 1 0] "width" [0.1 -0.2]' 11 \
	'Curves: "width" 1 is -0.2 \(a width is 0 or more\)'
bad_case bad_points '  Points "P" [0 0 0  0.5 0.5 0] "width" [0.1]' 11 \
	'Points: primitive variable "width" \(varying float\) needs 2 values, got 1'
bad_case bad_nvertices '  Curves "linear" [2 0] "nonperiodic" "P" [0 0 0  1 1 0]' 11 \
	'Curves: nvertices 1 is 0'
bad_case bad_wrap '  Curves "linear" [2] "closed" "P" [0 0 0  1 1 0]' 11 \
	'Curves wrap mode must be "periodic" or "nonperiodic"'

# a warning (an untyped primitive variable) renders; --strict makes it an error
scene warned "$good
  Points \"P\" [0.5 0.5 0] \"constantwidth\" [0.1] \"fuzz\" [1]"
run "warning" bash -c "cd '$work' && '$relight' render -q -o warned.png warned.rib"
expect_status 0
expect_stderr "^warned.rib:11: warning: Points: primitive variable 'fuzz' has no type"
# disks facing N are not supported: a warning, the disk faces the camera
scene pointsN '  Points "P" [0 0 0] "constantwidth" [0.4] "N" [1 0 0]'
run "Points N" bash -c "cd '$work' && '$relight' render -q -o pointsN.png pointsN.rib"
expect_status 0
expect_stderr '^pointsN.rib:10: warning: Points: "N" \(disks facing N\) is not supported: the disks face the camera'
run "--strict" bash -c "cd '$work' && '$relight' render -q --strict -o warned.png warned.rib"
expect_no_crash
expect_status 1
expect_stderr "^warned.rib:11: error: Points: primitive variable 'fuzz' has no type"

finish
