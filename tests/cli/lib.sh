# Helpers for the shell tests of the relight command. A test script runs as
#   bash tests/cli/NAME.sh PATH/TO/relight
# sources this file, calls `run` and the `expect_*` checks, and ends with
# `finish`, which prints "N checks, N failed" and sets the exit status.

set -u

relight=${1:?usage: $0 PATH/TO/relight}
# absolute, as some tests change directory
relight="$(cd "$(dirname "$relight")" && pwd)/$(basename "$relight")"
source_dir=${RELIGHT_SOURCE_DIR:-$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)}
checks=0
failures=0
what=""

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Seconds one command may take before it counts as hung.
limit=${RELIGHT_CLI_TIMEOUT:-60}

fail() {
	failures=$((failures + 1))
	printf '%s: [%s] %s\n' "$(basename "$0")" "$what" "$*" >&2
	if [ -s "$work/stderr" ]; then
		printf '  stderr was:\n' >&2
		head -c 2000 "$work/stderr" | sed 's/^/    /' >&2
	fi
}

# run DESCRIPTION CMD [ARGS]: run with a time limit; keep stdout, stderr and
# the exit status (in $status) for the checks that follow.
run() {
	what=$1
	shift
	status=0
	timeout "$limit" "$@" >"$work/stdout" 2>"$work/stderr" || status=$?
}

expect_status() {
	checks=$((checks + 1))
	if [ "$status" -eq 124 ]; then
		fail "timed out after ${limit}s"
	elif [ "$status" -ne "$1" ]; then
		fail "exit status $status, expected $1"
	fi
}

# The command ended on its own, without a signal (status < 128) or a sanitizer report.
expect_no_crash() {
	checks=$((checks + 1))
	if [ "$status" -eq 124 ] || [ "$status" -ge 128 ]; then
		fail "crashed or hung: exit status $status"
	elif grep -qE 'AddressSanitizer|LeakSanitizer|runtime error:' "$work/stderr"; then
		fail "sanitizer report"
	fi
}

# expect_stdout REGEX / expect_stderr REGEX: some line matches (grep -E).
expect_stdout() {
	checks=$((checks + 1))
	grep -qE -- "$1" "$work/stdout" || fail "stdout has no line matching '$1'"
}

expect_stderr() {
	checks=$((checks + 1))
	grep -qE -- "$1" "$work/stderr" || fail "stderr has no line matching '$1'"
}

expect_empty_stdout() {
	checks=$((checks + 1))
	[ ! -s "$work/stdout" ] || fail "stdout is not empty: $(head -c 200 "$work/stdout")"
}

expect_empty_stderr() {
	checks=$((checks + 1))
	[ ! -s "$work/stderr" ] || fail "stderr is not empty"
}

# expect_true DESCRIPTION CMD [ARGS]: CMD succeeds.
expect_true() {
	local d=$1
	shift
	checks=$((checks + 1))
	"$@" >/dev/null || fail "$d"
}

finish() {
	echo "$checks checks, $failures failed"
	[ "$failures" -eq 0 ]
}

# expect_matches_render WHAT REF IMAGE [MEAN_PCT MAX_PCT]: `relight diff REF IMAGE`
# (paths under $work) within MEAN_PCT mean and MAX_PCT max error of the 8-bit
# range, colour and alpha both: by default 0.1 % and 1 %, the acceptance line of
# a preview against the reference render. The figures are printed either way.
expect_matches_render() {
	local name=$1 ref=$2 img=$3 mean=${4:-0.1} max=${5:-1.0}
	run "$name vs render" "$relight" diff --json "$work/$ref" "$work/$img"
	expect_status 0
	checks=$((checks + 1))
	python3 - "$work/stdout" "$name" "$mean" "$max" <<'PY' || fail "$name differs from the render"
import json, sys
d = json.load(open(sys.argv[1]))
name, mean, mx = sys.argv[2], float(sys.argv[3]), float(sys.argv[4])
a = d["alpha"]
assert a is not None, "no alpha compared"
print("%s vs render: colour mean %.4f %% max %.4f %%, alpha mean %.4f %% max %.4f %% (limits %g %%, %g %%)"
      % (name, d["mean_pct"], d["max_pct"], a["mean_pct"], a["max_pct"], mean, mx))
assert d["mean_pct"] <= mean and d["max_pct"] <= mx, d
assert a["mean_pct"] <= mean and a["max_pct"] <= mx, a
PY
}

# skip_without_gpu: after a `run` of a GPU command, end the test when it failed
# for want of an EGL/OpenGL 4.3 context: a loud skip (77) if every check so far
# passed, a failure otherwise.
skip_without_gpu() {
	if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
		echo "SKIP: the GPU part: no EGL/OpenGL 4.3 context here: $(head -c 300 "$work/stderr")"
		[ "$failures" -eq 0 ] || { finish; exit 1; }
		exit 77
	fi
}

# set_light_params IN OUT EDIT...: the RIB IN written as OUT with each EDIT,
# HANDLE.PARAM=V[,V...], applied: the LightSource with that handle gets
# "PARAM" [V ...] (replacing the parameter if given), as --set edits a light.
set_light_params() {
	python3 - "$@" <<'PY'
import re, sys
src, dst, edits = sys.argv[1], sys.argv[2], sys.argv[3:]
text = open(src).read()
for e in edits:
	lhs, vals = e.split("=", 1)
	handle, param = lhs.split(".", 1)
	vals = " ".join(vals.split(","))
	m = re.search(r'LightSource\s+"[^"]+"\s+' + re.escape(handle) + r'\b', text)
	if not m:
		sys.exit("no LightSource " + handle)
	# the request runs until the next line that starts a request
	end = re.compile(r'\n\s*[A-Z][A-Za-z]*\b').search(text, m.end())
	end = end.start() if end else len(text)
	req = text[m.start():end]
	req = re.sub(r'\s*"' + re.escape(param) + r'"\s+(\[[^\]]*\]|\S+)', "", req)
	req += ' "%s" [%s]' % (param, vals)
	text = text[:m.start()] + req + text[end:]
open(dst, "w").write(text)
PY
}
