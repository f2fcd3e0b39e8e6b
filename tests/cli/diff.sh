#!/usr/bin/env bash
# `relight diff`: its help and usage errors; identical renders give zero
# error; two flat images with known linear values give the error computed by
# hand from the sRGB formula; a changed light gives a plausible error; the
# heat map is a PNG of the right size and colour; non-finite values, size
# and channel mismatches and unreadable files are reported, never a crash.
source "$(dirname "$0")/lib.sh"

# json_get FILE KEY...: print a value of the JSON object in FILE (nested keys
# and list indices), "null" for null.
json_get() {
	python3 - "$@" <<'PY'
import json, sys
v = json.load(open(sys.argv[1]))
for k in sys.argv[2:]:
    v = v[int(k)] if isinstance(v, list) else v[k]
print("null" if v is None else v)
PY
}

# near A B TOL: |A - B| <= TOL.
near() {
	python3 -c 'import sys; a, b, t = map(float, sys.argv[1:]); sys.exit(abs(a - b) > t)' "$@"
}

# expect_json KEY... -- VALUE TOL: the key of stdout's JSON is VALUE within TOL
# (TOL "=" compares as strings).
expect_json() {
	local keys=()
	while [ "$1" != "--" ]; do
		keys+=("$1")
		shift
	done
	local want=$2 tol=$3 got
	checks=$((checks + 1))
	got=$(json_get "$work/stdout" "${keys[@]}" 2>/dev/null) || {
		fail "stdout is not JSON with key ${keys[*]}"
		return
	}
	if [ "$tol" = "=" ]; then
		[ "$got" = "$want" ] || fail "${keys[*]} is '$got', expected '$want'"
	else
		near "$got" "$want" "$tol" || fail "${keys[*]} is $got, expected $want within $tol"
	fi
}

# expect_strict_json: stdout is JSON without NaN, Infinity or -Infinity.
expect_strict_json() {
	checks=$((checks + 1))
	python3 -c '
import json, sys
def bad(c):
    raise ValueError(c)
json.load(open(sys.argv[1]), parse_constant=bad)' "$work/stdout" 2>/dev/null ||
		fail "stdout is not strict JSON (NaN or Infinity?)"
}

# write_exr FILE W H CHANNELS VALUES: an uncompressed float scanline OpenEXR,
# written here from the file format, independently of relight. CHANNELS is a
# comma-separated list ("R,G,B,A"); VALUES a Python expression for the value
# of channel c at pixel (x, y), e.g. "0.5" or "float('nan') if x == 1 else 0".
write_exr() {
	python3 - "$@" <<'PY'
import struct, sys
path, w, h, chans, expr = sys.argv[1], int(sys.argv[2]), int(sys.argv[3]), sys.argv[4].split(','), sys.argv[5]
chans = sorted(chans)
def attr(name, typ, data):
    return name.encode() + b'\0' + typ.encode() + b'\0' + struct.pack('<i', len(data)) + data
chlist = b''.join(c.encode() + b'\0' + struct.pack('<iB3xii', 2, 0, 1, 1) for c in chans) + b'\0'
box = struct.pack('<4i', 0, 0, w - 1, h - 1)
head = b'\x76\x2f\x31\x01' + struct.pack('<i', 2)
head += attr('channels', 'chlist', chlist) + attr('compression', 'compression', b'\0')
head += attr('dataWindow', 'box2i', box) + attr('displayWindow', 'box2i', box)
head += attr('lineOrder', 'lineOrder', b'\0') + attr('pixelAspectRatio', 'float', struct.pack('<f', 1))
head += attr('screenWindowCenter', 'v2f', struct.pack('<2f', 0, 0))
head += attr('screenWindowWidth', 'float', struct.pack('<f', 1)) + b'\0'
lines = []
for y in range(h):
    data = b''
    for c in chans:
        data += b''.join(struct.pack('<f', float(eval(expr, {'x': x, 'y': y, 'c': c}))) for x in range(w))
    lines.append(struct.pack('<ii', y, len(data)) + data)
offset = len(head) + 8 * h
table = b''
for l in lines:
    table += struct.pack('<Q', offset)
    offset += len(l)
open(path, 'wb').write(head + table + b''.join(lines))
PY
}

# png_info FILE: "W H COLOURTYPE R,G,B-of-pixel-(0,0)" from the PNG's IHDR and
# its inflated first row (filter type 0), or a message and status 1.
png_info() {
	python3 - "$1" <<'PY'
import struct, sys, zlib
b = open(sys.argv[1], 'rb').read()
if b[:8] != b'\x89PNG\r\n\x1a\n':
    sys.exit('no PNG signature')
pos, idat, ihdr = 8, b'', None
while pos < len(b):
    n, t = struct.unpack('>I4s', b[pos:pos + 8])
    d = b[pos + 8:pos + 8 + n]
    if zlib.crc32(t + d) != struct.unpack('>I', b[pos + 8 + n:pos + 12 + n])[0]:
        sys.exit('bad CRC')
    if t == b'IHDR':
        ihdr = struct.unpack('>IIBBBBB', d)
    elif t == b'IDAT':
        idat += d
    pos += 12 + n
w, h, depth, ctype = ihdr[:4]
raw = zlib.decompress(idat)
if len(raw) != h * (1 + 3 * w) or raw[0] != 0:
    sys.exit('bad image data')
print(w, h, ctype, ','.join(str(v) for v in raw[1:4]))
PY
}

run "help" "$relight" diff --help
expect_status 0
expect_stdout "^usage: relight diff \[OPTIONS\] A.exr B.exr"
for opt in '--json' '--heatmap OUT.png' '--scale S' '--fail-above PCT' '-h, --help' \
	'not rounded to 8 bits' 'Exit status'; do
	expect_stdout "$opt"
done
expect_empty_stderr

run "listed in relight --help" "$relight" --help
expect_stdout "diff +Compare two rendered images"

run "relight help diff" "$relight" help diff
expect_status 0
expect_stdout "^usage: relight diff "

# Usage errors: exit 2.
run "no images" "$relight" diff
expect_status 2
expect_stderr "no images to compare"
run "one image" "$relight" diff a.exr
expect_status 2
expect_stderr "two images expected"
run "three images" "$relight" diff a.exr b.exr c.exr
expect_status 2
expect_stderr "extra argument 'c.exr'"
run "unknown option" "$relight" diff --frobnicate a.exr b.exr
expect_status 2
expect_stderr "unknown option '--frobnicate'"
run "missing argument" "$relight" diff a.exr b.exr --scale
expect_status 2
expect_stderr "option '--scale' needs an argument"
for bad in 0 -1 abc 101 nan inf 5x; do
	run "bad scale $bad" "$relight" diff --scale "$bad" a.exr b.exr
	expect_status 2
	expect_stderr "--scale needs a percentage"
done
run "bad fail-above" "$relight" diff --fail-above -0.5 a.exr b.exr
expect_status 2
expect_stderr "--fail-above needs a percentage"

# Unreadable input: exit 1, the file named.
run "missing file" "$relight" diff "$work/none.exr" "$work/none2.exr"
expect_no_crash
expect_status 1
expect_stderr "none.exr: error: cannot read"
printf 'not an image\n' >"$work/text.exr"
run "not an EXR" "$relight" diff "$work/text.exr" "$work/text.exr"
expect_no_crash
expect_status 1
expect_stderr "text.exr: error: cannot read"

# Two flat renders: every pixel exactly 0.25 and 0.5 (both exact in half).
flat_rib() {
	cat <<RIB
Format 16 12 1
PixelSamples 2 2
Display "$2" "file" "rgba"
Projection "orthographic"
WorldBegin
  Surface "constant"
  Color [$1 $1 $1]
  Translate 0 0 5
  Polygon "P" [-10 -10 0  10 -10 0  10 10 0  -10 10 0]
WorldEnd
RIB
}
flat_rib 0.25 flat_a.exr >"$work/flat_a.rib"
flat_rib 0.5 flat_b.exr >"$work/flat_b.rib"
run "render flat scenes" bash -c "cd '$work' && '$relight' render -q flat_a.rib && \
	'$relight' render -q flat_b.rib && cp flat_a.exr flat_a2.exr && '$relight' render -q -o flat_a2.exr flat_a.rib"
expect_status 0

run "identical: text" "$relight" diff "$work/flat_a.exr" "$work/flat_a2.exr"
expect_no_crash
expect_status 0
expect_stdout "16x12, channels R G B$"
expect_stdout "RMSE \(linear\) +0$"
expect_stdout "max error +0.0000 %"
expect_stdout "PSNR \(sRGB\) +identical"
expect_stdout "pixels over 1% +0 of 192"

run "identical: JSON" "$relight" diff --json "$work/flat_a.exr" "$work/flat_a2.exr"
expect_status 0
expect_json rmse -- 0 0
expect_json mean_pct -- 0 0
expect_json max_pct -- 0 0
expect_json psnr_db -- null =
expect_json over_1pct -- 0 =
expect_json width -- 16 =
expect_json height -- 12 =
expect_json channels 2 -- B =
expect_json alpha max_pct -- 0 0
expect_strict_json

# By hand: srgb(0.25) = 1.055 * 0.25^(1/2.4) - 0.055 = 0.5370987,
# srgb(0.5) = 0.7353570; 100 * |difference| = 19.825825 % in every sample;
# PSNR = -20 log10(0.19825825) = 14.055374 dB; linear RMSE 0.25.
run "flat: JSON" "$relight" diff --json --heatmap "$work/heat.png" --scale 100 \
	"$work/flat_a.exr" "$work/flat_b.exr"
expect_no_crash
expect_status 0
expect_json mean_pct -- 19.825825 1e-3
expect_json max_pct -- 19.825825 1e-3
expect_json rmse -- 0.25 1e-6
expect_json psnr_db -- 14.055374 1e-3
expect_json over_1pct -- 192 =
expect_json max_at 0 -- 0 =
expect_json max_at 1 -- 0 =
expect_json alpha mean_pct -- 0 0
expect_json scale_pct -- 100 0
expect_json heatmap -- "$work/heat.png" =

# The heat map: 16x12 RGB; 19.83 % on a 100 % scale is t = 0.9913 of the
# first fifth of the ramp (black -> blue): (0, 0, round(0.9913 * 255) = 253).
checks=$((checks + 1))
info=$(png_info "$work/heat.png" 2>&1) || fail "heat map: $info"
[ "$info" = "16 12 2 0,0,253" ] || fail "heat map is '$info', expected '16 12 2 0,0,253'"

run "flat: text with heat map" "$relight" diff --heatmap "$work/heat5.png" \
	"$work/flat_a.exr" "$work/flat_b.exr"
expect_status 0
expect_stdout "mean error +19.825[89] % of the 8-bit range"
expect_stdout "PSNR \(sRGB\) +14.06 dB"
expect_stdout "heat map +.*heat5.png \(black 0, .*white 5 % and above\)"
checks=$((checks + 1))
info=$(png_info "$work/heat5.png" 2>&1) || fail "heat map: $info"
[ "$info" = "16 12 2 255,255,255" ] || fail "heat map is '$info', expected white"

run "--fail-above, below" "$relight" diff --fail-above 20 "$work/flat_a.exr" "$work/flat_b.exr"
expect_status 0
run "--fail-above, above" "$relight" diff --fail-above 19.8 "$work/flat_a.exr" "$work/flat_b.exr"
expect_status 1
expect_stdout "max error +19.82"
expect_stderr "above --fail-above 19.8 %"

run "heat map cannot be written" "$relight" diff --heatmap "$work/no/such/dir.png" \
	"$work/flat_a.exr" "$work/flat_b.exr"
expect_status 1
expect_stderr "dir.png: error: cannot write"

# A lit sphere, then the same with the light 1.5 times as bright.
sphere_rib() {
	cat <<RIB
Format 32 24 1
PixelSamples 2 2
Display "$2" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1 "intensity" $1
  Surface "matte"
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
RIB
}
sphere_rib 1 lit1.exr >"$work/lit1.rib"
sphere_rib 1.5 lit2.exr >"$work/lit2.rib"
run "render lit spheres" bash -c "cd '$work' && '$relight' render -q lit1.rib && \
	'$relight' render -q lit2.rib"
expect_status 0
run "changed light" "$relight" diff --json "$work/lit1.exr" "$work/lit2.exr"
expect_no_crash
expect_status 0
# The background (most of the frame) is black in both; on the sphere the
# brighter light adds up to a third of the range.
checks=$((checks + 1))
python3 - "$work/stdout" <<'PY' || fail "implausible errors: $(cat "$work/stdout")"
import json, sys
d = json.load(open(sys.argv[1]))
ok = (0 < d['rmse'] < 0.5 and 0 < d['mean_pct'] < d['max_pct'] <= 40
      and 5 <= d['max_pct'] and d['psnr_db'] is not None and 5 < d['psnr_db'] < 60
      and 0 < d['over_1pct'] < d['pixels'] and d['alpha']['max_pct'] == 0)
sys.exit(not ok)
PY

# Non-finite values: each an error of the whole range, counted.
write_exr "$work/nan.exr" 4 2 R,G,B "float('nan') if (x, y, c) == (1, 0, 'G') else (float('inf') if (x, y, c) == (3, 1, 'R') else 0.25)"
write_exr "$work/quarter.exr" 4 2 R,G,B "0.25"
run "non-finite" "$relight" diff --json "$work/nan.exr" "$work/quarter.exr"
expect_no_crash
expect_status 0
expect_json nonfinite 0 -- 2 =
expect_json nonfinite 1 -- 0 =
expect_json max_pct -- 100 0
expect_json max_at 0 -- 1 =
expect_json max_at 1 -- 0 =
expect_json over_1pct -- 2 =
# 2 of 24 samples at 100 %: mean 8.3333 %; linear RMSE sqrt(2/24).
expect_json mean_pct -- 8.333333 1e-4
expect_json rmse -- 0.288675 1e-5
expect_json alpha -- null =
expect_strict_json
run "non-finite: text" "$relight" diff "$work/nan.exr" "$work/quarter.exr"
expect_status 0
expect_stdout "non-finite values +2 in .*nan.exr, 0 in .*quarter.exr"

# A hand-computable case through the small-value branch: 0.001 vs 0.002 is
# 12.92 * 0.001 = 1.292 % everywhere.
write_exr "$work/small1.exr" 3 3 R,G,B,A "0.001 if c != 'A' else 1"
write_exr "$work/small2.exr" 3 3 R,G,B,A "0.002 if c != 'A' else (0.5 if x == 2 else 1)"
run "small values" "$relight" diff --json "$work/small1.exr" "$work/small2.exr"
expect_status 0
expect_json mean_pct -- 1.292 1e-4
expect_json alpha max_pct -- 50 1e-4
expect_json alpha max_at 0 -- 2 =
expect_json alpha over_1pct -- 3 =

# Mismatches: exit 1 with a clear message.
write_exr "$work/small.exr" 8 6 R,G,B,A "0.25"
run "size mismatch" "$relight" diff "$work/flat_a.exr" "$work/small.exr"
expect_no_crash
expect_status 1
expect_stderr "differ in size: .*flat_a.exr is 16x12, .*small.exr is 8x6"
expect_empty_stdout
write_exr "$work/depth.exr" 16 12 Z "1"
run "no colour channels" "$relight" diff "$work/flat_a.exr" "$work/depth.exr"
expect_status 1
expect_stderr "no colour channels|different colour channels"
expect_stderr "depth.exr has Z"
write_exr "$work/red.exr" 16 12 R,A "0.25"
run "different colour channels" "$relight" diff "$work/flat_a.exr" "$work/red.exr"
expect_status 1
expect_stderr "different colour channels"
write_exr "$work/rgb.exr" 16 12 R,G,B "0.25"
run "alpha in one only" "$relight" diff "$work/flat_a.exr" "$work/rgb.exr"
expect_status 0
expect_stdout "alpha +only in .*flat_a.exr, not compared"

finish
