#!/usr/bin/env bash
# Imager shaders (RIB Imager) through the bake and both previews
# (tests/cli/imager/imager.rib: a sphere over nothing, composited over a
# background colour by shaders/background.sl):
#
#   - the GPU preview after an imager parameter edit (--set imager.bgcolor=...)
#     against `relight render` of the RIB edited the same way: mean error
#     <= 0.1 % and maximum error <= 1 % of the 8-bit range (after sRGB), and
#     against the CPU preview (--cpu) with the same edit: largest relative
#     difference <= 1e-4; the coarse levels against the CPU's too;
#   - the imager matters: the preview is far from a render without it;
#   - an imager edit runs the imager pass alone (the graph's resolve nodes do
#     not run again);
#   - refused edits of the imager (unknown parameter, not finite, wrong count).
# Without an EGL context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0
dir="$work/imager"
cp -R "$source_dir/tests/cli/imager" "$dir"

run "bake" bash -c "cd '$dir' && '$relight' bake -q imager.rib"
expect_status 0
run "info" "$relight" info "$dir/imager.shot.exr"
expect_status 0
expect_stdout "^imager: background \(edited as 'imager'\)"
run "EGL context" bash -c "cd '$dir' && '$relight' preview -q -o probe.exr imager.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi

# edit_rib OUT BGCOLOR [INTENSITY]: imager.rib with the imager's bgcolor (and
# light 1's intensity) replaced; BGCOLOR "none" drops the Imager request.
edit_rib() {
	python3 - "$dir/imager.rib" "$@" <<'PY'
import re, sys
src, dst, bg = sys.argv[1], sys.argv[2], sys.argv[3]
text = open(src).read()
if bg == "none":
	text = re.sub(r'\nImager [^\n]*', "", text)
else:
	text = re.sub(r'("color bgcolor" )\[[^\]]*\]', r'\1[%s]' % bg.replace(",", " "), text)
if len(sys.argv) > 4:
	text = re.sub(r'("intensity" )\[20\]', r'\1[%s]' % sys.argv[4], text)
open(dst, "w").write(text)
PY
}

# imager_case NAME BGCOLOR INTENSITY SET...: the GPU preview with the --set
# edits against the CPU preview and the render of the edited RIB.
imager_case() {
	local name=$1 bg=$2 inten=$3
	shift 3
	local sets=() e
	for e in "$@"; do sets+=(--set "$e"); done
	checks=$((checks + 1))
	what=$name
	run "$name: gpu" bash -c "cd '$dir' && '$relight' preview -q --json ${sets[*]} -o gpu.exr imager.shot.exr"
	[ "$status" -eq 0 ] || { fail "GPU preview failed (status $status)"; return; }
	cp "$work/stdout" "$dir/gpu.json"
	run "$name: cpu" bash -c "cd '$dir' && '$relight' preview -q --cpu ${sets[*]} -o cpu.exr imager.shot.exr"
	[ "$status" -eq 0 ] || { fail "CPU preview failed (status $status)"; return; }
	run "$name: gpu vs cpu" "$relight" diff --json "$dir/cpu.exr" "$dir/gpu.exr"
	cp "$work/stdout" "$dir/vs_cpu.json"
	edit_rib "$dir/edited.rib" "$bg" "$inten"
	run "$name: render" bash -c "cd '$dir' && '$relight' render -q -o edited.exr edited.rib"
	[ "$status" -eq 0 ] || { fail "render of the edited RIB failed (status $status)"; return; }
	run "$name: gpu vs render" "$relight" diff --json "$dir/edited.exr" "$dir/gpu.exr"
	cp "$work/stdout" "$dir/vs_render.json"
	edit_rib "$dir/plain.rib" none "$inten"
	run "$name: render without the imager" bash -c "cd '$dir' && '$relight' render -q -o plain.exr plain.rib"
	run "$name: gpu vs plain render" "$relight" diff --json "$dir/plain.exr" "$dir/gpu.exr"
	cp "$work/stdout" "$dir/vs_plain.json"
	: >"$work/stderr"
	python3 - "$dir" "$max_rel" "$max_mean_pct" "$max_max_pct" "$name" >"$work/verdict" <<'PY'
import json, sys
d, max_rel, max_mean, max_max, name = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
g = json.load(open(d + "/gpu.json"))
c = json.load(open(d + "/vs_cpu.json"))
r = json.load(open(d + "/vs_render.json"))
p = json.load(open(d + "/vs_plain.json"))
why = []
if not (c["max_rel"] <= max_rel):
	why.append("GPU vs CPU: max relative %.3g > %g at %s" % (c["max_rel"], max_rel, c["max_at"]))
if not (r["mean_pct"] <= max_mean and r["max_pct"] <= max_max):
	why.append("GPU vs edited render: mean %.4f %% max %.4f %% at %s (limits %g, %g)"
		   % (r["mean_pct"], r["max_pct"], r["max_at"], max_mean, max_max))
# the background covers most of the frame: without the imager it is black
if not (p["mean_pct"] > 10):
	why.append("GPU vs a render without the imager: mean %.4f %%, the imager did nothing" % p["mean_pct"])
nodes = {n["name"]: n for n in g["graph"]}
if "imager:level3" not in nodes:
	why.append("the graph has no imager node")
lv = g.get("levels", [])
print("%s: vs cpu max_rel %.2g; vs render mean %.4f %% max %.4f %%; without imager mean %.1f %%; edit levels %s ms"
      % (name, c["max_rel"], r["mean_pct"], r["max_pct"], p["mean_pct"], [l["ms"] for l in lv]))
for w in why:
	print("FAIL: " + w)
PY
	cat "$work/verdict"
	if grep -q '^FAIL' "$work/verdict"; then
		fail "$(grep '^FAIL' "$work/verdict" | tr '\n' ' ')"
	fi
}

imager_case "baked imager" 0.25,0.5,0.75 20
imager_case "imager edit" 0.6,0.3,0.1 20 imager.bgcolor=0.6,0.3,0.1
imager_case "imager and light edits" 0.1,0.8,0.2 35 imager.bgcolor=0.1,0.8,0.2 1.intensity=35

# relight render --set imager.PARAM edits the Imager as the previews do: the
# same image as the RIB edited, bit for bit; an unknown parameter is an error.
edit_rib "$dir/set.rib" 0.6,0.3,0.1
run "render --set imager" bash -c "cd '$dir' && '$relight' render -q --set imager.bgcolor=0.6,0.3,0.1 -o set1.exr imager.rib && '$relight' render -q -o set2.exr set.rib && '$relight' diff --fail-rel 0 set1.exr set2.exr"
expect_status 0
run "render --set imager.nope" bash -c "cd '$dir' && '$relight' render -q --set imager.nope=1 -o set3.exr imager.rib"
expect_status 1
expect_stderr "imager.rib:9: error: --set imager.nope: shader 'background' has no parameter 'nope'"

# An imager edit runs the imager pass alone: after the full frame (one
# resolve a level) the edit's refinement resolves levels 0-2 once (they were
# never asked for) and level 3 not again, while the imager runs there twice.
run "imager edit graph" bash -c "cd '$dir' && '$relight' preview -q --json --set imager.bgcolor=1,0,0 -o g.exr imager.shot.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
j = json.load(open(sys.argv[1]))
runs = {n["name"]: n["runs"] for n in j["graph"]}
assert runs["resolve:level3"] == 1 and runs["imager:level3"] == 2, runs
assert all(l["shaded"] == 0 for l in j["levels"]), j["levels"]
' "$work/stdout" || fail "an imager edit did more than the imager pass"

# Every level: coarse levels match the CPU resolver's coarse levels.
for level in 0 1 2; do
	run "level $level" bash -c "cd '$dir' && '$relight' preview -q --level $level --set imager.bgcolor=0.3,0.3,0.9 -o l$level.gpu.exr imager.shot.exr && '$relight' preview -q --cpu --level $level --set imager.bgcolor=0.3,0.3,0.9 -o l$level.cpu.exr imager.shot.exr && '$relight' diff --fail-rel $max_rel l$level.cpu.exr l$level.gpu.exr"
	expect_status 0
done

# Refused imager edits: a clear error, exit status 1, no image, on both paths.
for cpu in "" --cpu; do
	for bad in imager.nope=1 imager.bgcolor=nan imager.bgcolor=1,2; do
		run "refuse $bad $cpu" bash -c "cd '$dir' && rm -f bad.exr && '$relight' preview -q $cpu --set $bad -o bad.exr imager.shot.exr"
		expect_status 1
		expect_stderr "relight: error: .*imager 'background'"
		checks=$((checks + 1))
		[ ! -e "$dir/bad.exr" ] || fail "an image was written for a refused edit"
	done
done

# An imager the GPU cannot run (it asks the renderer an option): the bake
# says so at its Imager request (an error under --strict), the CPU preview runs
# it, the GPU preview refuses the shot naming the shader's line.
mkdir -p "$work/nogpu"
cat >"$work/nogpu/asks.sl" <<'SL'
imager asks()
{
	float f[3] = { 0, 0, 0 };
	option("Format", f);
	Ci += (1 - alpha) * color(f[0] / 100, 0, 0);
	alpha = 1;
}
SL
sed 's|^Imager .*|Option "searchpath" "shader" [".:\&"]\nImager "asks"|' "$dir/imager.rib" >"$work/nogpu/nogpu.rib"
run "no GPU imager: bake" bash -c "cd '$work/nogpu' && '$relight' bake nogpu.rib"
expect_status 0
expect_stderr "^nogpu.rib:10: warning: the imager 'asks' cannot run in the GPU preview"
expect_stderr "asks.sl:4:2: error: option\(\) is not supported on the GPU"
run "no GPU imager: bake --strict" bash -c "cd '$work/nogpu' && '$relight' bake --strict -o strict.shot.exr nogpu.rib"
expect_status 1
run "no GPU imager: --cpu" bash -c "cd '$work/nogpu' && '$relight' preview -q --cpu -o c.exr nogpu.shot.exr"
expect_status 0
run "no GPU imager: gpu" bash -c "cd '$work/nogpu' && '$relight' preview -q -o g.exr nogpu.shot.exr"
expect_status 1
expect_stderr "the imager 'asks' cannot run on the GPU"

# A light named like the imager: edits by that name are refused, on both paths.
mkdir -p "$work/clash"
sed 's/LightSource "pointlight" 1/LightSource "pointlight" "imager"/' "$dir/imager.rib" \
	>"$work/clash/clash.rib"
run "clash: bake" bash -c "cd '$work/clash' && '$relight' bake -q clash.rib"
expect_status 0
for cpu in "" --cpu; do
	run "clash $cpu" bash -c "cd '$work/clash' && '$relight' preview -q $cpu --set imager.intensity=3 -o c.exr clash.shot.exr"
	expect_status 1
	expect_stderr "a light is named 'imager' like the shot's imager"
done

# relightd: the opened reply lists the imager (valid against the protocol's
# reply schema), a set edit of "imager" over the protocol gives what `relight
# preview` gives with the same edit, bit for bit.
relightd="$(dirname "$relight")/server/relightd"
"$relightd" --listen 127.0.0.1:0 --shots "$dir" --log-level warn >"$work/d.out" 2>"$work/d.err" &
dpid=$!
trap 'kill -KILL $dpid 2>/dev/null; rm -rf "$work"' EXIT
for ((i = 0; i < 300; i++)); do
	line=$(head -n 1 "$work/d.out" 2>/dev/null)
	[ -n "$line" ] && break
	sleep 0.1
done
url=""
[[ "$line" =~ ^relightd:\ listening\ on\ https?://([^/]+)/$ ]] && url="ws://${BASH_REMATCH[1]}/ws"
checks=$((checks + 1))
what="relightd"
if [ -z "$url" ]; then
	fail "relightd did not start: $(head -c 300 "$work/d.err")"
else
	run "remote imager edit" "$relight" remote --json "$url" open imager set imager.bgcolor=0.6,0.3,0.1 \
		wait final snapshot "$dir/remote.exr"
	expect_status 0
	head -n 1 "$work/stdout" >"$dir/opened.json"
	checks=$((checks + 1))
	python3 -c '
import json, sys
o = json.load(open(sys.argv[1]))
im = o["imager"]
assert im["name"] == "imager" and im["shader"] == "background", im
assert [(p["name"], p["value"]) for p in im["params"]] == [("bgcolor", [0.25, 0.5, 0.75])], im
' "$dir/opened.json" || fail "the opened reply does not list the imager: $(head -c 400 "$dir/opened.json")"
	run "opened reply against the schema" python3 "$source_dir/protocol/schema/validate.py" \
		"$source_dir/protocol/schema/reply.schema.json" "$dir/opened.json"
	expect_status 0
	run "remote vs preview" bash -c "cd '$dir' && '$relight' preview -q --half --set imager.bgcolor=0.6,0.3,0.1 -o preview.exr imager.shot.exr && '$relight' diff --fail-rel 0 remote.exr preview.exr"
	expect_status 0
	run "remote refused imager edit" "$relight" remote "$url" open imager set imager.nope=1
	expect_status 1
	expect_stderr "unknown_param: imager 'background' .*has no parameter 'nope'"
	run "remote: the imager takes set alone" "$relight" remote "$url" open imager mute imager
	expect_status 1
fi
kill -TERM $dpid 2>/dev/null
wait $dpid 2>/dev/null

finish
