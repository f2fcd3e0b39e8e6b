"""relightd under hostile or careless clients.

Checks, each with its tolerance:
  - 10,000 malformed or random messages on a few connections: 9,400 text
    frames (not JSON, wrong types, huge numbers, NaN literals, unknown ops,
    deep nesting, long strings, empty frames) each get exactly one reply,
    errors carry a code of the protocol and the request's id when it had a
    usable one; 600 frame-level oddities (binary frames of random bytes,
    empty binary frames, text that is not UTF-8, pings) get an error reply
    or close the connection with 1002, 1003 or 1007, never anything else;
    afterwards a new client is served (its final image equals relight
    preview byte for byte) and /healthz answers;
  - 50 clients that open a shot, edit and vanish without a close frame
    while tiles flow (half with a TCP reset): the client gauge returns to
    what it was within 10 s, and a new client is served correctly;
  - 64 connections at once, each hello + list + open: all get the same
    final image;
  - a client that opens a shot in rgba16f and never reads, while another
    makes 200 edits: the daemon's RSS grows by at most
    2 x --client-queue + 64 MB (its queue and the editor's, plus working
    memory; not checked under AddressSanitizer, whose quarantine keeps
    freed memory), and the editor gets every ack and every edit's first
    level;
  - a frame of exactly --max-message bytes is served; one byte more closes
    the connection with 1009; a fragmented message over the limit too.
"""

import json
import os
import random
import socket
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("robustness")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)

CLIENT_QUEUE_MB = 8
WAIT = 60
ERROR_CODES = {"malformed", "unknown_op", "type", "range", "unknown_shot", "unknown_light",
               "unknown_param", "auth", "forbidden", "limit", "state", "internal"}
# Replies that answer a request one to one (tiles, level and progress do not).
PRIMARY = {"error", "hello", "shots", "opened", "ack", "closed", "snapshot", "stats"}


# ---------------------------------------------------------------------------
# Fuzz
# ---------------------------------------------------------------------------

class Fuzzer:
    """Text frames that are not valid requests (or harmless valid ones).
    next() returns (text, id the reply must carry or None)."""

    OPS = ["hello", "list", "open", "set", "add_light", "remove_light", "solo", "mute",
           "freeze", "close", "snapshot", "stats"]

    def __init__(self, seed):
        self.r = random.Random(seed)
        self.id = 1000

    def uid(self):
        self.id += 1
        return self.id

    def junk_value(self):
        r = self.r
        return r.choice([None, True, False, 0, -1, 1.5, 1e308, -1e308, 2 ** 64, "", "x" * r.randint(1, 400),
                         [], {}, [1, 2, 3], {"a": 1}, "\u00e9\u4e2d\U0001f600", "\x00\x01", [[[]]]])

    def next(self):
        r = self.r
        kind = r.randrange(14)
        if kind == 0:   # not JSON
            return r.choice(["", " ", "{", "}", "{op:list}", "{'op':'list'}", '{"op":"list"',
                             '{"op":"list"} x', '{"op":"list",}', "\u00ff" * r.randint(1, 50),
                             "null", "true", "[]", "1", '"list"', "\x00",
                             "".join(chr(r.randint(32, 0x2fff)) for _ in range(r.randint(1, 200)))]), None
        if kind == 1:   # random text
            n = r.randint(1, 2000)
            return "".join(chr(r.choice([r.randint(0x20, 0x7e), r.randint(0xa0, 0xd7ff),
                                         r.randint(0xe000, 0x10ffff)])) for _ in range(n)), None
        if kind == 2:   # wrong type of op
            return json.dumps({"op": self.junk_value() if r.random() < 0.9 else 5}), None
        if kind == 3:   # unknown op
            i = self.uid()
            op = "".join(r.choice("abcdefghijklmnopqrstuvwxyz_") for _ in range(r.randint(1, 30)))
            if op in self.OPS:
                op += "_x"
            return json.dumps({"op": op, "id": i}), i
        if kind == 4:   # wrong member types for a real op
            i = self.uid()
            op = r.choice(["set", "open", "mute", "freeze", "add_light", "remove_light", "solo"])
            msg = {"op": op, "id": i}
            for k in r.sample(["light", "shot", "params", "mute", "freeze", "shader", "format"],
                              r.randint(0, 4)):
                msg[k] = self.junk_value()
            # a wrong type, never a valid value by chance
            msg["light" if op != "open" else "shot"] = r.choice([5, [], {}, True, 1.5])
            return json.dumps(msg), i
        if kind == 5:   # huge or odd numbers written by hand
            i = self.uid()
            num = r.choice(["1e309", "-1e309", "1e39", "-3.5e38", "1e400", "123456789012345678901234567890",
                            "0.0000000000000000000000000000000000000000000001", "-0", "1E+999"])
            return '{"op":"set","id":%d,"light":"2","params":{"intensity":%s}}' % (i, num), i
        if kind == 6:   # NaN and infinity literals (not JSON)
            lit = r.choice(["NaN", "nan", "Infinity", "-Infinity", "inf", "undefined"])
            return '{"op":"set","id":%d,"light":"2","params":{"intensity":%s}}' % (self.uid(), lit), None
        if kind == 7:   # deep nesting
            k = r.choice([100, 999, 1000, 1001, 2000, 10000, 30000])
            if r.random() < 0.5:
                return "[" * k + "]" * k, None
            return '{"op":"list","x":' + "[" * k + "]" * k + "}", None
        if kind == 8:   # odd ids
            idv = r.choice(['"7"', "1.5", "true", "null", "[1]", "9007199254740993", "1e300", "-9007199254740993"])
            return '{"op":"bogus_op","id":%s}' % idv, None
        if kind == 9:   # too many or malformed parameters
            i = self.uid()
            params = r.choice([
                {"p%d" % j: 1.0 for j in range(r.randint(65, 200))},
                {"intensity": list(range(17))},
                {"intensity": []},
                {"": 1},
                {"x" * 300: 1},
                {"intensity": [1, "a", 3]},
                {"intensity": {"a": 1}},
                {"intensity": None},
            ])
            return json.dumps({"op": "set", "id": i, "light": "2", "params": params}), i
        if kind == 10:  # long names and hello of the wrong shape
            i = self.uid()
            return r.choice([
                json.dumps({"op": "open", "id": i, "shot": "s" * r.randint(257, 5000)}),
                json.dumps({"op": "hello", "id": i, "version": r.choice([0, 2, -1, "1", None, 1.5])}),
                json.dumps({"op": "mute", "id": i, "light": "x" * 1000}),
            ]), i
        if kind == 11:  # not an object
            return json.dumps(r.choice([[{"op": "list"}], [1, 2], 3.5, "op", None])), None
        if kind == 12:  # escapes
            return r.choice(['{"op":"li\\u0000st"}', '{"op":"\\ud800"}', '{"op":"\\uZZZZ"}',
                             '{"op":"list\\', '{"\\u006fp":"bogus"}']), None
        # harmless valid requests, answered one to one
        i = self.uid()
        return json.dumps({"op": r.choice(["list", "stats"]), "id": i, "extra": self.junk_value()}), i


class Conn:
    """A raw connection that counts its replies on a reader thread."""

    def __init__(self, d):
        self.ws = d.ws()
        self.ws.send(json.dumps({"op": "hello", "version": 1}))
        json.loads(self.ws.recv(10))
        self.replies = []
        self.bad = []
        self.closed = None
        self.cond = threading.Condition()
        self.t = threading.Thread(target=self.read, daemon=True)
        self.t.start()

    def read(self):
        try:
            while True:
                m = self.ws.recv()
                if isinstance(m, bytes):
                    continue
                try:
                    msg = json.loads(m)
                except ValueError:
                    self.bad.append(m[:100])
                    continue
                if msg.get("op") in PRIMARY:
                    with self.cond:
                        self.replies.append(msg)
                        self.cond.notify_all()
        except (relight.ConnectionClosed, relight.ProtocolError) as e:
            with self.cond:
                self.closed = e
                self.cond.notify_all()

    def wait_replies(self, n, timeout):
        deadline = time.monotonic() + timeout
        with self.cond:
            while len(self.replies) < n and self.closed is None:
                left = deadline - time.monotonic()
                if left <= 0:
                    break
                self.cond.wait(left)
            return len(self.replies)


def fuzz_text(d, n_conns=3, total=9400):
    C.section = "fuzz text"
    seed = int(os.environ.get("RELIGHT_FUZZ_SEED", "0")) or random.randrange(1 << 30)
    C.note("fuzz seed %d (set RELIGHT_FUZZ_SEED to repeat)" % seed)
    fz = Fuzzer(seed)
    conns = [Conn(d) for _ in range(n_conns)]
    sent = [0] * n_conns
    expect_ids = [set() for _ in range(n_conns)]
    t0 = time.monotonic()
    for k in range(total):
        i = k % n_conns
        text, rid = fz.next()
        if len(text.encode()) > 64 * 1024:
            text = text[:20000]
            rid = None
        conns[i].ws.send(text)
        sent[i] += 1
        if rid is not None:
            expect_ids[i].add(rid)
        # At most 300 replies outstanding on a connection.
        if sent[i] - len(conns[i].replies) > 300:
            conns[i].wait_replies(sent[i] - 300, 30)
    for i, c in enumerate(conns):
        got = c.wait_replies(sent[i], 60)
        C.check(c.closed is None, "fuzz connection %d stays open" % i, repr(c.closed))
        C.equal(got, sent[i], "fuzz connection %d: one reply per text frame" % i)
        codes = [m.get("code") for m in c.replies if m.get("op") == "error"]
        odd = [x for x in codes if x not in ERROR_CODES]
        C.check(not odd, "fuzz connection %d: error codes are the protocol's" % i, repr(odd[:5]))
        ids = set(m.get("id") for m in c.replies)
        missing = expect_ids[i] - ids
        C.check(not missing, "fuzz connection %d: replies carry the requests' ids" % i,
                "%d ids missing, e.g. %r" % (len(missing), sorted(missing)[:5]))
        C.equal(c.bad, [], "fuzz connection %d: every reply is JSON" % i)
        c.ws.close(1000)
        c.t.join(5)
        C.equal(getattr(c.closed, "code", None), 1000, "fuzz connection %d closes with 1000" % i)
        c.ws.abort()
    C.note("%d text frames answered in %.1f s" % (sum(sent), time.monotonic() - t0))


def fuzz_frames(d, total=600):
    C.section = "fuzz frames"
    r = random.Random(1)
    ws = None
    closes = {}
    errors = 0
    served = 0
    served_kind = [0] * 6
    bad_replies = []
    sid = 1 << 20
    for k in range(total):
        if ws is None:
            ws = d.ws()
            ws.send('{"op":"hello","version":1}')
            json.loads(ws.recv(10))
        kind = k % 6
        try:
            if kind == 0:
                ws.send(bytes(r.getrandbits(8) for _ in range(r.randint(1, 3000))))
            elif kind == 1:
                ws.send_frame(relight.OP_BINARY, b"")
            elif kind == 2:
                ws.send_frame(relight.OP_TEXT, r.choice([b"\xff", b"\xc3\x28", b'{"op":"\xed\xa0\x80"}',
                                                         b"\xf8\x88\x80\x80\x80", b'{"op":"list"}\x80']))
            elif kind == 3:   # a tile-looking binary frame
                ws.send(struct.pack("<4s8I", b"RLT1", 36, 1, 0, 1, 0, 0, 1, 1) + bytes(4))
            elif kind == 4:
                ws.ping(bytes(r.getrandbits(8) for _ in range(r.randint(0, 125))))
            else:             # a valid request split with a ping between its fragments
                ws.send_frame(relight.OP_TEXT, b'{"op":"st', fin=False)
                ws.ping(b"x")
                ws.send_frame(relight.OP_CONTINUATION, b'ats","id":5}')
            sid += 1
            ws.send(json.dumps({"op": "list", "id": sid}))
            while True:
                m = ws.recv(10)
                if isinstance(m, str):
                    msg = json.loads(m)
                    if msg.get("id") == sid:
                        served += 1
                        served_kind[kind] += 1
                        break
                    if msg.get("op") == "error":
                        errors += 1
        except relight.ConnectionClosed as e:
            closes[e.code] = closes.get(e.code, 0) + 1
            ws = None
        except relight.ProtocolError as e:
            # The daemon broke RFC 6455 (e.g. a reply that is not UTF-8).
            bad_replies.append("after oddity %d (kind %d): %s" % (k, kind, e))
            ws = None
        except TimeoutError:
            C.check(False, "frame oddity %d answered within 10 s" % k)
            ws.abort()
            ws = None
    if ws is not None:
        ws.close(1000, wait=2)
    C.note("frame oddities: %d followed by a served request, %d error replies, closes %r"
           % (served, errors, closes))
    C.check(set(closes) <= {1002, 1003, 1007}, "connections closed only with 1002, 1003 or 1007",
            repr(closes))
    C.equal(bad_replies, [], "the daemon's frames are valid (text frames UTF-8)")
    C.check(served + sum(closes.values()) + len(bad_replies) == total,
            "every oddity answered or closed",
            "%d served + %r closes != %d" % (served, closes, total))
    C.equal(served_kind[4], total // 6, "connections stay open after pings")
    C.equal(served_kind[5], total // 6, "fragmented requests with a ping inside are served")


def served_correctly(d, what, light="3", value=0.37):
    """A new client opens lights32, edits, and gets relight preview's image."""
    c = d.client(timeout=WAIT)
    o = c.open("lights32")
    c.wait(o["edit"], 3)
    e = c.set(light, intensity=value)
    img = c.wait(e, 3).copy()
    w, h, px = harness.preview_png(relight_exe, shots, "lights32",
                                   ["%s.intensity=%r" % (light, float(value))] + served_correctly.sets)
    diff, at = harness.max_diff(img, px)
    C.check(diff == 0, what + ": a new client's final image equals relight preview",
            "max difference %d at byte %d" % (diff, at))
    served_correctly.sets.append("%s.intensity=%r" % (light, float(value)))
    c.disconnect()


served_correctly.sets = []


def healthy(d, what):
    status, body = d.http("/healthz")
    C.equal((status, body), (200, b"ok\n"), what + ": /healthz")


# ---------------------------------------------------------------------------
# Vanishing, crowds, slow readers, big frames
# ---------------------------------------------------------------------------

def vanishing(d, times=50):
    C.section = "vanishing clients"
    base = d.metric("relight_clients")
    r = random.Random(2)
    for k in range(times):
        ws = d.ws()
        ws.send('{"op":"hello","version":1}')
        ws.recv(10)
        ws.send(json.dumps({"op": "open", "id": 1, "shot": "shadows", "format": "rgba16f"}))
        ws.send(json.dumps({"op": "set", "id": 2, "light": "2",
                            "params": {"intensity": r.uniform(10, 100)}}))
        # Let some tiles start flowing, read a few of them, then vanish.
        got, want = 0, r.randint(0, 5)
        deadline = time.monotonic() + r.uniform(0.0, 0.3)
        try:
            while time.monotonic() < deadline and got < want:
                if isinstance(ws.recv(0.3), bytes):
                    got += 1
        except (TimeoutError, relight.ConnectionClosed):
            pass
        if k % 2:
            # A reset instead of a FIN.
            ws.sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
        ws.abort()
    ok = harness.wait_until(lambda: d.metric("relight_clients") == base, 10, 0.1)
    C.check(ok, "relight_clients back to %r within 10 s" % base, repr(d.metric("relight_clients")))
    C.check(d.alive(), "relightd survives %d vanishing clients" % times)
    # shadows' state now has light 2 at some intensity: set it back and check.
    c = d.client(timeout=WAIT)
    o = c.open("shadows")
    c.wait(o["edit"], 3)
    e = c.set("2", intensity=60)
    img = c.wait(e, 3).copy()
    w, h, px = harness.preview_png(relight_exe, shots, "shadows", ["2.intensity=60.0"])
    C.equal(harness.max_diff(img, px)[0], 0, "afterwards a new client's image equals relight preview")
    c.disconnect()


def crowd(d, n=64):
    C.section = "crowd"
    results = [None] * n
    barrier = threading.Barrier(n)

    def one(i):
        try:
            barrier.wait(30)
            c = relight.Client(d.url, timeout=WAIT)
            shots_listed = [s["name"] for s in c.list()]
            o = c.open("lights32")
            img = c.wait(o["edit"], 3)
            results[i] = ("lights32" in shots_listed, img.copy())
            c.disconnect()
        except Exception as e:
            results[i] = ("error", repr(e))

    t0 = time.monotonic()
    threads = [threading.Thread(target=one, args=(i,)) for i in range(n)]
    for t in threads:
        t.start()
    for t in threads:
        t.join(WAIT * 2)
    errs = [r for r in results if r is None or r[0] is not True]
    C.check(not errs, "%d clients at once: hello, list, open and the final level" % n,
            "%d failed, e.g. %r" % (len(errs), errs[:2]))
    imgs = set(r[1] for r in results if r and r[0] is True)
    C.equal(len(imgs), 1, "all %d got the same image" % n)
    C.note("%d clients served in %.1f s" % (n, time.monotonic() - t0))


def slow_reader(d, edits=200):
    C.section = "slow reader"
    ed = d.client(timeout=WAIT)
    o = ed.open("shadows")
    ed.wait(o["edit"], 3)
    ed.wait(ed.set("2", intensity=50), 3)
    rss0 = d.rss_kb()
    slow = d.ws()
    slow.send('{"op":"hello","version":1}')
    slow.recv(10)
    slow.send(json.dumps({"op": "open", "id": 1, "shot": "shadows", "format": "rgba16f"}))
    peak = [rss0]
    stop = threading.Event()

    def sample():
        while not stop.is_set():
            try:
                peak[0] = max(peak[0], d.rss_kb())
            except OSError:
                return
            time.sleep(0.01)
    t = threading.Thread(target=sample, daemon=True)
    t.start()
    t0 = time.monotonic()
    acked, first_levels, last = 0, 0, None
    try:
        for k in range(edits):
            v = 20 + (k % 50)
            last = ed.set("2", intensity=v)
            acked += 1
            ed.wait(last, 0 if k % 20 else 3)
            first_levels += 1
        ed.wait(last, 3)
    except Exception as e:
        C.check(False, "editor keeps working while a client does not read", repr(e))
    stop.set()
    t.join()
    took = time.monotonic() - t0
    growth_mb = (peak[0] - rss0) / 1024.0
    bound = 2 * CLIENT_QUEUE_MB + 64
    C.note("RSS %.0f MB before, peak %.0f MB (+%.1f MB) over %d edits in %.1f s"
           % (rss0 / 1024.0, peak[0] / 1024.0, growth_mb, edits, took))
    if d.sanitized():
        # ASan holds freed memory in its quarantine and caches: RSS says
        # nothing about the daemon's queues there.
        C.note("RSS bound not checked: relightd runs under AddressSanitizer")
    else:
        C.check(growth_mb <= bound, "RSS grows at most 2 x client queue + 64 MB = %d MB" % bound,
                "%.1f MB" % growth_mb)
    C.equal((acked, first_levels), (edits, edits), "every edit acked and its first level received")
    if last is not None:
        w, h, px = harness.preview_png(relight_exe, shots, "shadows",
                                       ["2.intensity=%r" % float(20 + ((edits - 1) % 50))])
        C.equal(harness.max_diff(ed.image.copy(), px)[0], 0, "editor's last image equals relight preview")
    dropped = d.metric("relight_tiles_dropped_total") or 0
    # What became of the slow client: its queue dropped superseded tiles, or it was closed.
    closed = None
    try:
        while True:
            slow.recv(2)
    except relight.ConnectionClosed as e:
        closed = e.code
    except (TimeoutError, relight.ProtocolError):
        pass
    C.note("slow client: %s; relight_tiles_dropped_total %d"
           % ("closed with %s" % closed if closed else "still open", dropped))
    C.check(dropped > 0 or closed is not None,
            "superseded tiles were dropped or the slow client was closed")
    slow.abort()
    ed.disconnect()


def big_frames(d):
    C.section = "max message"
    ws = d.ws()
    ws.send('{"op":"hello","version":1}')
    limit = json.loads(ws.recv(10))["limits"]["max_message"]
    head = '{"op":"list","id":9,"pad":"'
    exact = head + "x" * (limit - len(head) - 2) + '"}'
    C.equal(len(exact), limit, "test frame is exactly the limit")
    ws.send(exact)
    try:
        r = json.loads(ws.recv(10))
        C.equal((r.get("op"), r.get("id")), ("shots", 9), "a frame of exactly max_message is served")
    except relight.ConnectionClosed as e:
        C.check(False, "a frame of exactly max_message is served", "closed with %d" % e.code)
    ws.send(exact[:-2] + 'x"}')
    try:
        m = ws.recv(10)
        C.check(False, "one byte over max_message closes with 1009", "got %r" % m[:100])
    except relight.ConnectionClosed as e:
        C.equal(e.code, 1009, "one byte over max_message closes with 1009")
    except TimeoutError:
        C.check(False, "one byte over max_message closes with 1009", "no answer in 10 s")
    ws.abort()
    # The same size in 16 KB fragments: a message over the limit, however sent.
    ws = d.ws()
    ws.send('{"op":"hello","version":1}')
    ws.recv(10)
    ws.send(exact[:-2] + 'x"}', fragment=16384)
    try:
        m = ws.recv(10)
        C.check(False, "a fragmented message over max_message closes with 1009", "got %r" % m[:100])
    except relight.ConnectionClosed as e:
        C.equal(e.code, 1009, "a fragmented message over max_message closes with 1009")
    except TimeoutError:
        C.check(False, "a fragmented message over max_message closes with 1009", "no answer in 10 s")
    ws.abort()
    healthy(d, "after big frames")


def main():
    d = harness.Daemon(relightd, shots, ["--client-queue", str(CLIENT_QUEUE_MB)])
    C.run(fuzz_text, d)
    C.run(fuzz_frames, d)
    C.section = "after fuzz"
    C.run(served_correctly, d, "after 10,000 bad messages")
    healthy(d, "after fuzz")
    C.run(vanishing, d)
    C.run(crowd, d)
    C.run(slow_reader, d)
    C.run(big_frames, d)
    C.section = "end"
    C.run(served_correctly, d, "at the end", "5", 0.21)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
