#!/usr/bin/env bash
# The writers on a full disk: `relight render -o`, `relight preview -o` and
# `relight bake` into a 64 KiB tmpfs that this script mounts and fills, so
# that the first write (the OpenEXR header) fails. Each must end promptly
# (a failed write once hung the OpenEXR writer for ever) with exit status 1,
# a message naming the file and the reason, and no temporary file left.
# Needs to mount a tmpfs (root): otherwise it skips (exit 77).
source "$(dirname "$0")/lib.sh"

# A failed write is an error at once, not after a long wait.
limit=${RELIGHT_CLI_TIMEOUT:-30}

full="$work/full"
mkdir -p "$full"
if ! mount -t tmpfs -o size=64k tmpfs "$full" 2>"$work/mount.err"; then
	echo "SKIP: cannot mount a tmpfs at $full: $(head -c 300 "$work/mount.err")"
	exit 77
fi
cleanup() {
	umount "$full" 2>/dev/null || umount -l "$full" 2>/dev/null
	rm -rf "$work"
}
trap cleanup EXIT

cat >"$work/small.rib" <<'RIB'
Format 32 24 1
PixelSamples 2 2
Display "small.exr" "file" "rgba"
WorldBegin
  LightSource "distantlight" 1
  Surface "matte"
  Translate 0 0 5
  Sphere 1 -1 1 360
WorldEnd
RIB

# A shot to preview, baked where there is room.
run "bake where there is room" bash -c "cd '$work' && '$relight' bake -q small.rib"
expect_status 0

# Fill the tmpfs: every later write to it fails with ENOSPC.
dd if=/dev/zero of="$full/filler" bs=4096 >/dev/null 2>&1
checks=$((checks + 1))
what="fill the tmpfs"
if dd if=/dev/zero of="$full/probe" bs=1 count=1 >/dev/null 2>&1 && [ -s "$full/probe" ]; then
	fail "the tmpfs is not full"
fi
rm -f "$full/probe"

# no_temporary NAME: no NAME.tmp.* was left in the full folder.
no_temporary() {
	checks=$((checks + 1))
	local left
	left=$(cd "$full" && ls -A | grep -v '^filler$')
	[ -z "$left" ] || fail "files left on the full disk: $left"
}

run "render -o to a full disk" "$relight" render -q -o "$full/out.exr" "$work/small.rib"
expect_no_crash
expect_status 1
expect_stderr "$full/out.exr: error: cannot write: No space left on device"
no_temporary out.exr

run "preview -o to a full disk" "$relight" preview -q --cpu -o "$full/prev.exr" \
	"$work/small.shot.exr"
expect_no_crash
expect_status 1
expect_stderr "$full/prev.exr: .*No space left on device"
no_temporary prev.exr

run "bake to a full disk" "$relight" bake -q -o "$full/small.shot.exr" "$work/small.rib"
expect_no_crash
expect_status 1
expect_stderr "$full/small.shot.exr: .*No space left on device"
no_temporary small.shot.exr

# The same writers still work where there is room, after the failures.
run "render -o where there is room" "$relight" render -q -o "$work/out.exr" "$work/small.rib"
expect_status 0
expect_true "the image was written" test -s "$work/out.exr"

finish
