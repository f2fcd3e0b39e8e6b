"""relightd keeps shots in GPU memory within --max-shots and --gpu-budget, the
least recently used evicted, and an evicted shot comes back as it was.

Checks (exact unless a tolerance is given):
  - with --max-shots 1, opening a second shot evicts the first:
    relight_shot_evictions_total rises by 1 and relight_shots_resident stays 1;
  - reopening the evicted shot loads it again (relight_shot_loads_total rises)
    with its edits replayed: the same edit number, the edited parameter
    reported as set, and a final rgba8 image byte for byte the one shown
    before the eviction;
  - with --gpu-budget holding either shot but not both (the larger one's
    bytes and half the smaller's, measured in the first run), the same holds
    through the budget, and the resident bytes stay within it once a load
    has made room (relight_gpu_bytes <= budget).
"""

import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

C = harness.Checks("eviction")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120
FINAL = 3


def param(opened, light, name):
    for l in opened.get("lights", []):
        if l.get("name") == light:
            for p in l.get("params", []):
                if p.get("name") == name:
                    return p.get("value")
    return None


def round_trip(d, what, sizes):
    C.section = what
    c = d.client(timeout=WAIT)
    o1 = c.open("shadows", "rgba8")
    e = c.set("2", intensity=77)
    before = c.wait(e, FINAL).copy()
    sizes["shadows"] = d.metric("relight_gpu_bytes")
    loads0 = d.metric("relight_shot_loads_total") or 0
    ev0 = d.metric("relight_shot_evictions_total") or 0
    o2 = c.open("lights32", "rgba8")
    c.wait(o2["edit"], FINAL)
    sizes["lights32"] = d.metric("relight_gpu_bytes")
    C.equal(d.metric("relight_shots_resident"), 1, "one shot resident after opening another")
    C.check((d.metric("relight_shot_evictions_total") or 0) >= ev0 + 1, "the first shot was evicted",
            "evictions %r -> %r" % (ev0, d.metric("relight_shot_evictions_total")))
    o3 = c.open("shadows", "rgba8")
    C.check((d.metric("relight_shot_loads_total") or 0) >= loads0 + 2,
            "shadows loaded again after its eviction",
            "loads %r -> %r" % (loads0, d.metric("relight_shot_loads_total")))
    C.equal(o3.get("edit"), e, "the reloaded shot keeps its edit number")
    C.equal(param(o3, "2", "intensity"), 77, "the edit was replayed (intensity 77)")
    after = c.wait(o3["edit"], FINAL)
    C.check(after.copy() == before,
            "the reloaded shot's final image equals the one before the eviction, byte for byte")
    C.check(o1.get("edit") < e, "the edit was newer than the opened state")
    c.disconnect()


def main():
    tmp = tempfile.mkdtemp(prefix="eviction-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd", "lights32.shot.exr"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own, f))
    d = harness.Daemon(relightd, own, ["--max-shots", "1"])
    sizes = {}
    C.run(round_trip, d, "max-shots 1", sizes)
    d.finish(C)

    # A budget that holds either shot but not both: the larger one and half
    # the smaller, in MB.
    a, b = sizes.get("shadows") or 0, sizes.get("lights32") or 0
    C.check(a > 0 and b > 0, "both shots' GPU bytes measured", repr(sizes))
    if not (a > 0 and b > 0):
        C.finish()
    own2 = os.path.join(tmp, "shots2")
    os.mkdir(own2)
    for f in ("shadows.shot.exr", "key.shd", "lights32.shot.exr"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own2, f))
    budget = int((max(a, b) + min(a, b) / 2) / (1 << 20)) + 1
    d = harness.Daemon(relightd, own2, ["--gpu-budget", str(budget)])
    C.run(round_trip, d, "gpu-budget %d MB" % budget, {})
    C.section = "budget"
    gpu = d.metric("relight_gpu_bytes")
    C.check(gpu is not None and gpu <= budget * (1 << 20),
            "resident bytes within the budget (%d MB)" % budget, "%r bytes" % gpu)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
