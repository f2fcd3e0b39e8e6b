#!/usr/bin/env bash
# `relight bench`: the speed-against-error report on one example, in quick
# mode, with its latency through relightd and the light-count sweep:
#
#   - the report's files (report.md, report/report.json, the plots and the
#     heat map) are written, and the Markdown holds the example's table;
#   - every level is timed (finite, positive) and compared with the render of
#     the edited RIB: the final level within the GPU runtime's limits against
#     the renderer (mean <= 0.1 %, max <= 1 % of the 8-bit range), and each
#     coarser level no better than the final one;
#   - the light-count rows: without the light cache an edit of one light in
#     16 costs more than with it, and both give the same image (1e-4
#     relative);
#   - the cache's samples kept and indirect entries per pixel, in the JSON
#     (the totals over the image's pixels) and in the Markdown's cache table;
#   - no NaN or Infinity anywhere in the JSON;
#   - usage errors exit 2; a missing example exits 1 naming it.
#
# The stability suite itself runs as the unit test `stability`. Without an
# EGL context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"
limit=${RELIGHT_CLI_TIMEOUT:-600}

run "help" "$relight" bench --help
expect_status 0
expect_stdout '^usage: relight bench'
expect_stdout '--only PARTS'

run "bad --only" "$relight" bench --only speed
expect_status 2
expect_stderr "--only: 'speed'"
run "bad --edits" "$relight" bench --edits 0
expect_status 2
run "bad name" "$relight" bench ../etc
expect_status 2
run "missing example" "$relight" bench --quick --only examples --examples "$source_dir/examples" nosuch
expect_status 1
expect_stderr 'nosuch/nosuch.rib: no such example'

out="$work/out"
run "quick bench of shadows" "$relight" bench --quick --json --edits 3 --viewers 0 \
	--only examples,latency,lights --examples "$source_dir/examples" -o "$out" \
	--work "$work/bw" shadows
if [ "$status" -eq 77 ]; then
	echo "SKIP: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
	exit 77
fi
expect_status 0
cp "$work/stdout" "$work/bench.json"
for f in report.md report/report.json report/speed-error.svg report/speed-maxerror.svg \
	report/lights.svg report/compression.svg report/heat-shadows.png; do
	expect_true "$f written" test -s "$out/$f"
done
expect_true "report.md has the example" grep -q '^## shadows' "$out/report.md"
expect_true "report.md has the light counts" grep -q '^## Light count' "$out/report.md"
expect_true "report.md has the cache per pixel" grep -q \
	'^| shadows | [0-9]* / [0-9]* ([0-9.]*x) | [0-9]* / [0-9]* ([0-9.]*x) | [0-9.]* / [0-9.]* | [0-9]* / [0-9]* / [0-9]* (' \
	"$out/report.md"
expect_true "report.md names its command" grep -q 'relight bench --quick' "$out/report.md"
expect_true "JSON on stdout equals the report's" \
	python3 -c 'import json,sys; a=json.load(open(sys.argv[1])); b=json.load(open(sys.argv[2])); sys.exit(a!=b)' \
	"$work/bench.json" "$out/report/report.json"

check_json() {
	python3 - "$work/bench.json" <<'PY'
import json, math, sys
def bad_const(c):
	raise ValueError("non-JSON number " + c)
j = json.load(open(sys.argv[1]), parse_constant=bad_const)
errors = []
def check(cond, msg):
	if not cond:
		errors.append(msg)
ex = j["examples"]
check(len(ex) == 1 and ex[0]["name"] == "shadows" and ex[0]["ok"], "one example, shadows, ok")
e = ex[0]
lv = e["levels"]
check(len(lv) == 4, "four levels")
for l in lv:
	check(l["ms"] is not None and l["ms"] > 0, "level %d timed" % l["level"])
	check(l["entries"] > 0, "level %d has entries" % l["level"])
final = lv[3]
check(final["mean_pct"] <= 0.1, "final mean error %.4f %% <= 0.1 %%" % final["mean_pct"])
check(final["max_pct"] <= 1.0, "final max error %.3f %% <= 1 %%" % final["max_pct"])
for l in lv[:3]:
	check(l["mean_pct"] >= final["mean_pct"], "level %d no better than final" % l["level"])
check(lv[0]["entries"] < lv[3]["entries"], "level 0 resolves fewer entries than the final")
check(e["render_s"] > 0 and e["bake_s"] > 0, "render and bake timed")
c = e["cache"]
check(c["stored_bytes"] > 0 and c["raw_bytes"] > c["stored_bytes"], "the cache is compressed")
check(c["shaded_points"] >= c["shading_samples"] > 0, "samples kept <= micropolygons")
# per pixel, as lightspeed-2007's totals compare across image sizes
px = e["width"] * e["height"]
for k in ("shading_samples", "indirect_entries"):
	v = c.get(k + "_per_pixel")
	check(v is not None and abs(v - c[k] / px) <= 1e-9 * v, "%s per pixel: %s, expected %g"
	      % (k, v, c[k] / px))
lat = e["latency"]
check(len(lat) == 1 and lat[0]["clients"] == 1 and lat[0]["median_ms"] > 0, "latency measured")
rows = j["light_counts"]["rows"]
check([r["lights"] for r in rows] == [1, 4, 16], "light counts 1, 4, 16")
r16 = rows[-1]
check(r16["without_cache"]["edit_ms"] > r16["with_cache"]["edit_ms"],
      "16 lights: no cache slower than the cache")
for r in rows:
	check(r["cache_vs_nocache_max_rel"] <= 1e-4, "%d lights: same image with and without cache" % r["lights"])
	check(r["vs_render"]["mean_pct"] is not None and r["vs_render"]["mean_pct"] <= 0.1,
	      "%d lights: final level against the render" % r["lights"])
check(j["ok"] is True, "ok")
for m in errors:
	print("FAIL:", m)
sys.exit(1 if errors else 0)
PY
}
expect_true "the JSON's figures" check_json
expect_true "no NaN in the report" bash -c "! grep -qiE 'nan|inf[^o]' '$out/report/report.json'"

# rays per second: Embree and the GPU's shadow kernel on the same rays, and
# how many they answer differently (at most 1 in 10,000)
run "quick rays" "$relight" bench --quick --json --only rays -o "$work/rays" --work "$work/rw"
expect_status 0
expect_true "report.md has the rays" grep -q '^## Rays per second' "$work/rays/report.md"
checks=$((checks + 1))
python3 - "$work/stdout" <<'PY' || fail "the rays' figures"
import json, sys
r = json.load(open(sys.argv[1]))["rays"]
print("rays: %d through %d triangles, %d blocked; Embree %.3g rays/s, GPU %.3g rays/s, "
      "%d answered otherwise" % (r["rays"], r["triangles"], r["occluded"],
      r["embree_rays_per_s"], r["gpu_rays_per_s"], r["disagree"]))
assert r["rays"] == 65536 and r["triangles"] == 102400
assert 0.2 * r["rays"] < r["occluded"] < 0.8 * r["rays"]
assert r["embree_rays_per_s"] > 0 and r["gpu_rays_per_s"] > 0 and r["gpu_bytes"] > 0
assert r["disagree"] <= r["rays"] / 10000
PY
finish
