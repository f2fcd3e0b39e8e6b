#!/usr/bin/env bash
# What `relight render` writes, planned before the first frame renders:
#   - with -o and several frames, each frame's image is numbered (out.0001.exr
#     from FrameBegin's number), or numbered by a '#' run or %0Nd in the name;
#   - with -o, the other image displays (AOVs) are named after it
#     (crop.N.exr), never written over the scene's own files (--crop too);
#   - two outputs naming one file (two Displays of a frame, or two frames)
#     are refused with FILE:LINE before anything is rendered, the old file
#     left as it was;
#   - a Display or -o name relight cannot write (tiff, .jpg) is refused with
#     the list of what it writes; .png is written as PNG; a framebuffer
#     display is skipped with a FILE:LINE warning;
#   - --set naming a light the scene lacks is refused before rendering.
source "$(dirname "$0")/lib.sh"

cd "$work" || exit 1

# rib FILE BODY: a 16x16 scene around BODY (options before WorldBegin go in BODY's frame).
world='WorldBegin
  LightSource "distantlight" 1
  Surface "matte"
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd'

# sentinel FILE: an old file whose content the run must keep.
sentinel() {
	printf 'old work\n' >"$1"
}
expect_kept() {
	checks=$((checks + 1))
	printf 'old work\n' | cmp -s - "$1" || fail "$1 was overwritten or removed"
}
expect_file() {
	checks=$((checks + 1))
	[ -s "$1" ] || fail "$1 was not written"
}
expect_absent() {
	checks=$((checks + 1))
	[ ! -e "$1" ] || fail "$1 was written"
}
# expect_magic FILE HEX: the file starts with those bytes.
expect_magic() {
	checks=$((checks + 1))
	[ "$(head -c $((${#2} / 2)) "$1" 2>/dev/null | od -An -tx1 | tr -d ' \n')" = "$2" ] ||
		fail "$1 does not start with $2"
}
EXR=762f3101
PNG=89504e470d0a1a0a

# ---- frames ----
cat >two.rib <<RIB
Format 16 16 1
FrameBegin 1
  Display "f1.exr" "file" "rgba"
  $world
FrameEnd
FrameBegin 2
  Display "f2.exr" "file" "rgba"
  $world
FrameEnd
RIB
sentinel out.exr
run "-o with two frames" "$relight" render -q -o out.exr two.rib
expect_status 0
expect_file out.0001.exr
expect_file out.0002.exr
expect_magic out.0002.exr $EXR
expect_kept out.exr
expect_absent f1.exr

run "-o with a # pattern" "$relight" render -q -o 'pat.##.exr' two.rib
expect_status 0
expect_file pat.01.exr
expect_file pat.02.exr

run "-o with a %03d pattern" "$relight" render -q -o 'p%03d.exr' two.rib
expect_status 0
expect_file p001.exr
expect_file p002.exr

# FrameBegin's number names the file, not the frame's place.
sed 's/FrameBegin 1/FrameBegin 41/; s/FrameBegin 2/FrameBegin 42/' two.rib >num.rib
run "-o numbers frames by FrameBegin" "$relight" render -q -o num.exr num.rib
expect_status 0
expect_file num.0041.exr
expect_file num.0042.exr

# A pattern with one frame: numbered too.
printf 'Format 16 16 1\nFrameBegin 7\n%s\nFrameEnd\n' "$world" >one.rib
run "-o pattern, one frame" "$relight" render -q -o 'one.####.exr' one.rib
expect_status 0
expect_file one.0007.exr

# An error found only when rendering (MakeShadow of a missing depth map, not
# run by the first read) holds back its frame; the next frame keeps its name.
cat >late.rib <<RIB
Format 16 16 1
FrameBegin 1
  MakeShadow "nothere.z" "nothere.shd"
  $world
FrameEnd
FrameBegin 2
  $world
FrameEnd
RIB
run "an error found when rendering" "$relight" render -q -o late.exr late.rib
expect_no_crash
expect_status 1
expect_stderr "^late.rib:3: error: MakeShadow 'nothere.z' -> 'nothere.shd' failed"
expect_absent late.0001.exr
expect_file late.0002.exr

# Two frames of the same number with -o: refused.
sed 's/FrameBegin 2/FrameBegin 1/' two.rib >same.rib
run "-o with two frames numbered alike" "$relight" render -q -o same.exr same.rib
expect_status 1
expect_stderr "frames 1 and 1 would both write same.0001.exr"
expect_absent same.0001.exr

# Two frames naming the same display file: refused before rendering.
sed 's/f2.exr/f1.exr/' two.rib >clash.rib
sentinel f1.exr
run "two frames, one file" "$relight" render -q clash.rib
expect_no_crash
expect_status 1
expect_stderr '^clash.rib:12: error: Display "f1.exr" of frame 2 would write over frame 1.s \(clash.rib:3\)'
expect_kept f1.exr

# ---- displays of one frame ----
cat >dup.rib <<RIB
Format 16 16 1
Display "dup.exr" "file" "rgba"
Display "+dup.exr" "file" "N"
$world
RIB
sentinel dup.exr
run "two Displays, one file" "$relight" render -q dup.rib
expect_no_crash
expect_status 1
expect_stderr '^dup.rib:3: error: Display "dup.exr": the frame.s display at dup.rib:2 writes that file too'
expect_kept dup.exr

# -o (and --crop) name the AOV display after the image: the scene's files are kept.
cat >aov.rib <<RIB
Format 16 16 1
Display "beauty.exr" "file" "rgba"
Display "+normals.exr" "file" "N"
$world
RIB
sentinel beauty.exr
sentinel normals.exr
run "--crop -o with an AOV display" "$relight" render -q --crop 0 8 0 8 -o crop.exr aov.rib
expect_status 0
expect_file crop.exr
expect_file crop.N.exr
expect_kept beauty.exr
expect_kept normals.exr
sed 's/^  Display "f\([12]\).exr" "file" "rgba"$/  Display "b\1.exr" "file" "rgba"\n  Display "+n\1.exr" "file" "N"/' two.rib >anim.rib
run "-o with an AOV display and two frames" "$relight" render -q -o anim.exr anim.rib
expect_status 0
expect_file anim.0001.exr
expect_file anim.N.0001.exr
expect_file anim.N.0002.exr
expect_absent n1.exr

# ---- formats ----
printf 'Format 16 16 1\nDisplay "t.tif" "tiff" "rgba"\n%s\n' "$world" >tiff.rib
run "Display type tiff" "$relight" render -q tiff.rib
expect_no_crash
expect_status 1
expect_stderr '^tiff.rib:2: error: Display "t.tif" "tiff": type .tiff. cannot be written; relight writes Display types "file"'
expect_absent t.tif

printf 'Format 16 16 1\nDisplay "j.jpg" "file" "rgba"\n%s\n' "$world" >jpg.rib
run "Display name .jpg" "$relight" render -q jpg.rib
expect_status 1
expect_stderr '^jpg.rib:2: error: Display "j.jpg" "file": a file name ending in .jpg is not an image relight writes \(.exr or .png\)'
expect_absent j.jpg

run "-o .jpg" "$relight" render -q -o out.jpg one.rib
expect_status 2
expect_stderr 'relight writes OpenEXR \(.exr, or no extension\) and PNG \(.png\), not .jpg'
expect_absent out.jpg

printf 'Format 16 16 1\nDisplay "p.png" "file" "rgba"\n%s\n' "$world" >png.rib
run "Display name .png" "$relight" render -q png.rib
expect_status 0
expect_magic p.png $PNG

run "-o .png" "$relight" render -q -o o.png one.rib
expect_status 0
expect_magic o.png $PNG

printf 'Format 16 16 1\nDisplay "z.png" "png" "rgbaz"\n%s\n' "$world" >pngz.rib
run "PNG of rgbaz" "$relight" render -q pngz.rib
expect_status 1
expect_stderr "^pngz.rib:2: error: z.png: a PNG holds the mode rgba, rgb, a or one output variable, not 'rgbaz'"
expect_absent z.png

printf 'Format 16 16 1\nDisplay "fb" "framebuffer" "rgb"\n%s\n' "$world" >fb.rib
run "framebuffer display" "$relight" render fb.rib
expect_status 0
expect_stderr '^fb.rib:2: warning: Display "fb" "framebuffer": relight has no framebuffer; the display is skipped'
expect_absent fb
run "framebuffer display with -o" "$relight" render -q -o fb.exr fb.rib
expect_status 0
expect_magic fb.exr $EXR

# ---- --set ----
sentinel set.exr
run "--set of a light the scene lacks" "$relight" render -q -o set.exr --set 9.intensity=2 one.rib
expect_no_crash
expect_status 1
expect_stderr '^one.rib: error: --set 9.intensity: no LightSource with handle 9$'
expect_kept set.exr

finish
