#!/usr/bin/env bash
# `relight render --set LIGHT.PARAM=V[,V...]`: a render with light edits is
# bit for bit the render of the RIB edited by hand the same way (the
# reference the preview's edits are measured against), the edit changes the
# image, a shadow pass is left alone, and bad edits are clear errors.
source "$(dirname "$0")/lib.sh"

run "help" "$relight" render --help
expect_status 0
expect_stdout "--set LIGHT.PARAM=V\[,V,V\]"
expect_stdout "Edit a light: LIGHT is its name \(the RIB handle"

cp -R "$source_dir/examples/crowd" "$source_dir/examples/shadows" "$work/"

# rmse FILE: the colour rmse of a `relight diff --json` answer.
rmse() {
	grep -oE '"rmse": [0-9.eE+-]+' "$1" | head -1 | cut -d' ' -f2
}

# The comparisons below are byte for byte, so the renderer must give the same
# file whatever the number of threads.
run "crowd: base render" bash -c "cd '$work/crowd' && '$relight' render -q -o base.exr crowd.rib"
expect_status 0
run "crowd: one thread" bash -c "cd '$work/crowd' && '$relight' render -q -t 1 -o one.exr crowd.rib"
expect_status 0
expect_true "the render depends on the thread count" cmp -s "$work/crowd/base.exr" \
	"$work/crowd/one.exr"

run "shadows: base render" bash -c "cd '$work/shadows' && '$relight' render -q shadows.rib"
expect_status 0
cp "$work/shadows/shadows.exr" "$work/shadows/base.exr"
cp "$work/shadows/key.z" "$work/shadows/base.z"
cp "$work/shadows/key.shd" "$work/shadows/base.shd"

# same_as_text EXAMPLE RIB SED-SCRIPT EDIT...: `render --set EDIT...` gives
# the same file as the RIB edited by SED-SCRIPT, and not the unedited image.
same_as_text() {
	local ex=$1 rib=$2 script=$3 dir="$work/$1"
	shift 3
	local name="$ex: --set $*" args=() e
	for e in "$@"; do
		args+=(--set "$e")
	done
	sed -e "$script" "$dir/$rib" >"$dir/text.rib"
	checks=$((checks + 1))
	if cmp -s "$dir/$rib" "$dir/text.rib"; then
		what=$name
		fail "the sed script '$script' changed nothing"
		return
	fi
	run "$name: the edited text" bash -c "cd '$dir' && '$relight' render -q -o text.exr text.rib"
	expect_status 0
	run "$name" bash -c "cd '$dir' && '$relight' render -q -o set.exr $(printf "'%s' " "${args[@]}") '$rib'"
	expect_no_crash
	expect_status 0
	expect_empty_stderr
	checks=$((checks + 1))
	cmp -s "$dir/set.exr" "$dir/text.exr" || {
		"$relight" diff --json "$dir/text.exr" "$dir/set.exr" >"$work/stderr" 2>&1
		fail "differs from the render of the edited RIB"
	}
	run "$name: changes the image" "$relight" diff --json "$dir/base.exr" "$dir/set.exr"
	expect_status 0
	checks=$((checks + 1))
	local r
	r=$(rmse "$work/stdout")
	awk -v r="$r" 'BEGIN { exit !(r > 0) }' || fail "the edit left the image as it was (rmse '$r')"
	if [ "$ex" = shadows ]; then
		checks=$((checks + 1))
		cmp -s "$dir/key.z" "$dir/base.z" && cmp -s "$dir/key.shd" "$dir/base.shd" ||
			fail "the shadow pass changed"
	fi
}

# crowd: ambient 1, distant 2, spot 3, point 4
same_as_text crowd crowd.rib 's/"spotlight" 3 "intensity" 40/"spotlight" 3 "intensity" 70/' \
	3.intensity=70
# a parameter the request does not give joins its list
same_as_text crowd crowd.rib '/LightSource "spotlight" 3/s/$/ "lightcolor" [0.9 0.6 0.3]/' \
	3.lightcolor=0.9,0.6,0.3
# one value is a grey colour
same_as_text crowd crowd.rib 's/"lightcolor" \[1 0.75 0.45\]/"lightcolor" [0.5 0.5 0.5]/' \
	4.lightcolor=0.5
same_as_text crowd crowd.rib 's/"from" \[3 3.3 11\]/"from" [2 3 9]/' 4.from=2,3,9
# a parameter on the request's second line; edits in order, the last one wins
same_as_text crowd crowd.rib \
	's/"coneangle" 0.3/"coneangle" 0.5/; s/"spotlight" 3 "intensity" 40/"spotlight" 3 "intensity" 55/' \
	3.intensity=10 3.coneangle=0.5 3.intensity=55
same_as_text crowd crowd.rib \
	's/"ambientlight" 1 "intensity" 0.12 "lightcolor" \[0.6 0.7 1\]/"ambientlight" 1 "intensity" 0.3 "lightcolor" [1 0.2 0.2]/' \
	1.intensity=0.3 1.lightcolor=1,0.2,0.2

# shadows: frame 1 renders the key light's depth (no lights), frame 2 the
# image with ambient 1, shadowspot 2 (reading key.shd), point 3
same_as_text shadows shadows.rib 's/"shadowspot" 2 "intensity" 60/"shadowspot" 2 "intensity" 30/' \
	2.intensity=30
same_as_text shadows shadows.rib 's/"from" \[4 6 -3\]/"from" [3 5 -2]/' 2.from=3,5,-2
same_as_text shadows shadows.rib '/LightSource "shadowspot" 2/s/$/ "lightcolor" [0.25 0.25 0.25]/' \
	2.lightcolor=0.25
same_as_text shadows shadows.rib 's/"lightcolor" \[0.4 0.5 0.8\]/"lightcolor" [1 0.8 0.6]/' \
	3.lightcolor=1,0.8,0.6

# A light of our own: a string handle, a matrix, an array and an output.
mkdir -p "$work/own"
cat >"$work/own/tint.sl" <<'SL'
light
tint(float intensity = 1;
     float weights[2] = {1, 1};
     matrix xf = 1;
     output float hits = 0;
     point from = point "shader" (0, 0, -5))
{
	illuminate(from) {
		point q = transform(xf, point(1, 2, 3));
		Cl = intensity * weights[0] * color(xcomp(q), ycomp(q), zcomp(q)) / (L . L);
	}
}
SL
cat >"$work/own/own.rib" <<'RIB'
Format 32 24 1
PixelSamples 2 2
Display "own.exr" "file" "rgba"
Option "searchpath" "shader" ".:@"
WorldBegin
  LightSource "tint" "key" "intensity" 20
  Surface "matte"
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
RIB
run "own: base render" bash -c "cd '$work/own' && '$relight' render -q -o base.exr own.rib"
expect_status 0
same_as_text own own.rib \
	'/LightSource "tint" "key"/s/$/ "xf" [2 0 0 0  0 0.5 0 0  0 0 1 0  0.1 0 0 1]/' \
	key.xf=2,0,0,0,0,0.5,0,0,0,0,1,0,0.1,0,0,1

# bad_edit EXAMPLE RIB EDIT REGEX: exit status 1 and a message matching
# REGEX; the edit's frame is held back, so no image.
bad_edit() {
	local dir="$work/$1" rib=$2 edit=$3
	rm -f "$dir/bad.exr"
	run "$1: --set $edit" bash -c "cd '$dir' && '$relight' render -q -o bad.exr --set '$edit' '$rib'"
	expect_no_crash
	expect_status 1
	expect_stderr "$4"
	checks=$((checks + 1))
	[ ! -e "$dir/bad.exr" ] || fail "an image was written"
}

# A light that no frame declares: the error, one line for each such edit,
# found by reading the whole scene before any frame renders (nothing written).
run "crowd: --set of unknown lights" bash -c \
	"cd '$work/crowd' && '$relight' render -q -o bad.exr --set 7.intensity=1 --set 3.intensity=2 --set key.from=0,0,0 crowd.rib"
expect_no_crash
expect_status 1
expect_stderr "^crowd.rib: error: --set 7.intensity: no LightSource with handle 7$"
expect_stderr "^crowd.rib: error: --set key.from: no LightSource with handle key$"
checks=$((checks + 1))
[ "$(wc -l <"$work/stderr")" -eq 2 ] || fail "expected two lines of errors"
checks=$((checks + 1))
[ ! -e "$work/crowd/bad.exr" ] || fail "an image was written despite the unknown lights"
bad_edit crowd crowd.rib 3.foo=1 "^crowd.rib:20: error: --set 3.foo: shader 'spotlight' has no parameter 'foo'$"
bad_edit crowd crowd.rib 3.intensity=1,2 \
	"^crowd.rib:20: error: --set 3.intensity: parameter 'intensity' of shader 'spotlight' is a float and takes 1 value, not 2$"
bad_edit crowd crowd.rib 3.lightcolor=1,2 \
	"^crowd.rib:20: error: --set 3.lightcolor: .* is a color and takes 3 values, not 2$"
# one value broadcasts to a colour only, not to a point
bad_edit crowd crowd.rib 4.from=1 \
	"^crowd.rib:22: error: --set 4.from: .* is a point and takes 3 values, not 1$"
# nothing after '=' is the empty string: not a float
bad_edit crowd crowd.rib 3.intensity= \
	"^crowd.rib:20: error: --set 3.intensity: parameter 'intensity' of shader 'spotlight' is a float and needs numbers, not ''$"
bad_edit crowd crowd.rib 3.intensity=nan \
	"^crowd.rib:20: error: --set 3.intensity: parameter 'intensity' needs finite values, not nan$"
bad_edit crowd crowd.rib 3.lightcolor=1,inf,1 "^crowd.rib:20: error: --set 3.lightcolor: .* needs finite values"
bad_edit crowd crowd.rib 3.intensity=-infinity "^crowd.rib:20: error: --set 3.intensity: .* needs finite values"
bad_edit shadows shadows.rib 2.shadowname=1 \
	"^shadows.rib:52: error: --set 2.shadowname: parameter 'shadowname' of shader 'shadowspot' is a string; only"
bad_edit own own.rib key.weights=1,2 "^own.rib:6: error: --set key.weights: .* is a float array; only"
bad_edit own own.rib key.hits=1 "^own.rib:6: error: --set key.hits: shader 'tint' has no parameter 'hits'$"
bad_edit own own.rib key.xf=1 "^own.rib:6: error: --set key.xf: .* is a matrix and takes 16 values, not 1$"
run "own: --set of the default handle" bash -c \
	"cd '$work/own' && '$relight' render -q -o bad.exr --set 1.intensity=2 own.rib"
expect_status 1
expect_stderr "^own.rib: error: --set 1.intensity: no LightSource with handle 1$"

# bad_usage EDIT: exit status 2 with preview's message, before any rendering.
bad_usage() {
	run "usage: --set $1" bash -c "cd '$work/crowd' && '$relight' render -q -o usage.exr --set '$1' crowd.rib"
	expect_no_crash
	expect_status 2
	expect_stderr "^relight render: --set needs LIGHT.PARAM=V\[,V,...\] with up to 16 numbers, or LIGHT.PARAM=TEXT for a string, not '"
	checks=$((checks + 1))
	[ ! -e "$work/crowd/usage.exr" ] || fail "an image was written"
}

bad_usage 3.intensity
bad_usage 3intensity=1
bad_usage .intensity=1
bad_usage 3.=1
bad_usage 3.intensity=1,
bad_usage 3.intensity=1,,2
bad_usage 3.intensity=1x
bad_usage 3.intensity=1e99
bad_usage "3.xf=$(seq -s, 1 17)"

run "usage: --set without its argument" "$relight" render crowd.rib --set
expect_status 2
expect_stderr "option '--set' needs an argument"

many=()
for i in $(seq 1 65); do
	many+=(--set 3.intensity=$i)
done
run "usage: 65 edits" "$relight" render -q "${many[@]}" "$work/crowd/crowd.rib"
expect_status 2
expect_stderr "at most 64 --set edits"

# The preview parses --set with the same code and says the same.
run "preview: --set malformed" "$relight" preview --cpu --set 3.intensity=1, x.shot.exr
expect_status 2
expect_stderr "^relight preview: --set needs LIGHT.PARAM=V\[,V,...\] with up to 16 numbers, or LIGHT.PARAM=TEXT for a string, not '3.intensity=1,'"

finish
