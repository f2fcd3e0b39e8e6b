#!/usr/bin/env bash
# The GPU runtime (`relight preview` without --cpu) on the examples, light
# edits included:
#
#   - against the CPU resolver (`relight preview --cpu`) with the same --set
#     edits: the largest relative difference of the linear colours,
#     |gpu - cpu| / max(|gpu|, |cpu|), at most 1e-4 (values under 1e-3
#     compared absolutely, see `relight diff --help`);
#   - against `relight render` of the RIB edited the same way: mean error
#     <= 0.1 % and maximum error <= 1 % of the 8-bit range (after sRGB).
#
# Edits cover light position, direction, intensity, colour, cone angles and
# shadow parameters. The shadows example's map is rendered by the RIB's own
# shadow pass, whose camera the edits leave alone: the edited render reads the
# same map as the shot, so shadow edges are compared like everything else.
#
# Also: the --json report (full_ms, edit_ms, per-level ms and entries), the
# computation graph (a shadow node only where a light reads a shadow map),
# refused edits, and every coarse level. Without an EGL context the script
# skips (exit 77).
source "$(dirname "$0")/lib.sh"

max_rel=1e-4
max_mean_pct=0.1
max_max_pct=1.0

# baked EXAMPLE RIB: a copy of the example folder with the RIB baked (once).
baked() {
	local ex=$1 rib=$2 dir="$work/$1"
	if [ ! -s "$dir/${rib%.rib}.shot.exr" ]; then
		rm -rf "$dir"
		cp -R "$source_dir/examples/$ex" "$dir"
		run "$ex: bake" bash -c "cd '$dir' && '$relight' bake -q '$rib'"
		[ "$status" -eq 0 ] || { fail "bake failed"; return 1; }
	fi
	echo "$dir"
}

# The first bake tells whether there is a GPU context at all.
dir=$(baked crowd crowd.rib) || { finish; exit 1; }
run "EGL context" bash -c "cd '$dir' && '$relight' preview -q -o probe.exr crowd.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi

# gpu_case EXAMPLE RIB EDIT...: one check of the GPU preview against the CPU
# resolver and against the edited render.
gpu_case() {
	local ex=$1 rib=$2
	shift 2
	local dir name sets=() e
	name="$ex $*"
	dir=$(baked "$ex" "$rib") || return
	for e in "$@"; do sets+=(--set "$e"); done
	checks=$((checks + 1))
	what="$name"
	local shot="${rib%.rib}.shot.exr"
	run "$name: gpu" bash -c "cd '$dir' && '$relight' preview -q --json ${sets[*]} -o gpu.exr '$shot'"
	[ "$status" -eq 0 ] || { fail "GPU preview failed (status $status)"; return; }
	cp "$work/stdout" "$dir/gpu.json"
	run "$name: cpu" bash -c "cd '$dir' && '$relight' preview -q --cpu ${sets[*]} -o cpu.exr '$shot'"
	[ "$status" -eq 0 ] || { fail "CPU preview failed (status $status)"; return; }
	run "$name: gpu vs cpu" "$relight" diff --json "$dir/cpu.exr" "$dir/gpu.exr"
	cp "$work/stdout" "$dir/vs_cpu.json"
	set_light_params "$dir/$rib" "$dir/edited.rib" "$@" || { fail "cannot edit $rib"; return; }
	local image
	image=$(grep -m1 -oE 'Display "[^"]+" "file"' "$dir/$rib" | cut -d'"' -f2)
	run "$name: render" bash -c "cd '$dir' && '$relight' render -q -o edited.exr edited.rib"
	[ "$status" -eq 0 ] || { fail "render of the edited RIB failed (status $status)"; return; }
	run "$name: gpu vs render" "$relight" diff --json "$dir/edited.exr" "$dir/gpu.exr"
	cp "$work/stdout" "$dir/vs_render.json"
	: >"$work/stderr"
	python3 - "$dir" "$max_rel" "$max_mean_pct" "$max_max_pct" "$name" "$image" >"$work/verdict" <<'PY'
import json, sys
d, max_rel, max_mean, max_max, name = sys.argv[1], float(sys.argv[2]), float(sys.argv[3]), float(sys.argv[4]), sys.argv[5]
g = json.load(open(d + "/gpu.json"))
c = json.load(open(d + "/vs_cpu.json"))
r = json.load(open(d + "/vs_render.json"))
why = []
if not (c["max_rel"] <= max_rel):
	why.append("GPU vs CPU: max relative %.3g > %g at %s" % (c["max_rel"], max_rel, c["max_at"]))
if not (r["mean_pct"] <= max_mean and r["max_pct"] <= max_max):
	why.append("GPU vs edited render: mean %.4f %% max %.4f %% at %s (limits %g, %g)"
		   % (r["mean_pct"], r["max_pct"], r["max_at"], max_mean, max_max))
for k in ("full_ms", "edit_ms"):
	if not (isinstance(g.get(k), (int, float)) and g[k] > 0):
		why.append("--json has no positive " + k)
lv = g.get("levels", [])
if len(lv) != 4 or any(not (l["ms"] >= 0 and l["entries"] > 0) for l in lv):
	why.append("--json levels are incomplete")
print("%s: vs cpu max_rel %.2g; vs render mean %.4f %% max %.4f %%; full %.1f ms, edit %.1f ms (level 0 %.1f ms)"
      % (name, c["max_rel"], r["mean_pct"], r["max_pct"], g["full_ms"], g["edit_ms"], lv[0]["ms"] if lv else -1))
for w in why:
	print("FAIL: " + w)
PY
	cat "$work/verdict"
	if grep -q '^FAIL' "$work/verdict"; then
		fail "$(grep '^FAIL' "$work/verdict" | tr '\n' ' ')"
	fi
}

# crowd: ambient 1, distant 2, spot 3, point 4
gpu_case crowd crowd.rib 3.intensity=70 3.lightcolor=0.9,0.6,0.3
gpu_case crowd crowd.rib 3.from=2,6.5,3 3.to=0.5,0.5,8
gpu_case crowd crowd.rib 3.coneangle=0.6 3.conedeltaangle=0.15
gpu_case crowd crowd.rib 2.to=1,-0.5,1.5 4.from=-2,3,9
gpu_case motion motion.rib 1.intensity=0.5 1.from=-2,3,-1 2.intensity=0.3
# lens: depth of field and a moving camera; distant 1, ambient 2, spot 3
gpu_case lens lens.rib 3.intensity=45 3.from=1,4,2 1.intensity=0.5
gpu_case displaced displaced.rib 1.lightcolor=1,0.8,0.6 2.intensity=2
gpu_case lights32 lights32.rib 5.from=1,2,3 33.coneangle=0.5 35.intensity=2
# shadows: ambient 1, shadowspot 2 (key.shd), point 3
gpu_case shadows shadows.rib 2.intensity=90 2.lightcolor=1,0.9,0.7
gpu_case shadows shadows.rib 2.samples=64 2.blur=0.01
gpu_case shadows shadows.rib 2.from=3.5,6,-2.5 2.coneangle=0.5
# Deforming primitives (tests/cli/deform/deform.rib: a sphere growing over
# the shutter, a height field whose heights move), baked here, so that
# baked() finds the shot.
mkdir -p "$work/deforming"
cp "$source_dir/tests/cli/deform/deform.rib" "$work/deforming/"
run "deforming: bake" bash -c "cd '$work/deforming' && '$relight' bake -q deform.rib"
expect_status 0
gpu_case deforming deform.rib 1.intensity=0.5 2.from=-1,2,1 2.intensity=6

# The graph has a shadow node only where a light reads a shadow map.
dir=$(baked crowd crowd.rib)
run "graph" bash -c "cd '$dir' && '$relight' preview -q --json -o g.exr crowd.shot.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
g = json.load(open(sys.argv[1]))["graph"]
names = [n["name"] for n in g]
assert not any(n.startswith("shadow:") for n in names), names
assert sum(n.startswith("shade:") for n in names) == 4 and sum(n.startswith("resolve:") for n in names) == 4
' "$work/stdout" || fail "the crowd graph is not what its lights need"
dir=$(baked shadows shadows.rib)
run "graph with shadows" bash -c "cd '$dir' && '$relight' preview -q --json -o g.exr shadows.shot.exr"
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
g = json.load(open(sys.argv[1]))["graph"]
assert [n["name"] for n in g if n["name"].startswith("shadow:")] == ["shadow:2"], g
' "$work/stdout" || fail "the shadows graph has no node for light 2's map"

# Every level: coarse levels match the CPU resolver's coarse levels.
dir=$(baked crowd crowd.rib)
for level in 0 1 2; do
	run "level $level" bash -c "cd '$dir' && '$relight' preview -q --level $level --set 3.intensity=55 -o l$level.gpu.exr crowd.shot.exr && '$relight' preview -q --cpu --level $level --set 3.intensity=55 -o l$level.cpu.exr crowd.shot.exr && '$relight' diff --fail-rel $max_rel l$level.cpu.exr l$level.gpu.exr"
	expect_status 0
done

# The runtime's outputs: linear half (within half precision of the CPU's
# floats) and 8-bit sRGB as PNG; both are the GPU's, not with --cpu.
run "half output" bash -c "cd '$dir' && '$relight' preview -q --half -o h.exr crowd.shot.exr && '$relight' preview -q --cpu -o c.exr crowd.shot.exr && '$relight' diff --fail-rel 1e-3 c.exr h.exr"
expect_status 0
run "png output" bash -c "cd '$dir' && '$relight' preview -q -o p.png crowd.shot.exr && head -c 8 p.png | od -An -tx1"
expect_status 0
expect_stdout "89 50 4e 47 0d 0a 1a 0a"
run "--half with --cpu" "$relight" preview --cpu --half -o x.exr "$dir/crowd.shot.exr"
expect_status 2

# Refused edits: a clear error, exit status 1, no image.
for bad in 3.intensity=nan 3.intensity=inf 3.coneangle=4 3.coneangle=-0.1 3.from=1,2 9.intensity=1 3.nope=1 3.shadowname=1; do
	run "refuse $bad" bash -c "cd '$dir' && rm -f bad.exr && '$relight' preview -q --set $bad -o bad.exr crowd.shot.exr"
	expect_status 1
	expect_stderr "relight: error: .*(light|finite|outside|takes|no )"
	checks=$((checks + 1))
	[ ! -e "$dir/bad.exr" ] || fail "an image was written for a refused edit"
done

finish
