#!/usr/bin/env bash
# `relight compile` on good and bad shaders: exit status, diagnostics, --emit
# output, -o, -I, -D and the shader search path.
source "$(dirname "$0")/lib.sh"

cat >"$work/good.sl" <<'SL'
surface good(float Kd = 0.5; color tint = 1)
{
	Oi = Os;
	Ci = Os * Cs * tint * Kd;
}
SL

cat >"$work/bad.sl" <<'SL'
surface bad()
{
	Ci = Cs * ;
}
SL

run "good shader, no --emit" "$relight" compile "$work/good.sl"
expect_status 0
expect_empty_stdout
expect_empty_stderr

run "bad shader" "$relight" compile "$work/bad.sl"
expect_status 1
expect_empty_stdout
# FILE:LINE:COL: error: MESSAGE, at line 3.
expect_stderr "^$work/bad.sl:3:[0-9]+: error: "

run "bad shader, --emit report" "$relight" compile --emit report "$work/bad.sl"
expect_status 1
expect_empty_stdout

printf 'surface u() { Ci = nosuchvar; }\n' >"$work/undeclared.sl"
run "undeclared variable" "$relight" compile "$work/undeclared.sl"
expect_status 1
expect_stderr "^$work/undeclared.sl:1:[0-9]+: error: .*nosuchvar"

run "--emit report" "$relight" compile --emit report "$work/good.sl"
expect_status 0
expect_true "report is valid JSON" python3 -m json.tool "$work/stdout"
expect_true "report names the shader and its type" python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
assert r["name"] == "good", r
assert r["type"] == "surface", r
names = [p["name"] for p in r["parameters"]]
assert names == ["Kd", "tint"], names
' "$work/stdout"

# A uniform local that has to vary is promoted, silently on stderr, with a
# note in the report: its name, declaration and the write that made it vary.
cat >"$work/promote.sl" <<'SL'
surface promote(float octaves = 4)
{
	uniform float i, amp = 1;
	float sum = 0;
	if (s > 0.5)
		for (i = 0; i < octaves; i += 1) {
			sum += amp * noise(P * i);
			amp *= 0.5;
		}
	Ci = sum;
}
SL
run "--emit report, promoted uniforms" "$relight" compile --emit report "$work/promote.sl"
expect_status 0
expect_empty_stderr
expect_true "report lists the promoted uniforms" python3 -c '
import json, sys
r = json.load(open(sys.argv[1]))
got = sorted((p["name"], p["declared"], p["line"], p["reason"]) for p in r["promoted"])
want = [("amp", 3, 8, "assigned under varying control flow"),
        ("i", 3, 6, "assigned under varying control flow")]
assert got == want, got
' "$work/stdout"
run "--emit report, nothing promoted" "$relight" compile --emit report "$work/good.sl"
expect_true "report has an empty promoted list" python3 -c '
import json, sys
assert json.load(open(sys.argv[1]))["promoted"] == []
' "$work/stdout"

run "--emit ir" "$relight" compile --emit ir "$work/good.sl"
expect_status 0
expect_stdout 'mul'

run "--emit ast" "$relight" compile --emit=ast "$work/good.sl"
expect_status 0
expect_stdout 'SHADER'

run "-o FILE" "$relight" compile --emit report -o "$work/out.json" "$work/good.sl"
expect_status 0
expect_empty_stdout
expect_true "-o wrote valid JSON" python3 -m json.tool "$work/out.json"

rm -f "$work/out2.json"
run "-o FILE on a bad shader" "$relight" compile --emit report -o "$work/out2.json" "$work/bad.sl"
expect_status 1
expect_true "-o wrote nothing for a bad shader" test ! -e "$work/out2.json"

run "-o in a missing directory" "$relight" compile --emit ir -o "$work/no/such/dir/x" "$work/good.sl"
expect_status 1
expect_stderr "cannot write"

# -I and -D, separate and joined.
mkdir -p "$work/inc"
printf '#define GAIN 0.25\n' >"$work/inc/gain.h"
cat >"$work/withinc.sl" <<'SL'
#include "gain.h"
surface withinc()
{
#ifdef BREAK_IT
	Ci = ;
#else
	Ci = Cs * GAIN;
#endif
}
SL
run "#include without -I" "$relight" compile "$work/withinc.sl"
expect_status 1
expect_stderr "withinc.sl:1:[0-9]+: error: "
run "-I DIR" "$relight" compile -I "$work/inc" "$work/withinc.sl"
expect_status 0
run "-IDIR" "$relight" compile "-I$work/inc" "$work/withinc.sl"
expect_status 0
run "--include DIR" "$relight" compile --include "$work/inc" "$work/withinc.sl"
expect_status 0
run "-D NAME" "$relight" compile -I "$work/inc" -D BREAK_IT "$work/withinc.sl"
expect_status 1
run "-DNAME=VALUE" "$relight" compile -I "$work/inc" -DBREAK_IT=1 "$work/withinc.sl"
expect_status 1
run "--define NAME" "$relight" compile -I "$work/inc" --define BREAK_IT "$work/withinc.sl"
expect_status 1

# The shader search: a bare name not found here is looked for in
# $RELIGHT_SHADER_PATH, then in the project's shaders/.
mkdir -p "$work/lib1" "$work/lib2" "$work/elsewhere"
cp "$work/good.sl" "$work/lib2/found.sl"
cd "$work/elsewhere" || exit 1
run "bare name in RELIGHT_SHADER_PATH" env RELIGHT_SHADER_PATH="$work/lib1:$work/lib2" \
	"$relight" compile --emit report found.sl
expect_status 0
expect_stdout '"good"'
run "bare name without .sl" env RELIGHT_SHADER_PATH="$work/lib2" "$relight" compile found
expect_status 0
run "bare name in the project's shaders/" env -u RELIGHT_SHADER_PATH \
	"$relight" compile --emit report plastic.sl
expect_status 0
expect_stdout '"plastic"'
run "a path with / is not searched" env RELIGHT_SHADER_PATH="$work/lib2" \
	"$relight" compile ./found.sl
expect_status 1
expect_stderr "cannot open './found.sl'"
cd "$source_dir" || exit 1

finish
