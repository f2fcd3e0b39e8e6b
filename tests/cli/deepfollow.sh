#!/usr/bin/env bash
# Deep shadow maps that follow a moving light, rendered on the GPU from the
# shot's shadow geometry. The scene (deepfollow/follow.rib): a deep shadow
# pass, looking down from the light, of three semi-transparent squares
# (opacities 0.3, 0.5, 0.2) and four half-opaque hairs; the view looks down
# at the receiver from under the squares. The light moves from (0, 10, 0) to
# (1.5, 10, 1), its maps following it (relight preview --follow 1). Checks:
#  - the GPU preview against `relight render` of the RIB whose shadow pass
#    moved with the light, within 0.1 % mean and 1 % max of the 8-bit range;
#    with the pass's samples at their strata's centres, as the GPU takes
#    them (the jittered pass is measured and printed, not held to it);
#  - at the receiver, against the light unshadowed at 0.28 of the
#    intensity: under the moved squares the product of the transparencies,
#    0.28, and where the moved light gets past them (under the squares for
#    the light where it was) all of it, each pixel within 1 %;
#  - no "kept as baked" warning, and the preview reports the map it rendered;
#  - without --follow the moved light keeps the baked map (the old image);
#  - --cpu: the CPU preview reads the baked maps (a warning says so), the
#    same image as the GPU's without --follow within 1e-4 relative, as for
#    depth maps.
# Without an EGL context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"

rib="$source_dir/tests/cli/deepfollow/follow.rib"
cd "$work" || exit 1

# scene NAME NLX NLZ LX LZ JITTER: the RIB with the light at (LX, 10, LZ)
scene() {
	sed -e "s/NLX/$2/;s/NLZ/$3/;s/LX/$4/g;s/LZ/$5/g;s/JITTER/$6/;s/follow\./$1./g" \
		"$rib" >"$1.rib"
}
scene base 0 0 0 0 0
scene moved -1.5 -1 1.5 1 0
scene jbase 0 0 0 0 1
scene jmoved -1.5 -1 1.5 1 1
# the moved light, unshadowed, at 0.28 of its intensity
sed -e 's/"shadowname" "moved.dsm"//' -e 's/"intensity" 100/"intensity" 28/' \
	-e 's/"moved.exr"/"open.exr"/' moved.rib >open.rib
checks=$((checks + 1))
grep -q '"intensity" 28' open.rib && ! grep -q shadowname open.rib || fail "cannot edit follow.rib"

for f in base moved open jbase jmoved; do
	run "render $f" "$relight" render -q "$f.rib"
	expect_status 0
	expect_empty_stderr
done
run "bake" "$relight" bake -q -o base.shot.exr base.rib
expect_status 0
expect_empty_stderr
run "bake, jittered pass" "$relight" bake -q -o jbase.shot.exr jbase.rib
expect_status 0
run "info" "$relight" info --json base.shot.exr
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("shot: %d shadow micropolygons with their opacity, %d bytes of shadow geometry" %
      (d["shadow_quads"], d["shadow_bytes"]))
assert d["shadow_quads"] > 0 and d["shadow_opacity"] and d["shadow_bytes"] >= 24 * d["shadow_quads"]
' "$work/stdout" || fail "relight info does not report the opacity: $(head -c 400 "$work/stdout")"

move=(--set 1.from=1.5,10,1 --set 1.to=1.5,0,1)
run "EGL context" "$relight" preview -q --json --follow 1 -o gpu.exr "${move[@]}" base.shot.exr
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	[ "$failures" -eq 0 ] || { finish; exit 1; }
	exit 77
fi
expect_status 0
expect_no_crash
checks=$((checks + 1))
! grep -q "is not rendered again" "$work/stderr" || fail "the deep map was kept as baked"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
print("GPU deep map: %d rendered, %d hits (at most %d in a texel), %d nodes, %d bytes, "
      "%d bytes of scratch" % (d["deep_maps_rendered"], d["deep_hits"], d["deep_max_texel_hits"],
      d["deep_nodes"], d["deep_map_bytes"], d["deep_scratch_bytes"]))
assert d["deep_maps_rendered"] >= 1 and d["deep_nodes"] > 0
' "$work/stdout" || fail "no deep map rendered: $(head -c 400 "$work/stdout")"

# compare WHAT REF IMG [strict]: relight diff; strict holds it to 0.1 % mean, 1 % max
compare() {
	run "$1 vs render" "$relight" diff --json "$2" "$3"
	expect_status 0
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
strict = sys.argv[3] == "strict"
print("%s: mean %.4f %% max %.4f %% of the 8-bit range%s" % (sys.argv[2], d["mean_pct"],
      d["max_pct"], " (limits 0.1, 1)" if strict else " (measured)"))
assert not strict or (d["mean_pct"] <= 0.1 and d["max_pct"] <= 1.0), d
' "$work/stdout" "$1" "$4" || fail "$1 differs from the render: $(head -c 300 "$work/stdout")"
}
compare "GPU preview, maps following, vs render of the moved pass" moved.exr gpu.exr strict

# The transmittance at the receiver: T = 0.28 * image / open, per pixel, in
# two regions of the receiver (world x0 x1 z0 z1 at y = 0, seen by the view
# camera at (0, 3.5, 0), fov 80 on 96x96, looking down, z up the image).
transmittance() {
	what="transmittance: $1"
	python3 - "$source_dir/tests/cli/deepfollow/exr.py" "$@" <<'PY'
import importlib.util, math, sys
spec = importlib.util.spec_from_file_location("exr", sys.argv[1])
exr = importlib.util.module_from_spec(spec)
spec.loader.exec_module(exr)
what, img, ref = sys.argv[2], exr.read(sys.argv[3]), exr.read(sys.argv[4])
regions = [("under the moved squares", (-1.5, 0.0, -1.5, 0.7), 0.28),
           ("past them, under the old ones", (0.9, 1.5, -1.2, 1.0), 1.0)]
t = 3.5 * math.tan(math.radians(40))
bad = False
for name, (x0, x1, z0, z1), want in regions:
	worst, total, n = 0.0, 0.0, 0
	for py in range(96):
		for px in range(96):
			x, z = ((px + 0.5) / 48 - 1) * t, (1 - (py + 0.5) / 48) * t
			if not (x0 <= x <= x1 and z0 <= z <= z1):
				continue
			T = 0.28 * img["G"][py][px] / ref["G"][py][px]
			worst = max(worst, abs(T - want) / want)
			total += T
			n += 1
	print("%s: %s: %d pixels, mean transmittance %.4f, want %.2f, worst %.3f %% off "
	      "(limit 1 %%)" % (what, name, n, total / n, want, 100 * worst))
	bad = bad or n < 50 or worst > 0.01
sys.exit(1 if bad else 0)
PY
}
checks=$((checks + 1))
transmittance "render of the moved pass" moved.exr open.exr || fail "the scene's closed form does not hold"
checks=$((checks + 1))
transmittance "GPU preview, maps following" gpu.exr open.exr || fail "the transparencies differ"

# Without --follow the moved light keeps the map's camera (the old behaviour):
# not the moved pass.
run "preview, maps not following" "$relight" preview -q -o kept.exr "${move[@]}" base.shot.exr
expect_status 0
checks=$((checks + 1))
if transmittance "GPU preview, baked map kept" kept.exr open.exr >"$work/kept.txt"; then
	fail "the baked map gives the moved light's shadows: $(cat "$work/kept.txt")"
else
	cat "$work/kept.txt"
fi

# The jittered pass: the GPU samples the strata's centres; measured.
run "preview, jittered pass" "$relight" preview -q --follow 1 -o jgpu.exr "${move[@]}" jbase.shot.exr
expect_status 0
compare "GPU preview vs render of the moved jittered pass" jmoved.exr jgpu.exr measured

# The CPU preview reads the baked maps, depth and deep alike: said, and the
# GPU's image without --follow.
run "preview --cpu --follow" "$relight" preview -q --cpu --follow 1 -o cpu.exr "${move[@]}" base.shot.exr
expect_status 0
expect_stderr "warning: --follow 1: the CPU preview reads the light's shadow maps as baked"
run "CPU vs GPU without --follow" "$relight" diff --fail-rel 1e-4 cpu.exr kept.exr
expect_status 0
finish
