#!/usr/bin/env bash
# `relight compile --dynamic ... --emit report|cache`: the specialization of
# surface shaders, and its errors.
source "$(dirname "$0")/lib.sh"

run "report of plastic, lights dynamic" "$relight" compile --emit report plastic
expect_status 0
checks=$((checks + 1))
python3 - "$work/stdout" <<'PY' || fail "report fields"
import json, sys
d = json.load(open(sys.argv[1]))
for k in ("dynamic_params", "cached_channels", "cached_scalars", "cache_required",
          "static_instructions", "dynamic_instructions", "dead_instructions", "glsl_lines"):
    assert k in d, k
assert d["dynamic_params"] == []
assert d["cached_scalars"] == sum(c["components"] for c in d["cached_channels"])
assert d["dynamic_instructions"] > 0
PY

run "report with --dynamic" "$relight" compile --emit report --dynamic Kd,roughness plastic
expect_status 0
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert d["dynamic_params"] == ["Kd", "roughness"], d["dynamic_params"]
' "$work/stdout" || fail "dynamic_params"

run "caching program" "$relight" compile --emit cache plastic
expect_status 0
expect_stdout "call +normalize"
checks=$((checks + 1))
grep -q "call *specular\|call *diffuse" "$work/stdout" && fail "lighting in the caching program"

run "unknown dynamic parameter" "$relight" compile --dynamic nosuch plastic
expect_status 1
expect_stderr "has no parameter 'nosuch'"

run "light shader" "$relight" compile --emit cache spotlight
expect_status 1
expect_stderr "only surface shaders are specialized"

run "empty --dynamic" "$relight" compile --dynamic , plastic
expect_status 2

# A light-dependent derivative: computed at bake time, a warning; an error with --strict.
cat >"$work/deriv.sl" <<'SL'
surface deriv()
{
	color c = diffuse(normalize(N));
	Oi = 1;
	Ci = Du(comp(c, 0)) * c;
}
SL
run "cache-required warning" "$relight" compile --emit report "$work/deriv.sl"
expect_status 0
expect_stderr "deriv.sl:5:7: warning: this light-dependent value cannot be computed on the GPU"
checks=$((checks + 1))
python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
assert [c["builtin"] for c in d["cache_required"]] == ["Du"], d["cache_required"]
' "$work/stdout" || fail "cache_required in the report"
run "cache-required with --strict" "$relight" compile --strict "$work/deriv.sl"
expect_status 1
expect_stderr "deriv.sl:5:7: error: this light-dependent value"
run "--strict on a clean shader" "$relight" compile --strict plastic
expect_status 0

# Every shader of the library gives GLSL that glslangValidator accepts.
if command -v glslangValidator >/dev/null 2>&1; then
	for sl in "$source_dir"/shaders/*.sl; do
		name=$(basename "$sl" .sl)
		case "$name" in noisebump|null_displacement) continue ;; esac   # displacement: not on the GPU
		# a volume shader runs on the GPU joined after its surface
		case "$name" in fog|depthcue) set -- --atmosphere "$sl" plastic ;; *) set -- "$sl" ;; esac
		run "glsl of $name" "$relight" compile --emit glsl -o "$work/$name.comp" "$@"
		expect_status 0
		run "glslangValidator accepts $name" glslangValidator "$work/$name.comp"
		expect_status 0
	done
else
	echo "specialize.sh: glslangValidator missing: GLSL validation skipped" >&2
fi

finish
