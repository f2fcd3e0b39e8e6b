"""What a write killed mid-way leaves (TARGET.tmp.PID.SUFFIX, the temporary
files of atomic writes) is removed at the next start of relightd, in the
shots and snapshots folders, and by `relight bake` beside the shot it
writes; nothing else is.

Checks:
  - relightd's start removes the temporary files of a writer that is gone
    from the shots folder and the snapshots folder;
  - it keeps: a temporary file of a live process (this test's pid), files
    of other names (notes.tmp.txt, a name with no pid, scene.rib, shot
    files), a link and a folder of the temporary pattern, and what is in a
    subfolder;
  - `relight bake scene.rib` removes the stale temporary files of
    scene.shot.exr and keeps those of other shots and of live writers.
"""

import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

C = harness.Checks("tempfiles")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)


def dead_pid():
    p = subprocess.Popen(["true"])
    p.wait()
    return p.pid


def touch(path, size=1000):
    with open(path, "wb") as f:
        f.write(b"x" * size)


def daemon_start(tmp):
    C.section = "relightd"
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd"):
        shutil.copyfile(os.path.join(shots, f), os.path.join(own, f))
    dead, live = dead_pid(), os.getpid()
    stale = ["shadows.shot.exr.tmp.%d.Ab12Cd" % dead, "x.shot.exr.tmp.%d.000001" % dead,
             "x.shot.exr.tmp.%d.1.tmp.%d.QwErTy" % (dead, dead)]
    kept = ["shadows.shot.exr.tmp.%d.Zz99Yy" % live, "notes.tmp.txt", "a.exr.tmp.ABCDEF",
            "shadows.shot.exr", "key.shd", "b.exr.tmp.%d.ab-cd" % dead]
    for f in stale + kept[:3] + kept[5:]:
        touch(os.path.join(own, f), 200000)
    os.symlink("shadows.shot.exr", os.path.join(own, "link.exr.tmp.%d.LinkLn" % dead))
    os.mkdir(os.path.join(own, "dir.exr.tmp.%d.DirDir" % dead))
    os.mkdir(os.path.join(own, "sub"))
    touch(os.path.join(own, "sub", "c.exr.tmp.%d.SubSub" % dead))
    kept += ["link.exr.tmp.%d.LinkLn" % dead, "dir.exr.tmp.%d.DirDir" % dead, "sub"]
    snaps = os.path.join(tmp, "snaps")
    os.mkdir(snaps)
    snap_stale = "shadows-edit3-1.exr.tmp.%d.SnApSh" % dead
    snap_kept = ["shadows-edit2-1.exr", "shadows-edit4-1.exr.tmp.%d.LiVeLv" % live]
    for f in [snap_stale] + snap_kept:
        touch(os.path.join(snaps, f))

    d = harness.Daemon(relightd, own, ["--snapshots", snaps])
    left = set(os.listdir(own))
    for f in stale:
        C.check(f not in left, "the stale %s is removed from the shots folder" % f)
    for f in kept:
        C.check(f in left, "%s stays in the shots folder" % f)
    C.check(os.path.exists(os.path.join(own, "sub", "c.exr.tmp.%d.SubSub" % dead)),
            "a subfolder is not looked into")
    left = set(os.listdir(snaps))
    C.check(snap_stale not in left, "the stale snapshot temporary is removed")
    for f in snap_kept:
        C.check(f in left, "%s stays in the snapshots folder" % f)
    c = d.client(timeout=60)
    C.check(c.open("shadows", "rgba8")["width"] > 0, "the daemon serves its shots")
    c.disconnect()
    d.finish(C)


def bake(tmp):
    C.section = "bake"
    work = os.path.join(tmp, "bake")
    os.mkdir(work)
    src = os.path.join(harness.SOURCE_DIR, "examples", "shadows")
    for f in os.listdir(src):
        p = os.path.join(src, f)
        if os.path.isfile(p):
            shutil.copyfile(p, os.path.join(work, f))
    dead, live = dead_pid(), os.getpid()
    stale = "shadows.shot.exr.tmp.%d.StAlE1" % dead
    kept = ["other.shot.exr.tmp.%d.OtHeR1" % dead, "shadows.shot.exr.tmp.%d.LiVe11" % live,
            "shadows.shot.exr.old"]
    for f in [stale] + kept:
        touch(os.path.join(work, f))
    r = subprocess.run([relight_exe, "bake", "-q", "shadows.rib"], cwd=work,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300)
    C.equal(r.returncode, 0, "relight bake succeeds", )
    left = set(os.listdir(work))
    C.check("shadows.shot.exr" in left, "the shot file is written")
    C.check(stale not in left, "the bake removes its shot's stale temporary file")
    for f in kept:
        C.check(f in left, "%s stays" % f)


def main():
    tmp = tempfile.mkdtemp(prefix="tempfiles-", dir=harness.build_dir())
    C.run(daemon_start, tmp)
    C.run(bake, tmp)
    C.finish()


if __name__ == "__main__":
    main()
