#!/usr/bin/env bash
# Memory guards and output paths of `relight render` and `relight bake`.
#
# A frame estimated to need more than the memory limit (--memory-limit; the
# default, 3/4 of the machine's or the cgroup's memory, is not used here so
# that the outcome does not depend on the machine) fails before it is diced,
# within SECONDS seconds, naming the request to change at its FILE:LINE and
# the estimate against the limit:
#   - ShadingRate 1e-6 on a sphere (about 7e9 micropolygons);
#   - Format 20000 20000 with PixelSamples 6 6 (15 GiB of images for the
#     render, 116 GiB of indirect-framebuffer entries for the bake);
#   - a 256x256 frame under a limit of 1M (its images alone take 1.5 MiB),
#     which renders under 1G.
# An output that cannot be written (a missing folder, a folder, a Display
# into a missing folder) fails before any rendering: no frame summary,
# within SECONDS seconds.
source "$(dirname "$0")/lib.sh"

seconds=10

cd "$work" || exit 1

# scene NAME "REQUEST LINES": a sphere under a distant light, displayed to NAME.exr
scene() {
	printf '%s\n' "$2" >"$1.rib"
	cat >>"$1.rib" <<EOF
Projection "perspective" "fov" 30
Display "$1.exr" "file" "rgba"
Translate 0 0 5
WorldBegin
LightSource "distantlight" 1
Surface "plastic"
Sphere 1 -1 1 360
WorldEnd
EOF
}

# timed DESCRIPTION CMD...: run, and fail when it took more than $seconds
timed() {
	local t0 t1
	t0=$(date +%s%N)
	run "$@"
	t1=$(date +%s%N)
	elapsed_ms=$(((t1 - t0) / 1000000))
	checks=$((checks + 1))
	[ "$elapsed_ms" -le $((seconds * 1000)) ] || fail "took ${elapsed_ms} ms, over ${seconds} s"
}

scene rate 'Format 64 64 1
ShadingRate 1e-6'
for cmd in render bake; do
	timed "ShadingRate 1e-6, $cmd" "$relight" "$cmd" -q --memory-limit 16G rate.rib
	expect_status 1
	expect_stderr '^rate\.rib:2: error: ShadingRate 1e-06 asks for about [0-9.e+]+ micropolygons \([0-9.]+ GiB .*over the memory limit of 16\.0 GiB .*raise the ShadingRate'
	echo "ShadingRate 1e-6, $cmd: ${elapsed_ms} ms: $(head -1 "$work/stderr")"
done

scene big 'Format 20000 20000 1
PixelSamples 6 6'
timed "Format 20000 20000, render" "$relight" render -q --memory-limit 8G big.rib
expect_status 1
expect_stderr '^big\.rib:1: error: Format 20000 20000 with PixelSamples 6 6 \(big\.rib:2\) needs about 14\.9 GiB .*over the memory limit of 8\.0 GiB .*lower the Format or the PixelSamples'
echo "Format 20000 20000, render: ${elapsed_ms} ms: $(head -1 "$work/stderr")"
timed "Format 20000 20000, bake" "$relight" bake -q --memory-limit 16G big.rib
expect_status 1
expect_stderr '^big\.rib:1: error: Format 20000 20000 with PixelSamples 6 6 \(big\.rib:2\) needs about 116\.2 GiB .*over the memory limit of 16\.0 GiB'
echo "Format 20000 20000, bake: ${elapsed_ms} ms: $(head -1 "$work/stderr")"

scene small 'Format 256 256 1'
run "limit below the frame's need" "$relight" render -q --memory-limit 1M small.rib
expect_status 1
expect_stderr '^small\.rib:1: error: Format 256 256 with PixelSamples 2 2 needs about [0-9.]+ MiB .*over the memory limit of 1\.0 MiB'
run "limit above the frame's need" "$relight" render -q --memory-limit 1G small.rib
expect_status 0
expect_true "the image is written" test -s small.exr
run "bake under a limit above its need" "$relight" bake -q --memory-limit 1G small.rib
expect_status 0
for bad in 12Q 0 -1G G 1.5.3M; do
	run "--memory-limit $bad" "$relight" render -q --memory-limit "$bad" small.rib
	expect_status 2
	expect_stderr "memory-limit needs a size"
done

# Outputs that cannot be written: refused before rendering. The scene takes
# seconds to render on one thread (3.2 s on the reference machine); a refusal
# takes milliseconds, so one within a second came before the rendering.
refuse_ms=1000
scene slow 'Format 512 512 1
PixelSamples 8 8
ShadingRate 0.25'
# refused OUTPUT-MESSAGE-REGEX DESCRIPTION CMD...
refused() {
	local re=$1
	shift
	timed "$@"
	expect_status 1
	expect_stderr "$re"
	checks=$((checks + 1))
	[ "$elapsed_ms" -le "$refuse_ms" ] ||
		fail "refused after ${elapsed_ms} ms: the frame was rendered first"
	grep -qE '^frame 1:' "$work/stderr" && fail "a frame was rendered before the refusal"
	echo "$1: refused in ${elapsed_ms} ms"
}
mkdir -p folder.exr
refused "cannot write 'missing/out.exr': the folder 'missing' does not exist" \
	"render -o into a missing folder" "$relight" render -t 1 -o missing/out.exr slow.rib
refused "cannot write 'folder.exr': it is a folder" \
	"render -o a folder" "$relight" render -t 1 -o folder.exr slow.rib
sed 's|Display "slow.exr"|Display "nowhere/lost.exr"|' slow.rib >lost.rib
refused "^lost\.rib:5: error: cannot write 'nowhere/lost.exr': the folder 'nowhere' does not exist" \
	"Display into a missing folder" "$relight" render -t 1 lost.rib
# a framebuffer display is skipped (a warning), whatever its name
sed 's|Display "small.exr" "file"|Display "nowhere/fb" "framebuffer"|' small.rib >fb.rib
run "a skipped framebuffer display is not an output" "$relight" render -q fb.rib
expect_status 0
expect_stderr "framebuffer.*skipped"
refused "^relight bake: error: cannot write 'missing/x.shot.exr': the folder 'missing' does not exist" \
	"bake -o into a missing folder" "$relight" bake -t 1 -o missing/x.shot.exr slow.rib

finish
