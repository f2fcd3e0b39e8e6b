"""relightd speaks protocol v1 (protocol/README.md) as the Python client sees it.

Checks, each with its tolerance:
  - hello (role editor without a token file, limits), list (both example
    shots, sizes, baked), open (lights and parameters with value, min, max);
  - every level 0..3 of an edit: tiles of tile_size x tile_size clipped at
    the edges, covering the image exactly once (no overlap, areas summing to
    width x height), all of a level's tiles before its level message, level
    messages 0, 1, 2, 3 in order;
  - the final rgba8 image of an edit equals `relight preview --set ... -o
    x.png` byte for byte (0 tolerance), for the opened state, one edit, a
    sequence of edits and an edit after a freeze;
  - rgba16f tiles agree with rgba8: sRGB-encoding the half floats gives the
    rgba8 bytes within 1 (half rounding), for every channel;
  - a second client that only watches gets the editor's final image byte
    for byte, level messages and no acks;
  - ack edit numbers strictly increase; a burst of edits ends on the last;
  - mute, solo, add_light change the image (at least 1 % of the bytes, and
    the mean of the colour channels moves the expected way); unmute, solo
    off, remove_light bring it back byte for byte; freeze acks and sends
    no tiles for 0.5 s, and leaves the image as it was;
  - errors: unknown light / parameter, out of range, wrong arity, no open
    shot, unknown shot, each with its code and the request's id;
  - snapshot writes an OpenEXR under --snapshots; stats count the edits;
    close; fragmented requests and ping; /healthz and /metrics;
  - a RIB without a shot file is baked when opened (progress, then opened);
  - over wss:// (a self-signed certificate): refused without its CA, and
    with it the final image equals relight preview byte for byte.
"""

import json
import os
import shutil
import ssl
import struct
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("protocol")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)

SHOT = "shadows"
FINAL = 3
WAIT = 60            # seconds an edit may take to reach its final level (llvmpipe, ASan)


def check_levels(events, edit, width, height, ts, what, all_levels=True):
    """The tiles and level messages of `edit` in `events` (Recorder order).
    Without `all_levels` (the tiles of an open), the levels sent may start
    past 0: a shot already refined is sent at its final level alone."""
    ev = [e for e in events if e[1] == edit]
    levels = [e[2] for e in ev if e[0] == "level"]
    if all_levels:
        C.equal(levels, [0, 1, 2, 3], what + ": level messages 0..3 in order")
    else:
        C.check(levels and levels[-1] == 3 and levels == sorted(set(levels)),
                what + ": level messages increasing up to 3", repr(levels))
    current = levels[0] if levels else 0
    tiles = {0: [], 1: [], 2: [], 3: []}
    misplaced = 0
    for e in ev:
        if e[0] == "level":
            current = e[2] + 1
        elif e[2] != current:
            misplaced += 1
        else:
            tiles[e[2]].append(e[3:])
    C.equal(misplaced, 0, what + ": every tile between the previous level message and its own")
    for lv in sorted(set(levels)):
        rects = tiles[lv]
        bad = [r for r in rects
               if r[0] % ts or r[1] % ts or r[2] != min(ts, width - r[0])
               or r[3] != min(ts, height - r[1])]
        C.check(not bad, "%s: level %d tiles are %dx%d on the grid, clipped at the edges"
                % (what, lv, ts, ts), repr(bad[:3]))
        C.equal(sum(r[2] * r[3] for r in rects), width * height,
                "%s: level %d tile areas sum to the image's" % (what, lv))
        C.equal(len(set(r[:2] for r in rects)), len(rects),
                "%s: level %d has no tile twice" % (what, lv))
    return tiles


def close_to(got, want, tol=1e-5):
    return (isinstance(got, list) and len(got) == len(want)
            and all(abs(g - w) <= tol * max(1.0, abs(w)) for g, w in zip(got, want)))


class State:
    """The --set edits applied so far, to redo them with relight preview."""

    def __init__(self):
        self.sets = {}

    def set(self, light, **params):
        for k, v in params.items():
            k = k.rstrip("_")
            self.sets["%s.%s" % (light, k)] = ",".join(
                repr(float(x)) for x in (v if isinstance(v, (list, tuple)) else [v]))

    def args(self):
        return ["%s=%s" % kv for kv in self.sets.items()]


def expect_preview(c, state, what, tolerance=0):
    """c's current image against relight preview of `state`."""
    w, h, px = harness.preview_png(relight_exe, shots, SHOT, state.args())
    img = c.image.copy()
    diff, at = harness.max_diff(img, px)
    ok = C.check((w, h) == (c.image.width, c.image.height) and diff <= tolerance,
                 "%s: rgba8 image equals relight preview %s (tolerance %d)"
                 % (what, " ".join(state.args()) or "(no edit)", tolerance),
                 "max difference %d at pixel %d channel %d, %d bytes differ"
                 % (diff, at // 4, at % 4, harness.count_diff(img, px)))
    return ok


def hello_list(d):
    C.section = "hello/list"
    c = d.client(timeout=30)
    C.equal(c.role, "editor", "role without a token file")
    C.equal(c.version, 1, "protocol version")
    C.check(isinstance(c.server, str) and c.server.startswith("relightd"), "server name", c.server)
    C.equal(c.limits.get("max_message"), 64 * 1024, "default max_message (64 KB)")
    C.equal(c.limits.get("tile_size"), 128, "default tile_size")
    shots_listed = {s["name"]: s for s in c.list()}
    for name, w, h in (("shadows", 640, 360), ("lights32", 320, 180)):
        s = shots_listed.get(name, {})
        C.equal((s.get("width"), s.get("height"), s.get("baked")), (w, h, True),
                "list: %s is %dx%d and baked" % (name, w, h))
    c.disconnect()


def editing(d):
    C.section = "open"
    rec = harness.Recorder()
    c = d.client(timeout=WAIT, **rec.kw())
    ts = c.limits.get("tile_size", 128)
    opened = c.open(SHOT, "rgba8")
    W, H = opened.get("width"), opened.get("height")
    C.equal((W, H, opened.get("levels"), opened.get("shot")), (640, 360, 4, SHOT), "opened reply")
    C.check(isinstance(opened.get("edit"), int), "opened has an edit number")
    lights = {l.get("name"): l for l in opened.get("lights", [])}
    C.equal(sorted(lights), ["1", "2", "3"], "lights of shadows.rib")
    C.equal({k: v.get("shader") for k, v in lights.items()},
            {"1": "ambientlight", "2": "shadowspot", "3": "pointlight"}, "light shaders")
    missing = [(l, p.get("name")) for l, v in lights.items() for p in v.get("params", [])
               if not all(k in p for k in ("name", "type", "value", "min", "max"))]
    C.check(not missing and all(v.get("params") for v in lights.values()),
            "every parameter has name, type, value, min and max", repr(missing[:5]))
    params2 = {p["name"]: p for p in lights.get("2", {}).get("params", [])}
    inten = params2.get("intensity", {})
    C.check(inten.get("value") == 60 and inten.get("min") <= 60 <= inten.get("max"),
            "light 2 intensity 60 within [min, max]", repr(inten))
    C.check(close_to(params2.get("from", {}).get("value"), [4, 6, -3]),
            "light 2 'from' as in the RIB, [4, 6, -3] (within 1e-5)",
            repr(params2.get("from", {}).get("value")))
    C.check("shadowname" not in params2, "string parameters are not offered")
    c.wait(opened["edit"], FINAL)
    check_levels(rec.take(), opened["edit"], W, H, ts, "opened state", all_levels=False)
    state = State()
    expect_preview(c, state, "opened state")

    C.section = "edits"
    e1 = c.set("2", intensity=90)
    C.check(e1 > opened["edit"], "set acks a newer edit", "%d after %d" % (e1, opened["edit"]))
    c.wait(e1, FINAL)
    check_levels(rec.take(), e1, W, H, ts, "set intensity")
    state.set("2", intensity=90)
    expect_preview(c, state, "2.intensity=90")
    e2 = c.set("2", {"from": [3.5, 6, -2.5]}, lightcolor=[1, 0.9, 0.7])
    C.check(e2 > e1, "edit numbers increase", "%d after %d" % (e2, e1))
    c.wait(e2, FINAL)
    rec.take()
    state.set("2", from_=[3.5, 6, -2.5], lightcolor=[1, 0.9, 0.7])
    expect_preview(c, state, "point and colour edit")
    # A burst, as a slider drag sends it: only the last must be complete.
    reqs = [c.set_async("3", intensity=v) for v in (2, 4, 6, 8, 10)]
    edits = [r.result()["edit"] for r in reqs]
    C.check(all(b > a for a, b in zip(edits, edits[1:])) and edits[0] > e2,
            "a burst of 5 edits acked with increasing numbers", repr(edits))
    t0 = time.monotonic()
    c.wait(edits[-1], FINAL)
    C.note("burst of 5 edits: final level of the last %.0f ms after its ack"
           % (1000 * (time.monotonic() - t0)))
    state.set("3", intensity=10)
    ev = rec.take()
    C.equal([e[2] for e in ev if e[0] == "level" and e[1] == edits[-1]], [0, 1, 2, 3],
            "the last edit of the burst gets all its levels in order")
    stale = [e for e in ev if e[0] == "tile" and e[1] not in edits]
    C.equal(stale, [], "no tile of an edit that was not made")
    expect_preview(c, state, "after a burst")
    return c, rec, state


def watcher_and_formats(d, c, rec, state):
    C.section = "viewer"
    vrec = harness.Recorder()
    acks = []
    v = d.client(timeout=WAIT, on_event=acks.append, **vrec.kw())
    vo = v.open(SHOT, "rgba8")
    h = d.client(timeout=WAIT)
    ho = h.open(SHOT, "rgba16f")
    C.equal((vo["width"], vo["height"]), (640, 360), "second client opens the same shot")
    v.wait(vo["edit"], FINAL)
    h.wait(ho["edit"], FINAL)
    vrec.take()
    e = c.set("3", intensity=7)
    state.set("3", intensity=7)
    c.wait(e, FINAL)
    v.wait(e, FINAL)
    h.wait(e, FINAL)
    C.equal(v.image.copy(), c.image.copy(), "the watcher's final image equals the editor's")
    C.equal([x[2] for x in vrec.take() if x[0] == "level" and x[1] == e], [0, 1, 2, 3],
            "the watcher gets the level messages of the editor's edit")
    C.equal([m for m in acks if m.get("op") == "ack"], [], "the watcher gets no ack")

    C.section = "rgba16f"
    half = h.image.copy()
    px8 = c.image.copy()
    n = len(half) // 2
    values = struct.unpack("<%de" % n, half)
    memo = {}
    worst, at = 0, -1
    for i, x in enumerate(values):
        ch = i & 3
        key = (x, ch == 3)
        enc = memo.get(key)
        if enc is None:
            enc = harness.srgb8(x) if ch != 3 else max(0, min(255, int(255 * max(0.0, x) + 0.5)))
            memo[key] = enc
        dlt = abs(enc - px8[i])
        if dlt > worst:
            worst, at = dlt, i
    C.check(worst <= 1, "rgba16f sRGB-encoded equals rgba8 within 1 (every channel)",
            "difference %d at pixel %d channel %d: half %r, rgba8 %d"
            % (worst, at // 4, at % 4, values[at] if at >= 0 else None, px8[at] if at >= 0 else -1))
    C.check(max(values) > 0.05, "the rgba16f image is not black", "max %r" % max(values))
    v.disconnect()
    h.disconnect()


def light_ops(d, c, rec, state):
    C.section = "mute/solo/add/remove/freeze"
    base = c.image.copy()
    n = len(base)

    def after(edit):
        c.wait(edit, FINAL)
        return c.image.copy()

    def colour_mean(px):
        return sum(harness.mean(px, ch) for ch in range(3)) / 3

    def changed(px, what, brighter):
        nd = harness.count_diff(px, base)
        C.check(nd >= n // 100, what + ": at least 1 % of the bytes change", "%d of %d" % (nd, n))
        m0, m1 = colour_mean(base), colour_mean(px)
        C.check(m1 > m0 if brighter else m1 < m0,
                what + ": the image gets " + ("brighter" if brighter else "darker"),
                "mean %.2f -> %.2f" % (m0, m1))

    def restored(px, what):
        diff, at = harness.max_diff(px, base)
        C.check(diff == 0, what + ": the image is back byte for byte",
                "max difference %d at byte %d" % (diff, at))

    muted = after(c.mute("2"))
    changed(muted, "mute key light 2", brighter=False)
    restored(after(c.unmute("2")), "unmute 2")
    solo = after(c.solo("3"))
    changed(solo, "solo light 3", brighter=False)
    restored(after(c.solo(None)), "solo off")
    c.mute("1")
    both = after(c.mute("2"))
    C.equal(both, solo, "muting lights 1 and 2 gives the solo-3 image")
    c.unmute("1")
    restored(after(c.unmute("2")), "unmute 1 and 2")
    rec.take()
    ack = c.freeze("2")
    C.equal(ack.get("op"), "ack", "freeze is acknowledged")
    time.sleep(0.5)
    C.equal([e for e in rec.take() if e[0] == "tile"], [], "freeze sends no tiles (0.5 s)")
    C.equal(c.image.copy(), base, "freeze leaves the image as it was")
    e = c.set("3", intensity=9)
    state.set("3", intensity=9)
    c.wait(e, FINAL)
    expect_preview(c, state, "an edit of another light while 2 is frozen")
    e = c.set("2", intensity=70)
    state.set("2", intensity=70)
    c.wait(e, FINAL)
    expect_preview(c, state, "an edit of the frozen light")
    C.equal(c.unfreeze("2").get("op"), "ack", "unfreeze is acknowledged")
    # Added and removed last: the state after them is the one before.
    base = after(c.set("3", intensity=9))
    added = after(c.add_light("extra", "pointlight", intensity=30, from_=[0, 3, 1],
                              lightcolor=[1, 1, 1]))
    changed(added, "add a point light", brighter=True)
    dimmer = after(c.set("extra", intensity=5))
    C.check(base != dimmer and colour_mean(dimmer) < colour_mean(added),
            "set on the added light takes effect (dimmer than at 30, not the base image)")
    restored(after(c.remove_light("extra")), "remove the added light")
    C.raises(lambda: c.set("extra", intensity=1), "unknown_light", "the removed light is gone")
    C.raises(lambda: c.remove_light("extra"), "unknown_light", "removing it again")


def errors(d, c):
    C.section = "errors"
    C.raises(lambda: c.set("nope", intensity=1), "unknown_light", "set on an unknown light")
    C.raises(lambda: c.set("2", nope=1), "unknown_param", "set of an unknown parameter")
    C.raises(lambda: c.set("2", coneangle=4), "range", "coneangle 4 is out of range")
    try:
        c.set("2", {"from": [1, 2]})
        C.check(False, "'from' with 2 values refused")
    except relight.ServerError as e:
        C.check(e.code in ("type", "range"), "'from' with 2 values refused", e.code)
    C.raises(lambda: c.mute("nope"), "unknown_light", "mute an unknown light")
    C.raises(lambda: c.solo("nope"), "unknown_light", "solo an unknown light")
    C.raises(lambda: c.add_light("x", "nosuchshader"), None, "add a light of no shader")
    o = d.client(timeout=WAIT)
    C.raises(lambda: o.set("2", intensity=1), "state", "set before open")
    C.raises(lambda: o.snapshot(), "state", "snapshot before open")
    C.raises(lambda: o.open("nope"), "unknown_shot", "open an unknown shot")
    req = o.request_async("open", shot=SHOT, format="rgb")
    try:
        req.result()
        C.check(False, "format 'rgb' refused")
    except relight.ServerError as e:
        C.check(e.code in ("range", "type") and e.id == req.id,
                "format 'rgb' refused with the request's id", "%s id %r" % (e.code, e.id))
    C.raises(lambda: o.request("bogus"), "unknown_op", "unknown op")
    C.raises(lambda: o.request("set", light="2", params={"intensity": True}), "type",
             "a boolean value")
    C.raises(lambda: o.request("set", light="2", params={"intensity": 1e39}), "range",
             "1e39 is not a float")
    o.disconnect()


def misc(d, c):
    C.section = "snapshot/stats/close"
    # The reply names the file in --snapshots, not by the server's path.
    name = c.snapshot()
    C.check(isinstance(name, str) and "/" not in name, "snapshot path is a name", repr(name))
    path = os.path.join(d.snapshots, name) if isinstance(name, str) else None
    C.check(path and os.path.isfile(path), "snapshot under --snapshots exists", repr(name))
    if path and os.path.isfile(path):
        with open(path, "rb") as f:
            C.equal(f.read(4), b"\x76\x2f\x31\x01", "snapshot is an OpenEXR file")
    st = c.stats()
    C.check(st.get("edits", 0) >= 20, "stats: edits counted (>= 20 made)", repr(st))
    C.check(st.get("tiles_sent", 0) > 0 and st.get("bytes_sent", 0) > 0,
            "stats: tiles and bytes sent", repr(st))
    C.equal(c.close().get("op"), "closed", "close")
    C.raises(lambda: c.set("2", intensity=1), "state", "set after close")
    o = c.open("lights32")
    C.equal((o["width"], o["height"]), (320, 180), "another shot on the same connection")
    c.wait(o["edit"], FINAL)
    C.equal((c.image.width, c.image.height), (320, 180), "its image")
    # A value as "opened" reports it, sent back, changes nothing: what a
    # client's widget shows is what set takes.
    p3 = {p["name"]: p for l in o["lights"] if l["name"] == "3" for p in l["params"]}
    frm = p3.get("from", {}).get("value")
    C.check(close_to(frm, [3.2, 2.2, 3.0]), "lights32 light 3 'from' as in the RIB (within 1e-5)",
            repr(frm))
    before = c.image.copy()
    if isinstance(frm, list) and len(frm) == 3:
        c.wait(c.set("3", {"from": frm}), FINAL)
        C.equal(c.image.copy(), before, "setting 'from' to its reported value leaves the image")

    C.section = "websocket"
    ws = d.ws()
    ws.send('{"op":"hello","version":1}', fragment=3)
    C.equal(json.loads(ws.recv(10)).get("op"), "hello", "a hello in 3-byte fragments")
    ws.send('{"op":"list","id":77}', fragment=5)
    r = json.loads(ws.recv(10))
    C.equal((r.get("op"), r.get("id")), ("shots", 77), "a list in 5-byte fragments")
    ws.ping(b"relight")
    try:
        ws.recv(1.0)
    except TimeoutError:
        pass
    C.equal(ws.pongs, 1, "ping answered by one pong")
    ws.close(1000, wait=5)
    C.equal(ws.close_code, 1000, "closing handshake completes with 1000")

    C.section = "http"
    status, body = d.http("/healthz")
    C.equal((status, body), (200, b"ok\n"), "/healthz")
    status, body = d.http("/metrics")
    names = [l.split()[0] for l in body.decode(errors="replace").splitlines()
             if l and not l.startswith("#")]
    C.check(status == 200 and names and all(n.startswith("relight_") for n in names),
            "/metrics is Prometheus text of relight_ names", repr(names[:5]))
    edits = d.metric("relight_edits_total")
    C.check(edits is not None and edits >= 20, "relight_edits_total counts the edits", repr(edits))


def on_demand_bake():
    C.section = "bake on open"
    tmp = tempfile.mkdtemp(prefix="bake-", dir=harness.build_dir())
    try:
        shutil.copyfile(os.path.join(harness.SOURCE_DIR, "examples", "lights32", "lights32.rib"),
                        os.path.join(tmp, "lights32.rib"))
        d = harness.Daemon(relightd, tmp)
        c = d.client(timeout=WAIT)
        listed = {s["name"]: s for s in c.list()}
        C.equal(listed.get("lights32", {}).get("baked"), False, "a lone RIB is listed, not baked")
        progress = []
        o = c.open("lights32", on_progress=progress.append)
        C.equal((o.get("width"), o.get("height")), (320, 180), "opening it bakes and opens it")
        C.check(all(0 <= p.get("fraction", -1) <= 1 and p.get("shot") == "lights32"
                    for p in progress), "progress messages name the shot, fraction in [0, 1]",
                repr(progress[:3]))
        c.wait(o["edit"], FINAL)
        C.check(os.path.exists(os.path.join(tmp, "lights32.shot.exr")), "the shot file was written")
        listed = {s["name"]: s for s in c.list()}
        C.equal(listed.get("lights32", {}).get("baked"), True, "listed as baked afterwards")
        c.disconnect()
        d.finish(C)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def tls():
    C.section = "wss"
    tmp = tempfile.mkdtemp(prefix="tls-", dir=harness.build_dir())
    try:
        cert, key = os.path.join(tmp, "cert.pem"), os.path.join(tmp, "key.pem")
        r = subprocess.run(["openssl", "req", "-x509", "-newkey", "rsa:2048", "-nodes", "-days", "1",
                            "-subj", "/CN=127.0.0.1", "-addext", "subjectAltName=IP:127.0.0.1",
                            "-keyout", key, "-out", cert],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=60)
        if r.returncode != 0:
            C.note("wss not checked: openssl cannot make a certificate here")
            return
        d = harness.Daemon(relightd, shots, ["--tls-cert", cert, "--tls-key", key])
        C.check(d.url.startswith("wss://"), "with --tls-cert the daemon serves https/wss", d.url)
        try:
            relight.Client(d.url, timeout=WAIT)
            C.check(False, "an unknown certificate is refused by default")
        except ssl.SSLError:
            C.check(True, "an unknown certificate is refused by default")
        ctx = ssl.create_default_context(cafile=cert)
        c = relight.Client(d.url, timeout=WAIT, ssl_context=ctx)
        C.equal(c.role, "editor", "hello over wss")
        o = c.open("lights32")
        c.wait(o["edit"], FINAL)
        e = c.set("4", intensity=0.3)
        img = c.wait(e, FINAL).copy()
        w, h, px = harness.preview_png(relight_exe, shots, "lights32", ["4.intensity=0.3"])
        C.equal(img, px, "the final image over wss equals relight preview")
        c.disconnect()
        d.finish(C)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    d = harness.Daemon(relightd, shots)
    C.run(hello_list, d)
    r = C.run(editing, d)
    if r:
        c, rec, state = r
        C.run(watcher_and_formats, d, c, rec, state)
        C.run(light_ops, d, c, rec, state)
        C.run(errors, d, c)
        C.run(misc, d, c)
        c.disconnect()
    d.finish(C)
    C.run(on_demand_bake)
    C.run(tls)
    C.finish()


if __name__ == "__main__":
    main()
