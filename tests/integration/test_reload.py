"""A shot loaded again after its eviction is looked up again in the shots
folder, as at its first open.

Checks (--max-shots 1: a second client opening another shot evicts the
first client's):
  - a shot file that was a link inside the folder and has become a link out
    of it while the shot was evicted is not loaded again: the edit that
    needs it gets an error, and no tiles come;
  - a shot file replaced, while evicted, by a shot of another size is an
    error to the client showing it (an error event naming both sizes and the
    refused edit), which gets no tile of the other image; opened again, the
    shot shows the new size.
"""

import os
import shutil
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
import relight  # noqa: E402

C = harness.Checks("reload")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120
FINAL = 3


def evict(d, other):
    ev0 = d.metric("relight_shot_evictions_total") or 0
    b = d.client(timeout=WAIT)
    o = b.open(other, "rgba8")
    b.wait(o["edit"], FINAL)
    C.check((d.metric("relight_shot_evictions_total") or 0) >= ev0 + 1, "the shot was evicted")
    return b


def a_client():
    rec = harness.Recorder()
    events = []
    return rec, events, dict(rec.kw(), on_event=events.append)


def link_out(d, own, outside):
    C.section = "link out of the folder"
    rec, events, kw = a_client()
    a = d.client(timeout=WAIT, **kw)
    o = a.open("linked", "rgba8")
    a.wait(o["edit"], FINAL)
    light = o["lights"][0]["name"]
    b = evict(d, "lights32")
    link = os.path.join(own, "linked.shot.exr")
    os.remove(link)
    os.symlink(outside, link)
    loads0 = d.metric("relight_shot_loads_total") or 0
    rec.take()
    C.raises(lambda: a.set(light, intensity=3), None,
             "an edit of a shot whose file became a link out of the folder is refused")
    time.sleep(0.5)
    C.equal([e for e in rec.take() if e[0] == "tile"], [], "no tiles come")
    C.equal(d.metric("relight_shot_loads_total") or 0, loads0, "the file outside is not loaded")
    a.disconnect()
    b.disconnect()


def resized(d, own):
    C.section = "size changed"
    rec, events, kw = a_client()
    a = d.client(timeout=WAIT, **kw)
    o = a.open("sized", "rgba8")
    a.wait(o["edit"], FINAL)
    w, h = o["width"], o["height"]
    light = o["lights"][0]["name"]
    b = evict(d, "lights32")
    ob = b.shot
    C.check((ob["width"], ob["height"]) != (w, h), "the other shot is of another size",
            "%dx%d and %dx%d" % (w, h, ob["width"], ob["height"]))
    tmp = os.path.join(own, "sized.new")
    shutil.copyfile(os.path.join(own, "lights32.shot.exr"), tmp)
    os.rename(tmp, os.path.join(own, "sized.shot.exr"))
    rec.take()
    C.raises(lambda: a.set(light, intensity=3), None,
             "the edit that reloads a shot now of another size is refused")
    time.sleep(0.5)
    tiles = [e for e in rec.take() if e[0] == "tile"]
    C.equal(tiles, [], "no tile of the other image comes")
    errors = [e for e in events if e.get("op") == "error"]
    C.check(errors and "%dx%d" % (w, h) in errors[0].get("message", "")
            and "%dx%d" % (ob["width"], ob["height"]) in errors[0].get("message", ""),
            "an error event names both sizes", repr(events[:3]))
    o2 = a.open("sized", "rgba8")
    C.equal((o2["width"], o2["height"]), (ob["width"], ob["height"]),
            "opened again, the shot shows its new size")
    img = a.wait(o2["edit"], FINAL)
    C.equal((img.width, img.height), (ob["width"], ob["height"]), "and its image is that size")
    a.disconnect()
    b.disconnect()


def main():
    tmp = tempfile.mkdtemp(prefix="reload-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd", "lights32.shot.exr"):
        shutil.copyfile(os.path.join(shots, f), os.path.join(own, f))
    os.symlink("shadows.shot.exr", os.path.join(own, "linked.shot.exr"))
    shutil.copyfile(os.path.join(own, "shadows.shot.exr"), os.path.join(own, "sized.shot.exr"))
    out = os.path.join(tmp, "elsewhere")
    os.mkdir(out)
    outside = os.path.join(out, "shadows.shot.exr")
    shutil.copyfile(os.path.join(own, "shadows.shot.exr"), outside)
    d = harness.Daemon(relightd, own, ["--max-shots", "1"])
    C.run(link_out, d, own, outside)
    C.run(resized, d, own)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
