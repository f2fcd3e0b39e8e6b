"""relightd with its snapshots folder on a full disk.

The script mounts a 64 KiB tmpfs, fills it, and gives it to relightd as its
--snapshots folder. Checks:
  - a snapshot request gets an error reply in time (a failed OpenEXR write
    once hung the render worker for ever), and no temporary file is left;
  - the daemon serves on: another connection opens the shot, edits a light
    and gets the edit's final level, and a second snapshot fails the same way;
  - relightd exits with status 0 on SIGTERM.
Skips (77) when the tmpfs cannot be mounted (not root) or relightd cannot get
an EGL context.
"""

import os
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("diskfull")
relightd, relight_exe = harness.args()
# Seconds a reply may take: a failed write is an error at once.
WAIT = 20


def leftovers(folder):
    return sorted(n for n in os.listdir(folder) if n != "filler")


def snapshot_fails(c, what):
    try:
        path = c.snapshot()
        C.check(False, what + ": an error reply", "wrote %r" % path)
    except relight.ServerError as e:
        C.check(bool(e.message), what + ": an error reply with a message", repr(e))
        C.note("%s: %s: %s" % (what, e.code, e.message))
    except relight.Error as e:
        C.check(False, what + ": an error reply in time", repr(e))


def main(full):
    shots = harness.bake_shots(relight_exe)
    # Fill the tmpfs: every write to it fails with ENOSPC.
    subprocess.run(["dd", "if=/dev/zero", "of=" + os.path.join(full, "filler"), "bs=4096"],
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        with open(os.path.join(full, "probe"), "wb") as f:
            f.write(b"x")
        C.check(False, "the tmpfs is full")
    except OSError:
        pass
    if os.path.exists(os.path.join(full, "probe")):
        os.unlink(os.path.join(full, "probe"))
    d = harness.Daemon(relightd, shots, extra=["--snapshots", full])
    try:
        C.section = "snapshot to a full disk"
        c = d.client(timeout=WAIT)
        c.open("shadows")
        snapshot_fails(c, "first snapshot")
        C.equal(leftovers(full), [], "no temporary file left on the full disk")

        C.section = "serving on"
        o = d.client(timeout=WAIT)
        try:
            o.open("shadows")
            edit = o.set("3", intensity=3)
            img = o.wait(edit, timeout=WAIT)
            C.check(img is not None and img.width > 0, "another connection's edit reaches "
                    "its final level")
            C.equal(o.stats().get("op"), "stats", "stats answered")
        except relight.Error as e:
            C.check(False, "another connection is served", repr(e))
        snapshot_fails(o, "second snapshot")
        C.equal(leftovers(full), [], "still no temporary file left")
        o.disconnect()
        c.disconnect()
    finally:
        d.finish(C)


def run():
    os.makedirs(harness.build_dir(), exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="relight-diskfull-",
                                     dir=harness.build_dir()) as tmp:
        full = os.path.join(tmp, "snapshots")
        os.mkdir(full)
        r = subprocess.run(["mount", "-t", "tmpfs", "-o", "size=64k", "tmpfs", full],
                           stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
        if r.returncode != 0:
            harness.skip("cannot mount a tmpfs at %s: %s"
                         % (full, r.stdout.decode(errors="replace").strip()[:300]))
        try:
            C.run(main, full)
        finally:
            if subprocess.run(["umount", full]).returncode != 0:
                subprocess.run(["umount", "-l", full])
    C.finish()


if __name__ == "__main__":
    run()
