#!/usr/bin/env bash
# `relight remote` against a running relightd (the build's, beside relight:
# DIR/server/relightd):
#
#   - images: an edit made over the protocol, waited for and snapshotted by
#     the client from the tiles it received, equals `relight preview` of the
#     same shot with the same edits, exactly: the half floats of rgba16f
#     tiles (OpenEXR) and the 8-bit sRGB bytes of rgba8 tiles (PNG). Edits
#     of intensity, colour and position; the daemon keeps a shot's state
#     across connections, so the preview gets every edit made so far;
#   - errors: the server's codes (unknown light, no open shot, unknown
#     shot, a path for a shot name) with exit status 1, usage errors with 2,
#     a refused connection naming the URL;
#   - tokens: none or a bad one refused (auth), a viewer cannot edit
#     (forbidden), an editor can;
#   - list, stats, server-snapshot, watch and --json print what they say;
#   - wss:// with a self-signed certificate (when openssl is there);
#   - relightd exits with status 0 on SIGTERM.
#
# Without an EGL context the script skips (exit 77).
source "$(dirname "$0")/lib.sh"

relightd="$(dirname "$relight")/server/relightd"
if [ ! -x "$relightd" ]; then
	echo "no relightd at $relightd" >&2
	exit 1
fi

pids=()
cleanup() {
	local p
	for p in "${pids[@]}"; do
		kill -KILL "$p" 2>/dev/null
	done
	rm -rf "$work"
}
trap cleanup EXIT

shots="$work/shots"
mkdir -p "$shots"

# bake EXAMPLE: the example's RIB baked into the shots folder (shadow maps
# beside it, where both the daemon and the preview look for them).
bake() {
	cp "$source_dir/examples/$1/$1.rib" "$shots/"
	run "bake $1" bash -c "cd '$shots' && '$relight' bake -q '$1.rib'"
	expect_status 0
}
bake shadows
bake crowd

run "EGL context" bash -c "cd '$shots' && '$relight' preview -q -o '$work/probe.exr' crowd.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "SKIP: no EGL/OpenGL context here: $(head -c 300 "$work/stderr")"
	exit 77
fi

# start_daemon NAME [ARGS...]: start relightd on a free port; sets $url and
# ${NAME}_pid. Its stdout's first line gives the port.
start_daemon() {
	local name=$1 out="$work/$1.out" line="" i
	shift
	"$relightd" --listen 127.0.0.1:0 --shots "$shots" --log-level warn "$@" \
		>"$out" 2>"$work/$name.err" &
	local pid=$!
	pids+=("$pid")
	printf -v "${name}_pid" '%s' "$pid"
	for ((i = 0; i < 600; i++)); do
		line=$(head -n 1 "$out")
		[ -n "$line" ] && break
		kill -0 "$pid" 2>/dev/null || break
		sleep 0.1
	done
	checks=$((checks + 1))
	what="start relightd $name"
	if [[ "$line" =~ ^relightd:\ listening\ on\ https?://([^/]+)/$ ]]; then
		url="ws://${BASH_REMATCH[1]}/ws"
	else
		fail "no 'listening on' line: '$line'; stderr: $(head -c 500 "$work/$name.err")"
		url=""
	fi
}

# stop_daemon NAME: SIGTERM, then its exit status must be 0 within 30 s.
stop_daemon() {
	local pid_var="${1}_pid" i
	local pid=${!pid_var}
	what="relightd $1: SIGTERM"
	kill -TERM "$pid"
	for ((i = 0; i < 300; i++)); do
		kill -0 "$pid" 2>/dev/null || break
		sleep 0.1
	done
	checks=$((checks + 1))
	if kill -0 "$pid" 2>/dev/null; then
		fail "still running 30 s after SIGTERM"
		kill -KILL "$pid"
	fi
	status=0
	wait "$pid" || status=$?
	expect_status 0
}

start_daemon main
[ -n "$url" ] || { finish; exit 1; }

# exact A.exr B.exr: the two images hold the same values, bit for bit.
exact() {
	run "$what: diff" "$relight" diff --json --fail-rel 0 "$1" "$2"
	checks=$((checks + 1))
	python3 -c '
import json, sys
d = json.load(open(sys.argv[1]))
a = d.get("alpha") or {}
ok = d["rmse"] == 0 and d["max_rel"] == 0 and d["nonfinite"] == [0, 0] and a.get("rmse") == 0
sys.exit(0 if ok else 1)
' "$work/stdout" || fail "the images differ: $(head -c 600 "$work/stdout")"
	checks=$((checks + 1))
	cmp -s "$1" "$2" || fail "$1 and $2 are not the same bytes"
}

# (a) rgba16f: snapshots against `relight preview --half`, edits cumulated.
applied=()
case_exr() {
	local n=$1 e sets=()
	shift
	applied+=("$@")
	for e in "${applied[@]}"; do sets+=(--set "$e"); done
	run "exr $n: remote" "$relight" remote -q "$url" open shadows set "$@" wait final \
		snapshot "$work/r$n.exr"
	expect_status 0
	expect_empty_stderr
	run "exr $n: preview" bash -c "cd '$shots' && '$relight' preview -q --half ${sets[*]} -o '$work/p$n.exr' shadows.shot.exr"
	expect_status 0
	what="exr $n ($*)"
	exact "$work/r$n.exr" "$work/p$n.exr"
}
# shadows: ambient 1, shadowspot 2 (key.shd), point 3
case_exr 1 2.intensity=90 2.lightcolor=1,0.9,0.7
case_exr 2 2.from=3.5,6,-2.5
case_exr 3 3.intensity=0.7 3.from=-2,3,1

# The same state opened anew: the snapshot needs no edit.
run "exr: no edit" "$relight" remote -q "$url" open shadows snapshot "$work/r4.exr"
expect_status 0
what="exr: no edit"
exact "$work/r4.exr" "$work/p3.exr"

# A snapshot of the state before the last edit is not the same image: the
# comparison can fail.
checks=$((checks + 1))
what="exr: an edit changes the image"
cmp -s "$work/r2.exr" "$work/r3.exr" && fail "two different edits gave the same snapshot"

# (b) rgba8: PNG snapshots against `relight preview` PNG, byte for byte.
case_png() {
	local n=$1 e sets=()
	shift
	for e in "$@"; do sets+=(--set "$e"); done
	run "png $n: remote" "$relight" remote -q "$url" open crowd set "$@" snapshot "$work/r$n.png"
	expect_status 0
	run "png $n: preview" bash -c "cd '$shots' && '$relight' preview -q ${sets[*]} -o '$work/p$n.png' crowd.shot.exr"
	expect_status 0
	checks=$((checks + 1))
	what="png $n ($*)"
	[ "$(head -c 8 "$work/r$n.png" | od -An -tx1 | tr -d ' ')" = "89504e470d0a1a0a" ] ||
		fail "not a PNG"
	cmp -s "$work/r$n.png" "$work/p$n.png" || fail "the PNGs differ"
}
# crowd: ambient 1, distant 2, spot 3, point 4
case_png 1 3.intensity=70 3.lightcolor=0.9,0.6,0.3
case_png 2 3.intensity=70 3.lightcolor=0.9,0.6,0.3 3.from=2,6.5,3 3.to=0.5,0.5,8

# Another shot opened on the same connection: the first one's tiles, still
# coming, are not taken for the second's.
run "png: two shots" "$relight" remote -q "$url" open shadows set 2.intensity=95 open crowd \
	snapshot "$work/r3.png"
expect_status 0
checks=$((checks + 1))
what="png: two shots"
cmp -s "$work/r3.png" "$work/p2.png" || fail "the second shot's snapshot is not its state"

# Every level of an edit comes: watch prints them; --json replies parse.
run "watch" "$relight" remote "$url" open crowd set 4.intensity=0.5 watch 2
expect_status 0
expect_stdout '^level .*level=0'
expect_stdout '^level .*level=3'
expect_stderr '^set 4: edit [0-9]+'
run "--json" "$relight" remote --json "$url" list open crowd set 4.intensity=0.6 wait 1 stats
expect_status 0
checks=$((checks + 1))
what="--json"
python3 -c '
import json, sys
ops = [json.loads(l)["op"] for l in open(sys.argv[1])]
assert ops == ["shots", "opened", "ack", "wait", "stats"], ops
' "$work/stdout" || fail "the JSON lines are not the replies: $(head -c 500 "$work/stdout")"

run "list" "$relight" remote "$url" list
expect_status 0
expect_stdout '^crowd +320x180 +baked$'
expect_stdout '^shadows +[0-9]+x[0-9]+ +baked$'

run "stats" "$relight" remote -q "$url" open crowd stats
expect_status 0
expect_stdout '^tiles_sent: [0-9]+$'

run "server-snapshot" "$relight" remote -q "$url" open crowd server-snapshot
expect_status 0
checks=$((checks + 1))
what="server-snapshot"
# The server names the file in its snapshots folder (SHOTS/snapshots by default).
snap="$shots/snapshots/$(head -n 1 "$work/stdout")"
[ -f "$snap" ] && [ "$(head -c 4 "$snap" | od -An -tx1 | tr -d ' ')" = "762f3101" ] ||
	fail "the server's snapshot '$snap' is no OpenEXR file"

# (c) the server's errors, with exit status 1; usage errors with 2.
run "unknown light" "$relight" remote "$url" open crowd set 9.intensity=1
expect_status 1
expect_stderr '^relight remote: set: unknown_light: '
run "set without open" "$relight" remote "$url" set 3.intensity=1
expect_status 1
expect_stderr '^relight remote: set: state: '
run "unknown parameter" "$relight" remote "$url" open crowd set 3.nope=1
expect_status 1
expect_stderr '^relight remote: set: unknown_param: '
run "three values wanted" "$relight" remote "$url" open crowd set 3.from=1,2
expect_status 1
expect_stderr '^relight remote: set: (range|type): '
run "unknown shot" "$relight" remote "$url" open nothere
expect_status 1
expect_stderr '^relight remote: open: unknown_shot: '
# One prefix: the server's message is not prefixed with its op a second time.
expect_stderr "^relight remote: open: unknown_shot: no shot 'nothere'\$"
run "set without open: one prefix" "$relight" remote "$url" set 3.intensity=1
expect_stderr '^relight remote: set: state: no shot is open$'
run "wait without open" "$relight" remote "$url" wait
expect_status 1
expect_stderr '^relight remote: wait: no shot is open'
run "the commands stop at the first error" "$relight" remote "$url" open crowd set 9.x=1 snapshot "$work/never.png"
expect_status 1
checks=$((checks + 1))
[ ! -e "$work/never.png" ] || fail "a snapshot was written after a failed command"

run "usage: no command" "$relight" remote "$url"
expect_status 2
run "usage: bad URL" "$relight" remote http://127.0.0.1:1/ list
expect_status 2
expect_stderr "bad URL"
run "usage: unknown command" "$relight" remote "$url" frobnicate
expect_status 2
expect_stderr "unknown command 'frobnicate'"
run "usage: not finite" "$relight" remote "$url" open crowd set 3.intensity=nan
expect_status 2
run "usage: one format" "$relight" remote "$url" open crowd snapshot a.exr snapshot b.png
expect_status 2
run "usage: format" "$relight" remote --format rgba8 "$url" open crowd snapshot a.exr
expect_status 2
run "help" "$relight" remote --help
expect_status 0
for w in list open set mute unmute solo freeze unfreeze add-light remove-light wait snapshot \
	server-snapshot stats watch --token --token-file --format --ca-file --insecure --timeout \
	--json --quiet \
	'Exit status'; do
	expect_stdout "$w"
done

# (d) tokens.
printf '# who may connect\neditor-token-1 editor\nviewer-token-1 viewer\n' >"$work/tokens"
printf 'viewer-token-1 viewer\n' >"$work/viewer.token"
printf '# mine\n\n  editor-token-1\n' >"$work/editor.token"
main_url=$url
start_daemon tokens --token-file "$work/tokens"
if [ -n "$url" ]; then
	run "no token" "$relight" remote "$url" list
	expect_status 1
	expect_stderr "cannot connect: $url: .*auth"
	run "bad token" "$relight" remote --token not-a-token "$url" list
	expect_status 1
	expect_stderr 'auth'
	run "viewer" "$relight" remote --token-file "$work/viewer.token" "$url" open crowd set 3.intensity=3
	expect_status 1
	expect_stderr '^opened crowd'
	expect_stderr '^relight remote: set: forbidden: '
	run "editor" "$relight" remote --token-file "$work/editor.token" "$url" open crowd set 3.intensity=70
	expect_status 0
	run "a path for a shot" "$relight" remote --token editor-token-1 "$url" open ../x
	expect_status 1
	expect_stderr '^relight remote: open: (unknown_shot|range|type): '
	run "an absolute path for a shot" "$relight" remote --token editor-token-1 "$url" open /etc/passwd
	expect_status 1
	expect_stderr '^relight remote: open: '
	stop_daemon tokens
fi

# wss:// with a self-signed certificate: refused unless trusted (--ca-file)
# or unchecked (--insecure).
if command -v openssl >/dev/null &&
	openssl req -x509 -newkey rsa:2048 -nodes -keyout "$work/key.pem" -out "$work/cert.pem" \
		-days 2 -subj /CN=localhost -addext subjectAltName=IP:127.0.0.1 >/dev/null 2>&1; then
	start_daemon tls --tls-cert "$work/cert.pem" --tls-key "$work/key.pem"
	if [ -n "$url" ]; then
		url="wss://${url#ws://}"
		run "wss: untrusted" "$relight" remote "$url" list
		expect_status 1
		expect_stderr "cannot connect: $url: "
		run "wss: --ca-file" "$relight" remote --ca-file "$work/cert.pem" "$url" list open crowd \
			set 3.intensity=40 snapshot "$work/tls.png"
		expect_status 0
		expect_stdout '^crowd '
		checks=$((checks + 1))
		[ "$(head -c 8 "$work/tls.png" | od -An -tx1 | tr -d ' ')" = "89504e470d0a1a0a" ] ||
			fail "no PNG over wss"
		run "wss: --insecure" "$relight" remote --insecure "$url" list
		expect_status 0
		expect_stdout '^shadows '
		stop_daemon tls
	fi
else
	echo "no openssl: wss:// not tested"
fi

# (e) SIGTERM: exit status 0; then the connection is refused, naming the URL.
url=$main_url
stop_daemon main
run "refused" "$relight" remote --timeout 5 "$url" list
expect_status 1
expect_stderr "^relight remote: cannot connect: $url: "

finish
