#!/usr/bin/env bash
# Procedural: DelayedReadArchive, RunProgram and DynamicLoad.
#
#  - An archive whose bound is in view renders as ReadArchive would render it
#    (the image is identical to the scene with the archive's requests written
#    in place); one whose bound is out of view is never opened (a missing
#    file there says nothing), unless a light reading a shadow map came
#    first; a shadow light after an unread archive is a warning at its line;
#    a missing archive in view is an error at the Procedural's line and the
#    rest renders.
#  - RunProgram's helper renders its RIB in the current state (identical to
#    the requests in place); a helper that exits 1 before writing, one that
#    writes what is not RIB, one that never ends (killed after
#    RELIGHT_RUNPROGRAM_TIMEOUT=2 s) and one that cannot be run are errors at
#    the Procedural's line, and the rest of the frame renders.
#  - DynamicLoad is a warning ("relight loads no foreign code"), an error
#    with --strict.
source "$(dirname "$0")/lib.sh"

cd "$work" || exit 1
identical() {
	"$relight" diff "$1" "$2" >diff.txt 2>&1 &&
		grep -qE '^  PSNR \(sRGB\) +identical' diff.txt &&
		grep -qE '^  alpha +RMSE 0,' diff.txt
}

cat >ball.rib <<'RIB'
AttributeBegin
  Color [0.2 0.9 0.3]
  Sphere 0.8 -0.8 0.8 360
AttributeEnd
RIB
cat >ok.sh <<'SH'
#!/bin/sh
read detail data || exit 2
echo "# asked for detail $detail"
echo "Translate $data 0 0"
echo "Sphere 0.5 -0.5 0.5 360"
printf '\377'
SH
cat >dead.sh <<'SH'
#!/bin/sh
exit 1
SH
cat >garbage.sh <<'SH'
#!/bin/sh
read detail data
echo 'Sphere 0.5 "oops" [1 2'
printf '\377'
SH
cat >hang.sh <<'SH'
#!/bin/sh
exec sleep 100
SH
chmod +x ok.sh dead.sh garbage.sh hang.sh

head='Format 96 64 1
PixelSamples 4 4
Projection "perspective" "fov" 40
WorldBegin
  LightSource "distantlight" 1
  Surface "matte"
  Translate 0 0 6'

# ---- DelayedReadArchive ----
cat >delayed.rib <<RIB
$head
  Procedural "DelayedReadArchive" ["ball.rib"] [-0.8 0.8 -0.8 0.8 -0.8 0.8]
  Procedural "DelayedReadArchive" ["not-there.rib"] [40 41 -1 1 -1 1]
  Procedural "DelayedReadArchive" ["not-there-either.rib"] [-1 1 -1 1 -30 -20]
WorldEnd
RIB
cat >inplace.rib <<RIB
$head
  AttributeBegin
    Color [0.2 0.9 0.3]
    Sphere 0.8 -0.8 0.8 360
  AttributeEnd
WorldEnd
RIB
run "DelayedReadArchive" "$relight" render -o delayed.exr delayed.rib
expect_status 0
expect_stderr "0 warnings \(0 repeats not shown\), 0 errors$"
run "in place" "$relight" render -q -o inplace.exr inplace.rib
expect_status 0
expect_true "the archive renders as its requests in place" identical inplace.exr delayed.exr

sed -e 's/^  Translate 0 0 6$/  Translate 0 0 6\n  Procedural "DelayedReadArchive" ["absent.rib"] [-1 1 -1 1 -1 1]/' \
	delayed.rib >missing.rib
run "DelayedReadArchive of a missing file in view" "$relight" render -o missing.exr missing.rib
expect_status 1
expect_no_crash
expect_stderr "^missing.rib:8: error: cannot find archive 'absent.rib'"
expect_stderr "1 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 1 error, 1 primitive dropped$"
expect_true "the rest rendered" identical inplace.exr missing.exr

# a light reading a shadow map makes every archive count
sed -e 's/^  LightSource "distantlight" 1$/  LightSource "shadowspot" 1 "shadowname" "none.shd"/' \
	delayed.rib >shadowed.rib
run "DelayedReadArchive with a shadow light" "$relight" render -o shadowed.exr shadowed.rib
expect_stderr "^shadowed.rib:9: error: cannot find archive 'not-there.rib'"
sed -e '/^  LightSource "distantlight" 1$/d' -e 's/^WorldEnd$/  LightSource "shadowspot" 1 "shadowname" "none.shd"\nWorldEnd/' \
	delayed.rib >late.rib
run "a shadow light after an unread archive" "$relight" render -o late.exr late.rib
expect_stderr "^late.rib:10: warning: this light reads a shadow map, but 2 DelayedReadArchive out of view before it were not read"

# ---- RunProgram ----
cat >run.rib <<RIB
$head
  Procedural "DelayedReadArchive" ["ball.rib"] [-0.8 0.8 -0.8 0.8 -0.8 0.8]
  Procedural "RunProgram" ["./ok.sh" "1.5"] [1 2 -0.5 0.5 -0.5 0.5]
WorldEnd
RIB
cat >runplace.rib <<RIB
$head
  Procedural "DelayedReadArchive" ["ball.rib"] [-0.8 0.8 -0.8 0.8 -0.8 0.8]
  AttributeBegin
    Translate 1.5 0 0
    Sphere 0.5 -0.5 0.5 360
  AttributeEnd
WorldEnd
RIB
run "RunProgram" "$relight" render -o run.exr run.rib
expect_status 0
expect_stderr "0 warnings \(0 repeats not shown\), 0 errors$"
run "its requests in place" "$relight" render -q -o runplace.exr runplace.rib
expect_true "the program's RIB renders as its requests in place" identical runplace.exr run.exr

for bad in dead garbage hang nosuch; do
	sed -e "s|\./ok.sh|./$bad.sh|" run.rib >$bad.rib
	start=$(date +%s)
	run "RunProgram $bad" env RELIGHT_RUNPROGRAM_TIMEOUT=2 "$relight" render -o $bad.exr $bad.rib
	took=$(( $(date +%s) - start ))
	expect_status 1
	expect_no_crash
	expect_stderr "1 of 1 frame rendered, 0 warnings \(0 repeats not shown\), 1 error, 1 primitive dropped$"
	expect_true "$bad: the rest rendered" identical inplace.exr $bad.exr
	checks=$((checks + 1))
	[ "$took" -le 10 ] || fail "$bad took ${took}s"
done
run "dead" env RELIGHT_RUNPROGRAM_TIMEOUT=2 "$relight" render -o dead.exr dead.rib
expect_stderr "^dead.rib:9: error: RunProgram './dead.sh' exited with status 1 before it ended its output$"
run "garbage" env RELIGHT_RUNPROGRAM_TIMEOUT=2 "$relight" render -o garbage.exr garbage.rib
expect_stderr "^garbage.rib:9: error: RunProgram './garbage.sh' wrote what is not RIB \(\./garbage.sh:1: error: "
run "hang" env RELIGHT_RUNPROGRAM_TIMEOUT=2 "$relight" render -o hang.exr hang.rib
expect_stderr "^hang.rib:9: error: RunProgram './hang.sh' did not answer within 2 s: killed"
run "nosuch" env RELIGHT_RUNPROGRAM_TIMEOUT=2 "$relight" render -o nosuch.exr nosuch.rib
expect_stderr "^nosuch.rib:9: error: RunProgram './nosuch.sh' cannot be run: No such file or directory$"

# ---- DynamicLoad ----
sed -e 's|^  Procedural "RunProgram".*$|  Procedural "DynamicLoad" ["hair.so" "x"] [-1 1 -1 1 -1 1]|' run.rib >dso.rib
run "DynamicLoad" "$relight" render -o dso.exr dso.rib
expect_status 0
expect_stderr "^dso.rib:9: warning: relight loads no foreign code: DynamicLoad 'hair.so' skipped$"
expect_true "the rest rendered" identical inplace.exr dso.exr
run "DynamicLoad --strict" "$relight" render --strict -o dso.exr dso.rib
expect_status 1
expect_stderr "^dso.rib:9: error: relight loads no foreign code: DynamicLoad 'hair.so' skipped"
finish
