"""relightd's edit log holds the state its edits produce, not every edit.

Checks:
  - 100,000 edits of a shot (sets of two lights' parameters, mutes, solos,
    freezes) leave at most one log entry per parameter set, a mute and a
    freeze per light and one solo ("log_entries" in stats), and log_bytes
    under 16 KB;
  - the daemon's resident memory grows by less than 4 MB over those edits
    (the log alone took ~360 bytes an edit, 36 MB for 100,000, before; not
    checked under AddressSanitizer, whose quarantine keeps freed memory);
  - evicted (--max-shots 1, another shot opened) and loaded again, the shot
    comes back with the same edit number and a final rgba8 image byte for
    byte the one shown before the eviction.
"""

import os
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

C = harness.Checks("editlog")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120
FINAL = 3
EDITS = 100000


def float_params(opened, light):
    for l in opened.get("lights", []):
        if l.get("name") == light:
            return [p for p in l.get("params", []) if p.get("type") == "float"]
    return []


def edits(d):
    C.section = "edits"
    c = d.client(timeout=WAIT)
    o = c.open("shadows", "rgba8")
    lights = [l["name"] for l in o["lights"]][:2]
    C.check(len(lights) == 2, "the shot has two lights", repr(lights))
    params = {l: [p["name"] for p in float_params(o, l)][:3] for l in lights}
    C.check(all(params.values()), "each light has float parameters", repr(params))
    rss0 = d.rss_kb()
    last = None
    pending = []
    for i in range(EDITS):
        light = lights[i % 2]
        k = i % 50
        if k == 10:
            pending.append(c.request_async("mute", light=light, mute=bool(i % 4)))
        elif k == 20:
            pending.append(c.request_async("solo", light=light if i % 3 else None))
        elif k == 30:
            pending.append(c.request_async("freeze", light=light, freeze=bool(i % 4)))
        else:
            name = params[light][i % len(params[light])]
            pending.append(c.set_async(light, {name: 0.5 + (i % 97) / 97.0}))
        if len(pending) > 200:
            for r in pending[:100]:
                r.result()
            pending = pending[100:]
    for r in pending:
        last = r.result()
    # the last edits: a set of each light's first parameter, solo off, all unmuted
    c.request("solo", light=None)
    for light in lights:
        c.request("mute", light=light, mute=False)
    e = c.set(lights[0], {params[lights[0]][0]: 0.75})
    before = c.wait(e, FINAL).copy()
    st = c.stats()
    rss1 = d.rss_kb()
    n = st.get("log_entries")
    want = sum(len(v) for v in params.values()) + 2 * len(lights) + 1
    C.check(n is not None and n <= want,
            "%d edits leave at most %d log entries" % (EDITS, want), "log_entries %r" % n)
    C.check(st.get("log_bytes") is not None and st["log_bytes"] < 16384,
            "the log holds under 16 KB", "log_bytes %r" % st.get("log_bytes"))
    if d.sanitized():
        # AddressSanitizer keeps freed memory in quarantine: RSS says nothing there.
        C.note("AddressSanitizer build: resident memory not checked")
    else:
        C.check(rss1 - rss0 < 4096, "resident memory grows by less than 4 MB over the edits",
                "%d kB -> %d kB" % (rss0, rss1))
    C.note("log: %r entries, %r bytes; RSS %d kB -> %d kB" % (n, st.get("log_bytes"), rss0, rss1))

    C.section = "eviction"
    ev0 = d.metric("relight_shot_evictions_total") or 0
    o2 = c.open("lights32", "rgba8")
    c.wait(o2["edit"], FINAL)
    C.check((d.metric("relight_shot_evictions_total") or 0) >= ev0 + 1, "the shot was evicted")
    o3 = c.open("shadows", "rgba8")
    C.equal(o3.get("edit"), e, "the reloaded shot keeps its edit number")
    after = c.wait(o3["edit"], FINAL)
    C.check(after.copy() == before,
            "the reloaded shot's final image equals the one before the eviction, byte for byte")
    c.disconnect()
    del last


def main():
    tmp = tempfile.mkdtemp(prefix="editlog-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd", "lights32.shot.exr"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own, f))
    # 100,000 edits free far more than AddressSanitizer's default quarantine
    # would keep (about 7 GB resident by the end): a smaller one still catches
    # a use after free of anything freed recently.
    asan = os.environ.get("ASAN_OPTIONS", "")
    env = {"ASAN_OPTIONS": (asan + ":" if asan else "") + "quarantine_size_mb=64"}
    d = harness.Daemon(relightd, own, ["--max-shots", "1"], env=env)
    C.run(edits, d)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
