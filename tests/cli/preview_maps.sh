#!/usr/bin/env bash
# `relight preview` of a shot whose shadow map cannot be found: the image is
# written but it is not the shot's (its shadow() lookups give the fill), so
# the exit status is 3, with the warning naming the map and an error line
# naming the image. Beside the map the same preview exits 0. On the CPU
# always; on the GPU where there is an EGL context.
source "$(dirname "$0")/lib.sh"

# The shadows example, small: a shadow pass, MakeShadow, the lit frame.
mkdir -p "$work/bake" "$work/elsewhere"
sed -e 's/^  Format 512 512 1/  Format 64 64 1/' -e 's/^  Format 640 360 1/  Format 64 36 1/' \
	-e 's/PixelSamples 4 4/PixelSamples 1 1/' -e 's/"samples" 16/"samples" 4/' \
	"$source_dir/examples/shadows/shadows.rib" >"$work/bake/small.rib"
run "bake" bash -c "cd '$work/bake' && '$relight' bake -q small.rib"
expect_status 0
expect_true "the shadow map was made" test -s "$work/bake/key.shd"
cp "$work/bake/small.shot.exr" "$work/elsewhere/"

run "CPU preview beside the map" bash -c "cd '$work/bake' && '$relight' preview -q --cpu -o cpu.exr small.shot.exr"
expect_status 0
expect_empty_stderr

run "CPU preview without the map" bash -c "cd '$work/elsewhere' && '$relight' preview -q --cpu -o cpu.exr small.shot.exr"
expect_no_crash
expect_status 3
expect_stderr "shadow 'key.shd' not found"
expect_stderr "^relight preview: error: cpu.exr is not the shot's image: 1 shadow map or texture could not be read"
expect_true "the image is still written" test -s "$work/elsewhere/cpu.exr"

run "help says what 3 means" "$relight" preview --help
expect_stdout "3 when the image was written but is not the shot's"

run "GPU preview beside the map" bash -c "cd '$work/bake' && '$relight' preview -q -o gpu.exr small.shot.exr"
if [ "$status" -ne 0 ] && grep -q "no GPU context" "$work/stderr"; then
	echo "no EGL/OpenGL context here: the GPU half is not checked"
else
	expect_status 0
	run "GPU preview without the map" bash -c "cd '$work/elsewhere' && '$relight' preview -q -o gpu.exr small.shot.exr"
	expect_no_crash
	expect_status 3
	expect_stderr "light '2': key.shd: not found"
	expect_stderr "^relight preview: error: gpu.exr is not the shot's image"
fi

finish
