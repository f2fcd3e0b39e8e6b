#!/usr/bin/env bash
# Shader lookup as prman does it: a shader found by the name it declares
# when no file has that name (the file of that name wins when both exist),
# #include along the shader's folder, -I and Option "searchpath" "include",
# $RMAN_SHADERPATH after $RELIGHT_SHADER_PATH, and the built-in "null".
# Each image is compared with the one of a plainly written reference scene.
source "$(dirname "$0")/lib.sh"

cd "$work" || exit 1
unset RELIGHT_SHADER_PATH RMAN_SHADERPATH
mkdir -p named byfile inc incdir owndir env1 env2 ref

# scene NAME SURFACE [OPTIONS]: a square filling a 16x16 frame, written to NAME.exr.
scene() {
	cat >"$1.rib" <<RIB
$3
Format 16 16 1
PixelSamples 1 1
Display "$1.exr" "file" "rgba"
Projection "orthographic"
WorldBegin
  Color [0.25 0.5 0.75]
  $2
  Polygon "P" [-2 -2 1  2 -2 1  2 2 1  -2 2 1]
WorldEnd
RIB
}

# same A B: the images A.exr and B.exr are equal in colour and alpha. A.exr
# is removed after, so that the next comparison sees a fresh render.
same() {
	run "$1 = $2" "$relight" diff --json "$1.exr" "$2.exr"
	rm -f "$1.exr"
	checks=$((checks + 1))
	if ! python3 -c '
import json, sys
try:
    d = json.load(sys.stdin)
except ValueError:
    sys.exit(1)
sys.exit(0 if d["max_pct"] == 0 and (d["alpha"] is None or d["alpha"]["max_pct"] == 0) else 1)
' <"$work/stdout"; then
		fail "the images differ or one is missing: $(head -c 400 "$work/stdout")"
	fi
}

# render_ok NAME [ENV...]: relight render NAME.rib succeeds.
render_ok() {
	local name=$1
	shift
	run "render $name" env "$@" "$relight" render -q "$name.rib"
	expect_no_crash
	expect_status 0
}

# References: constant colours.
for c in "red 1 0 0" "green 0 1 0" "blue 0 0 1" "grey 0.5 0.5 0.5"; do
	set -- $c
	echo "surface ref_$1() { Oi = Os; Ci = Os * color($2, $3, $4); }" >"ref/ref_$1.sl"
	scene "ref_$1" "Surface \"ref_$1\"" 'Option "searchpath" "shader" ["ref:@"]'
	render_ok "ref_$1"
done
# A null surface leaves Ci and Oi as they start: black, opaque.
echo 'surface ref_black() { Ci = 0; Oi = 1; }' >ref/ref_black.sl
scene ref_black 'Surface "ref_black"' 'Option "searchpath" "shader" ["ref:@"]'
render_ok ref_black

# 1. A shader found by its declared name (file plastic.sl, shader RCPlastic).
cat >named/plastic.sl <<'SL'
/* surface decoy() in a comment, and a string: "surface decoy2(" */
#define NOT_A_SHADER surface decoy3(
surface RCPlastic(float Kd = 1; string s = "light x(")
{
	Oi = Os;
	Ci = Os * color(1, 0, 0);
}
SL
scene named 'Surface "RCPlastic"' 'Option "searchpath" "shader" ["named:@"]'
render_ok named
same named ref_red
run "declared name twice" "$relight" render -q named.rib
expect_status 0
scene decoy 'Surface "decoy"' 'Option "searchpath" "shader" ["named:@"]'
run "a name in a comment is no shader" "$relight" render -q decoy.rib
expect_status 1
expect_stderr "decoy.rib:[0-9]+: error: cannot find shader 'decoy'"

# 2. The file of the name wins over a file that declares the name.
cat >byfile/aaa.sl <<'SL'
surface RCPlastic() { Oi = Os; Ci = Os * color(1, 0, 0); }
SL
cat >byfile/RCPlastic.sl <<'SL'
surface RCPlastic() { Oi = Os; Ci = Os * color(0, 1, 0); }
SL
scene byfile 'Surface "RCPlastic"' 'Option "searchpath" "shader" ["byfile:@"]'
render_ok byfile
same byfile ref_green
# ... and an earlier folder's declared name over a later folder's.
scene order 'Surface "RCPlastic"' 'Option "searchpath" "shader" ["named:byfile:@"]'
render_ok order
same order ref_green

# 3. #include: the shader's own folder first, then -I, or Option "searchpath" "include".
cat >inc/incshader.sl <<'SL'
#include "col.h"
surface incshader() { Oi = Os; Ci = Os * COL; }
SL
echo '#define COL color(0, 0, 1)' >incdir/col.h
scene incl 'Surface "incshader"' 'Option "searchpath" "shader" ["inc:@"]'
run "no include folder" "$relight" render -q incl.rib
expect_status 1
expect_stderr "cannot find include file 'col.h'"
run "render -I" "$relight" render -q -I incdir incl.rib
expect_no_crash
expect_status 0
same incl ref_blue
run "render --include, twice" "$relight" render -q --include owndir --include incdir incl.rib
expect_status 0
same incl ref_blue
run "bake -I" "$relight" bake -q -I incdir -o incl.shot.exr incl.rib
expect_no_crash
expect_status 0
run "bake without -I" "$relight" bake -q -o incl2.shot.exr incl.rib
expect_status 1
expect_stderr "cannot find include file 'col.h'"
run "bad -I" "$relight" render -q -I a:b incl.rib
expect_status 2
expect_stderr "-I needs a folder without ':'"
scene incopt 'Surface "incshader"' \
	$'Option "searchpath" "shader" ["inc:@"]\nOption "searchpath" "include" ["owndir:'"$work"'/incdir"]'
render_ok incopt
same incopt ref_blue
# '@' in the include path is the -I folders.
scene incat 'Surface "incshader"' \
	$'Option "searchpath" "shader" ["inc:@"]\nOption "searchpath" "include" ["owndir:@"]'
run "include path with @" "$relight" render -q -I incdir incat.rib
expect_status 0
same incat ref_blue
# The shader's own folder comes before -I.
echo '#define COL color(0.5, 0.5, 0.5)' >owndir/col.h
cp inc/incshader.sl owndir/ownshader.sl
sed -i 's/incshader/ownshader/' owndir/ownshader.sl
scene own 'Surface "ownshader"' 'Option "searchpath" "shader" ["owndir:@"]'
run "own folder first" "$relight" render -q -I incdir own.rib
expect_status 0
same own ref_grey

# 4. $RMAN_SHADERPATH beside $RELIGHT_SHADER_PATH, which comes first.
echo 'surface envshader() { Oi = Os; Ci = Os * color(1, 0, 0); }' >env1/envshader.sl
echo 'surface envshader() { Oi = Os; Ci = Os * color(0, 1, 0); }' >env2/envshader.sl
scene env 'Surface "envshader"' ''
render_ok env RMAN_SHADERPATH="$work/env2"
same env ref_green
render_ok env RMAN_SHADERPATH="$work/env2" RELIGHT_SHADER_PATH="$work/env1"
same env ref_red
run "bake with RMAN_SHADERPATH" env RMAN_SHADERPATH="$work/env2" "$relight" bake -q \
	-o env.shot.exr env.rib
expect_status 0
run "no path" "$relight" render -q env.rib
expect_status 1
expect_stderr "cannot find shader 'envshader'"
# relight compile finds a bare name along $RMAN_SHADERPATH too, and the
# preview finds a shot's shader there once it is neither where the bake
# read it nor beside the shot.
run "compile along RMAN_SHADERPATH" env RMAN_SHADERPATH="$work/env2" "$relight" compile envshader
expect_status 0
run "compile, no path" "$relight" compile envshader
expect_status 1
mkdir -p moved
mv env2/envshader.sl moved/
run "preview along RMAN_SHADERPATH" env RMAN_SHADERPATH="$work/moved" "$relight" preview --cpu \
	-o envp.exr env.shot.exr
expect_status 0
run "preview, no path" "$relight" preview --cpu -o envq.exr env.shot.exr
expect_status 1
expect_stderr "RMAN_SHADERPATH"
mv moved/envshader.sl env2/

# 5. The built-in null shader: accepted for each kind; does nothing.
scene null $'LightSource "null" 1\n  Displacement "null"\n  Surface "null"' ''
render_ok null
same null ref_black
run "bake null" "$relight" bake -q -o null.shot.exr null.rib
expect_status 0
# The preview of a shot baked with null shaders and a light found by its
# declared name finds their sources, and matches the render.
echo 'light MyLight(float intensity = 1) { illuminate(point(0, 0, 0)) { Cl = intensity; } }' \
	>named/lights.sl
cat >pv.rib <<'RIB'
Option "searchpath" "shader" ["named:@"]
Format 16 16 1
PixelSamples 1 1
Display "pv.exr" "file" "rgba"
Projection "perspective" "fov" 40
Translate 0 0 5
WorldBegin
  LightSource "MyLight" 1
  LightSource "null" 2
  Surface "matte"
  Sphere 1 -1 1 360
  Translate 0.8 0 -1
  Surface "null"
  Sphere 0.5 -0.5 0.5 360
WorldEnd
RIB
render_ok pv
run "bake pv" "$relight" bake -q -o pv.shot.exr pv.rib
expect_status 0
run "preview pv" "$relight" preview --cpu -o pvp.exr pv.shot.exr
expect_no_crash
expect_status 0
run "preview = render" "$relight" diff --fail-above 1 pv.exr pvp.exr
expect_status 0

# A file null.sl along the path wins over the built-in one.
cp ref/ref_red.sl ref/null.sl
sed -i 's/ref_red/null/' ref/null.sl
scene nullfile 'Surface "null"' 'Option "searchpath" "shader" ["ref:@"]'
render_ok nullfile
same nullfile ref_red

finish
