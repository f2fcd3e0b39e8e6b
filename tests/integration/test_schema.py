"""The JSON Schemas of protocol/schema/ hold to the codec and to relightd.

Checks (none with a tolerance: verdicts and names are exact):
  - the schemas load in validate.py, which refuses a keyword it does not
    know; request.schema.json has one branch per op of proto.c's table and
    reply.schema.json's error codes are proto.c's and the README's;
  - a table of requests, valid and not (wrong types, missing members, out of
    range, too many values, too long): request.schema.json and the codec
    (proto_check, the codec alone) agree on every one, and the codec refuses
    each bad one with the code the table names. The few frames the two
    cannot judge alike are listed apart with the reason, and each side's
    verdict on them is checked as stated;
  - a session with relightd (hello, list, open of a RIB that bakes, set,
    mute, solo, freeze, add_light, remove_light, snapshot, stats, close, an
    rgba16f open, errors; the Python client and raw WebSockets, with and
    without ids): every text frame the daemon sends is UTF-8 JSON valid
    against reply.schema.json, every op seen has a branch and every branch
    is seen; ids come back exactly, 2^53 included;
  - names the daemon echoes stay valid messages: non-ASCII names cut short
    in error messages, and the level events of a shot with a name of the
    longest length allowed (128).
"""

import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
import threading
import time

# Leave no compiled files in the source tree (validate.py is imported from it).
sys.dont_write_bytecode = True
sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

sys.path.insert(0, os.path.join(harness.SOURCE_DIR, "protocol", "schema"))
import validate  # noqa: E402

C = harness.Checks("schema")
relightd, relight_exe = harness.args()
SCHEMA_DIR = os.path.join(harness.SOURCE_DIR, "protocol", "schema")
WAIT = 60            # seconds for a reply or a level (llvmpipe under ASan)
FINAL = 3


def proto_check_path():
    """The proto_check program of this build (tests/integration/ of the build folder)."""
    roots = [os.environ.get("RELIGHT_BUILD_DIR"),
             os.path.dirname(os.path.dirname(os.path.dirname(relightd)))]
    for root in roots:
        if root:
            p = os.path.join(root, "tests", "integration", "proto_check")
            if os.access(p, os.X_OK):
                return p
    sys.exit("proto_check is not built (looked in %s)" % ", ".join(r for r in roots if r))


def tags(schema):
    """The op of each branch of a schema's top-level oneOf."""
    out = []
    for alt in schema.root["oneOf"]:
        branch = schema.root["$defs"][alt["$ref"].rsplit("/", 1)[1]]
        out.append(branch["properties"]["op"]["const"])
    return out


# ---------------------------------------------------------------------------
# The schemas and the sources they describe
# ---------------------------------------------------------------------------


def schemas_and_sources():
    C.section = "schemas"
    req = validate.load_schema(os.path.join(SCHEMA_DIR, "request.schema.json"))
    rep = validate.load_schema(os.path.join(SCHEMA_DIR, "reply.schema.json"))
    with open(os.path.join(harness.SOURCE_DIR, "protocol", "proto.c")) as f:
        proto_c = f.read()
    ops = re.findall(r'\[PROTO_\w+\] = "(\w+)"', proto_c)
    C.equal(sorted(tags(req)), sorted(ops), "request.schema.json has one branch per op of proto.c")
    body = proto_c[proto_c.index("const char *proto_error_name"):]
    body = body[:body.index("\n}\n")]
    codes = re.findall(r'return "(\w+)";', body)
    codes = [c for c in codes if c != "internal"] + ["internal"]
    error = rep.root["$defs"]["error"]["properties"]["code"]["enum"]
    C.equal(sorted(error), sorted(set(codes)), "reply.schema.json's error codes are proto.c's")
    with open(os.path.join(harness.SOURCE_DIR, "protocol", "README.md")) as f:
        readme = f.read()
    table = readme[readme.index("### Errors"):]
    table = table[:table.index("\n## ")]
    documented = set()
    for line in table.splitlines():
        if line.startswith("| `"):
            documented.update(re.findall(r"`(\w+)`", line.split("|")[1]))
    C.equal(sorted(error), sorted(documented), "reply.schema.json's error codes are the README's")

    # The validator refuses what it cannot check, rather than passing it by.
    for kw in ({"patternProperties": {"^a": {}}}, {"format": "email"}, {"properties": {"a": {"multipleOf": 2}}},
               {"$ref": "other.json#/x"}, {"$ref": "#/$defs/missing"}):
        try:
            validate.Schema(kw)
            C.check(False, "validate.py refuses the schema %s" % json.dumps(kw))
        except validate.SchemaError:
            C.check(True, "validate.py refuses the schema %s" % json.dumps(kw))
    # pattern is searched, as JSON Schema has it.
    s = validate.Schema({"type": "string", "pattern": "^[a-z]+$"})
    C.check(s.is_valid("abc") and not s.is_valid("a/b") and not s.is_valid(""),
            "validate.py checks pattern")
    # It tells numbers exactly and booleans from numbers.
    s = validate.Schema({"type": "integer", "maximum": 9007199254740992})
    C.check(s.is_valid(validate.loads("9007199254740992")) and s.is_valid(validate.loads("1e3"))
            and not s.is_valid(validate.loads("9007199254740993"))
            and not s.is_valid(validate.loads("true")) and not s.is_valid(validate.loads("2.5")),
            "validate.py: integers exactly (2^53 in, 2^53+1 out, 1e3 an integer, true not)")
    C.check(validate.Schema({"const": 1}).is_valid(validate.loads("1.0"))
            and not validate.Schema({"const": 1}).is_valid(True)
            and not validate.Schema({"enum": [False]}).is_valid(0),
            "validate.py: const and enum compare numbers by value, booleans apart")
    for text in ('{"a":1,"a":2}', '{"a":NaN}', '[Infinity]'):
        try:
            validate.loads(text)
            C.check(False, "validate.loads refuses %s" % text)
        except ValueError:
            C.check(True, "validate.loads refuses %s" % text)
    # The command line: valid, invalid, not JSON.
    tool = os.path.join(SCHEMA_DIR, "validate.py")
    schema = os.path.join(SCHEMA_DIR, "request.schema.json")
    for text, want, what in (('{"op":"list","id":1}', 0, "a valid request"),
                             ('{"op":"set","light":"2","params":{}}', 1, "an invalid one"),
                             ('{"op":', 2, "text that is not JSON")):
        r = subprocess.run([sys.executable, tool, schema, "-"], input=text.encode(),
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=30)
        C.equal(r.returncode, want, "validate.py on %s exits %d" % (what, want))
        if want == 1:
            C.check(b"<stdin>:1: error: /params:" in r.stderr,
                    "validate.py names the place of the error", r.stderr.decode()[:200])
    return req, rep


# ---------------------------------------------------------------------------
# Requests: the schema against the codec
# ---------------------------------------------------------------------------


def nums(n, v=1):
    return "[" + ",".join(str(v + i) for i in range(n)) + "]"


def params(n):
    return "{" + ",".join('"p%d":%d' % (i, i) for i in range(n)) + "}"


A256, A257 = "a" * 256, "a" * 257
SET = '{"op":"set","light":"2","params":{"a":%s}}'

# (frame, the codec's verdict): "ok" or the code of its error. The schema
# must accept exactly the "ok" ones.
REQUESTS = [
    # hello
    ('{"op":"hello","version":1}', "ok"),
    ('{"op":"hello","version":1,"token":"secret-token"}', "ok"),
    ('{"op":"hello","version":1.0}', "ok"),
    ('{"op":"hello","version":1,"token":null}', "ok"),
    ('{"op":"hello","version":1,"token":""}', "ok"),
    ('{"op":"hello","version":1,"token":"%s"}' % A256, "ok"),
    ('{"op":"hello"}', "type"),
    ('{"op":"hello","version":"1"}', "type"),
    ('{"op":"hello","version":true}', "type"),
    ('{"op":"hello","version":1.5}', "type"),
    ('{"op":"hello","version":-1}', "type"),
    ('{"op":"hello","version":2}', "range"),
    ('{"op":"hello","version":0}', "range"),
    ('{"op":"hello","version":1,"token":5}', "type"),
    ('{"op":"hello","version":1,"token":"%s"}' % A257, "limit"),
    # frames that are no request at all
    ('[]', "malformed"),
    ('"list"', "malformed"),
    ('{}', "malformed"),
    ('{"op":5}', "malformed"),
    ('{"op":null}', "malformed"),
    ('{"op":["list"]}', "malformed"),
    ('{"op":"LIST"}', "unknown_op"),
    ('{"op":"bogus","id":3}', "unknown_op"),
    ('{"op":""}', "unknown_op"),
    # ids, and members nobody knows
    ('{"op":"list"}', "ok"),
    ('{"op":"list","id":0}', "ok"),
    ('{"op":"list","id":-0}', "ok"),
    ('{"op":"list","id":1e3}', "ok"),
    ('{"op":"list","id":9007199254740992}', "ok"),
    ('{"op":"list","id":-9007199254740992}', "ok"),
    ('{"op":"list","future":{"x":[1,"y",null]},"more":true}', "ok"),
    (' \r\n\t{"op":"list"}\n ', "ok"),
    ('{"op":"list","id":1.5}', "type"),
    ('{"op":"list","id":"1"}', "type"),
    ('{"op":"list","id":null}', "type"),
    ('{"op":"list","id":true}', "type"),
    ('{"op":"list","id":[1]}', "type"),
    ('{"op":"list","id":9007199254740994}', "type"),
    ('{"op":"list","id":-9007199254740994}', "type"),
    ('{"op":"list","id":1e300}', "type"),
    ('{"op":"list","id":1e400}', "type"),
    ('{"op":"close","id":0.5}', "type"),
    ('{"op":"stats","id":{}}', "type"),
    ('{"op":"bogus","id":0.5}', "type"),
    # open
    ('{"op":"open","shot":"shadows"}', "ok"),
    ('{"op":"open","shot":"shadows","format":"rgba8","id":2}', "ok"),
    ('{"op":"open","shot":"shadows","format":"rgba16f"}', "ok"),
    ('{"op":"open","shot":"shadows","format":null}', "ok"),
    ('{"op":"open","shot":"%s"}' % A256, "ok"),
    ('{"op":"open","shot":"%s"}' % ("\u00e9" * 128), "ok"),
    ('{"op":"open"}', "type"),
    ('{"op":"open","shot":""}', "type"),
    ('{"op":"open","shot":null}', "type"),
    ('{"op":"open","shot":5}', "type"),
    ('{"op":"open","shot":"%s"}' % A257, "limit"),
    ('{"op":"open","shot":"s","format":"rgb"}', "range"),
    ('{"op":"open","shot":"s","format":"RGBA8"}', "range"),
    ('{"op":"open","shot":"s","format":""}', "range"),
    ('{"op":"open","shot":"s","format":16}', "type"),
    ('{"op":"open","shot":"s","format":"%s"}' % A257, "limit"),
    # set and parameter values
    ('{"op":"set","light":"2","params":{"intensity":2}}', "ok"),
    ('{"op":"set","light":"2","params":{"from":[1,2,3],"intensity":0.5},"id":4}', "ok"),
    (SET % nums(1), "ok"),
    (SET % nums(16), "ok"),
    (SET % "3.4e38", "ok"),
    (SET % "-3.4e38", "ok"),
    (SET % "[1e-45,-0.0,1E+2]", "ok"),
    ('{"op":"set","light":"2","params":%s}' % params(64), "ok"),
    ('{"op":"set","light":"2","params":{"%s":1}}' % A256, "ok"),
    ('{"op":"set","light":"%s","params":{"a":1}}' % A256, "ok"),
    ('{"op":"set","light":"2"}', "type"),
    ('{"op":"set","params":{"a":1}}', "type"),
    ('{"op":"set","light":"","params":{"a":1}}', "type"),
    ('{"op":"set","light":2,"params":{"a":1}}', "type"),
    ('{"op":"set","light":"%s","params":{"a":1}}' % A257, "limit"),
    ('{"op":"set","light":"2","params":{}}', "type"),
    ('{"op":"set","light":"2","params":null}', "type"),
    ('{"op":"set","light":"2","params":[1]}', "type"),
    ('{"op":"set","light":"2","params":"intensity=1"}', "type"),
    (SET % '"x"', "ok"),
    (SET % ('"%s"' % ("m" * 4095)), "ok"),
    (SET % ('"%s"' % ("m" * 4096)), "range"),
    (SET % "true", "type"),
    (SET % "null", "type"),
    (SET % "{}", "type"),
    (SET % "[1,\"x\"]", "type"),
    (SET % "[1,[2]]", "type"),
    (SET % "[1,null]", "type"),
    (SET % "[]", "range"),
    (SET % nums(17), "range"),
    (SET % "3.5e38", "range"),
    (SET % "-1e39", "range"),
    (SET % "[1,1e400]", "range"),
    (SET % "1e400", "range"),
    ('{"op":"set","light":"2","params":{"":1}}', "type"),
    ('{"op":"set","light":"2","params":{"%s":1}}' % A257, "type"),
    ('{"op":"set","light":"2","params":%s}' % params(65), "limit"),
    # add_light, remove_light
    ('{"op":"add_light","light":"k","shader":"pointlight"}', "ok"),
    ('{"op":"add_light","light":"k","shader":"pointlight","params":{}}', "ok"),
    ('{"op":"add_light","light":"k","shader":"pointlight","params":{"from":[0,1,0]}}', "ok"),
    ('{"op":"add_light","light":"k"}', "type"),
    ('{"op":"add_light","shader":"pointlight"}', "type"),
    ('{"op":"add_light","light":"k","shader":""}', "type"),
    ('{"op":"add_light","light":"k","shader":"%s"}' % A257, "limit"),
    ('{"op":"add_light","light":"k","shader":"../../tmp/evil"}', "range"),
    ('{"op":"add_light","light":"k","shader":"/tmp/evil"}', "range"),
    ('{"op":"add_light","light":"k","shader":"evil.sl"}', "range"),
    ('{"op":"add_light","light":"k","shader":"_spot2"}', "ok"),
    ('{"op":"add_light","light":"k","shader":"s","params":null}', "type"),
    ('{"op":"add_light","light":"k","shader":"s","params":{"a":[]}}', "range"),
    ('{"op":"add_light","light":"k","shader":"s","params":%s}' % params(65), "limit"),
    ('{"op":"remove_light","light":"k"}', "ok"),
    ('{"op":"remove_light"}', "type"),
    ('{"op":"remove_light","light":7}', "type"),
    ('{"op":"remove_light","light":null}', "type"),
    # solo, mute, freeze
    ('{"op":"solo","light":"2"}', "ok"),
    ('{"op":"solo"}', "ok"),
    ('{"op":"solo","light":null}', "ok"),
    ('{"op":"solo","light":""}', "ok"),
    ('{"op":"solo","light":5}', "type"),
    ('{"op":"solo","light":false}', "type"),
    ('{"op":"solo","light":"%s"}' % A257, "limit"),
    ('{"op":"mute","light":"2"}', "ok"),
    ('{"op":"mute","light":"2","mute":false}', "ok"),
    ('{"op":"mute"}', "type"),
    ('{"op":"mute","light":"2","mute":1}', "type"),
    ('{"op":"mute","light":"2","mute":null}', "type"),
    ('{"op":"mute","light":"2","mute":"true"}', "type"),
    ('{"op":"freeze","light":"2"}', "ok"),
    ('{"op":"freeze","light":"2","freeze":false,"id":9}', "ok"),
    ('{"op":"freeze"}', "type"),
    ('{"op":"freeze","light":"2","freeze":0}', "type"),
    ('{"op":"freeze","light":"","freeze":true}', "type"),
    # the requests without members
    ('{"op":"close"}', "ok"),
    ('{"op":"snapshot","id":5}', "ok"),
    ('{"op":"stats","id":6}', "ok"),
    ('{"op":"pick","x":0,"y":0}', "ok"),
    ('{"op":"pick","id":7,"x":2147483647,"y":12}', "ok"),
    ('{"op":"pick","x":1}', "type"),
    ('{"op":"pick","x":1.5,"y":0}', "type"),
    ('{"op":"pick","x":-1,"y":0}', "range"),
    ('{"op":"pick","x":2147483648,"y":0}', "range"),
    ('{"op":"pick","x":"1","y":0}', "type"),
]

# Frames the schema and the codec cannot judge alike, each with the codec's
# verdict, the schema's (None: Python's JSON reader refuses the text, so no
# schema ever sees it) and the reason.
APART = [
    # The text itself: a schema sees parsed values, not bytes.
    (b'{"op":"list","x":"\xff"}', "malformed", None,
     "not UTF-8: the codec refuses it, no JSON reader gets as far as a schema"),
    (b'{"op":"list","x":"a\\u0000b"}', "malformed", True,
     "an escaped NUL is a fine JSON string; the codec refuses it, C strings would cut it"),
    (b'{"op":"list"} {"op":"list"}', "malformed", None,
     "two objects in one frame: not one JSON text"),
    (b'{"op":"list","op":"bogus"}', "malformed", None,
     "a repeated member: the codec refuses it as malformed, validate.loads refuses the text"),
    # Numbers: the codec reads them as doubles, the schema exactly.
    (b'{"op":"list","id":9007199254740993}', "ok", False,
     "2^53+1 rounds to 2^53 as a double"),
    (b'{"op":"hello","version":1.0000000000000001}', "ok", False,
     "rounds to 1.0 as a double"),
    (('{"op":"set","light":"2","params":{"a":3.40000000000000000001e38}}').encode(), "ok", False,
     "rounds to 3.4e38 as a double"),
    # Lengths: the codec counts bytes of UTF-8, JSON Schema characters.
    (('{"op":"open","shot":"%s"}' % ("\u00e9" * 129)).encode(), "limit", True,
     "129 characters of 2 bytes: 258 bytes, over the codec's 256"),
    (('{"op":"set","light":"2","params":{"%s":1}}' % ("\u00e9" * 200)).encode(), "type", True,
     "a parameter name of 200 characters, 400 bytes"),
]


def requests_vs_codec(req):
    C.section = "requests"
    checker = proto_check_path()
    frames = [f.encode() for f, _ in REQUESTS] + [f for f, _, _, _ in APART]
    tmp = tempfile.mkdtemp(prefix="schema-", dir=harness.build_dir())
    try:
        paths = []
        for i, f in enumerate(frames):
            p = os.path.join(tmp, "%03d.json" % i)
            with open(p, "wb") as out:
                out.write(f)
            paths.append(p)
        r = subprocess.run([checker] + paths, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=60)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    lines = r.stdout.decode(errors="replace").splitlines()
    if not C.check(r.returncode == 0 and len(lines) == len(frames),
                   "proto_check judges every frame",
                   "status %d, %d lines for %d frames: %s" % (r.returncode, len(lines),
                                                              len(frames), r.stderr[:300])):
        return
    verdicts = [ln.split("\t")[0].split(" ")[0] for ln in lines]

    agree, accepted = 0, 0
    for (frame, want), got, line in zip(REQUESTS, verdicts, lines):
        shown = frame if len(frame) < 90 else frame[:80] + "..."
        C.equal(got, want, "the codec on %s" % shown)
        errors = req.errors(validate.loads(frame))
        ok = C.check((not errors) == (want == "ok"),
                     "the schema %s %s" % ("accepts" if want == "ok" else "refuses", shown),
                     "; ".join(errors[:3]) if errors else "it accepts it")
        agree += ok
        accepted += want == "ok"
    for (frame, want, schema_ok, why), got in zip(APART, verdicts[len(REQUESTS):]):
        shown = frame.decode(errors="replace")[:80]
        C.equal(got, want, "the codec on %s (%s)" % (shown, why))
        try:
            doc = validate.loads(frame.decode("utf-8"))
            verdict = not req.errors(doc)
        except ValueError:
            verdict = None
        C.equal(verdict, schema_ok, "the schema on %s (%s)" % (shown, why))
    C.note("%d requests (%d valid): schema and codec agree on %d; %d judged apart as stated"
           % (len(REQUESTS), accepted, agree, len(APART)))


# ---------------------------------------------------------------------------
# Replies: a session with relightd
# ---------------------------------------------------------------------------

FRAMES = []          # (section, text or None, why it is no text)
FRAMES_LOCK = threading.Lock()
_recv = relight.WebSocket.recv


def _recording_recv(self, timeout=None):
    """WebSocket.recv that keeps every text frame (the client's reader thread
    and raw sockets alike), and notes a text frame that was no UTF-8."""
    try:
        msg = _recv(self, timeout)
    except relight.ProtocolError as e:
        with FRAMES_LOCK:
            FRAMES.append((C.section, None, str(e)))
        raise
    if isinstance(msg, str):
        with FRAMES_LOCK:
            FRAMES.append((C.section, msg, None))
    return msg


relight.WebSocket.recv = _recording_recv


def next_text(ws, timeout=WAIT):
    """The next text frame on a raw WebSocket, as a dict (tiles skipped)."""
    deadline = time.monotonic() + timeout
    while True:
        m = ws.recv(max(0.01, deadline - time.monotonic()))
        if isinstance(m, str):
            return json.loads(m)


def raw_session(d):
    """Requests with and without ids, before and after hello, on a raw socket."""
    C.section = "raw"
    ws = d.ws(timeout=WAIT)
    ws.send('{"op":"list","id":-9007199254740992}')
    m = next_text(ws)
    C.equal((m.get("op"), m.get("code"), m.get("id")), ("error", "auth", -9007199254740992),
            "a request before hello: an auth error with the id, -2^53 exactly")
    ws.send(b"\x00binary")
    m = next_text(ws)
    C.equal((m.get("op"), m.get("code"), "id" in m), ("error", "malformed", False),
            "a binary frame: a malformed error, no id")
    ws.send('{"op":"hello","version":1}')
    m = next_text(ws)
    C.equal((m.get("op"), "id" in m), ("hello", False), "hello without an id: no id back")
    ws.send('{"op":"list"}')
    m = next_text(ws)
    listed = {s.get("name"): s for s in m.get("shots", [])}
    C.equal(listed.get("lights32"), {"name": "lights32", "width": 0, "height": 0, "baked": False},
            "list: a RIB not baked yet is listed 0x0, not baked")
    ws.send('{"op":"stats"}')
    m = next_text(ws)
    C.equal((m.get("op"), "shot" in m, "id" in m), ("stats", False, False),
            "stats with no shot open: no shot, no id")
    ws.send('{"op":"close","id":9007199254740992}')
    m = next_text(ws)
    C.equal((m.get("op"), m.get("id")), ("closed", 9007199254740992),
            "close: closed, the id 2^53 back exactly")
    ws.send("not JSON")
    m = next_text(ws)
    C.equal((m.get("op"), m.get("code")), ("error", "malformed"), "text that is not JSON")
    ws.send('{"op":"set","light":"2","params":{"intensity":1}}')
    m = next_text(ws)
    C.equal((m.get("op"), m.get("code"), "id" in m), ("error", "state", False),
            "set with no shot open: a state error, no id")
    ws.close(wait=2)


def client_session(d):
    """The Python client through every request, the errors among them."""
    C.section = "session"
    c = d.client(timeout=WAIT)
    c.list()
    c.stats()
    progress = []
    o = c.open("lights32", on_progress=progress.append)
    C.check(len(progress) >= 1, "opening a RIB not baked sends progress", repr(progress[:2]))
    c.wait(o["edit"], FINAL)
    light = next((l["name"] for l in o["lights"]
                  if any(p["name"] == "intensity" for p in l["params"])), None)
    if not C.check(light is not None, "lights32 has a light with an intensity"):
        return
    e = c.set(light, intensity=0.25)
    c.wait(e, FINAL)
    # a string parameter takes a string (uberlight 35's slide: none), not numbers
    e = c.set("35", slidename="")
    c.wait(e, FINAL)
    C.raises(lambda: c.set("35", slidename=2), "type", "numbers for a string parameter")
    c.mute(light)
    c.unmute(light)
    c.solo(light)
    c.solo(None)
    c.freeze(light)
    c.unfreeze(light)
    c.add_light("extra", "pointlight", intensity=1.0, from_=[0, 1, 0])
    e = c.remove_light("extra")
    c.wait(e, FINAL)
    c.snapshot()
    c.pick(1, 1)
    C.raises(lambda: c.pick(1 << 20, 0), "range", "a pixel outside the image")
    s = c.stats()
    C.equal((s.get("shot"), s.get("edit")), ("lights32", e), "stats name the open shot and edit")
    C.raises(lambda: c.set("nope", intensity=1), "unknown_light", "set of an unknown light")
    C.raises(lambda: c.set(light, nope=1), "unknown_param", "set of an unknown parameter")
    C.raises(lambda: c.request("bogus"), "unknown_op", "an unknown op")
    C.raises(lambda: c.request("set", light=light, params={"intensity": "x"}), "type",
             "a string value for a float parameter")
    C.raises(lambda: c.request("set", light=light, params={"intensity": 1e39}), "range",
             "a value past a float")
    C.raises(lambda: c.request("hello", version=1), "state", "hello twice")
    C.raises(lambda: c.request("open", shot="s" * 300), "limit", "a shot name over 256 bytes")
    C.raises(lambda: c.open("nope"), "unknown_shot", "open of an unknown shot")
    o = c.open("shadows", format="rgba16f")
    c.wait(o["edit"], FINAL)
    c.close()
    C.raises(lambda: c.snapshot(), "state", "snapshot after close")
    c.disconnect()


def echoed_names(d):
    """Error messages quote the names of the request, cut to fit: still UTF-8."""
    C.section = "echoed names"
    cases = [
        ('{"op":"%s"}' % ("\u00e9" * 30), "unknown_op", None),
        ('{"op":"open","shot":"x%s"}' % ("\u00e9" * 40), "unknown_shot", None),
        ('{"op":"set","light":"xy%s","params":{"intensity":1}}' % ("\u00e9" * 120),
         "unknown_light", "lights32"),
    ]
    for text, code, shot in cases:
        ws = d.ws(timeout=WAIT)
        try:
            ws.send('{"op":"hello","version":1}')
            next_text(ws)
            if shot:
                ws.send('{"op":"open","shot":"%s"}' % shot)
                while next_text(ws).get("op") != "opened":
                    pass
            ws.send(text)
            m = next_text(ws)
            while m.get("op") == "level":
                m = next_text(ws)
            C.equal(m.get("code"), code, "%s... gets %s" % (text[:24], code))
        except relight.ProtocolError as e:
            C.check(False, "%s... gets a UTF-8 reply" % text[:24], str(e))
        except relight.ConnectionClosed as e:
            C.check(False, "%s... gets a reply" % text[:24], "closed %d %s" % (e.code, e.reason))
        finally:
            ws.abort()


def long_name(d, name):
    """A shot whose name has the longest length allowed: its level events."""
    C.section = "long shot name"
    ws = d.ws(timeout=WAIT)
    levels = []
    try:
        ws.send('{"op":"hello","version":1}')
        next_text(ws)
        ws.send('{"op":"open","shot":"%s"}' % name)
        deadline = time.monotonic() + WAIT
        while time.monotonic() < deadline and FINAL not in levels:
            m = ws.recv(max(0.01, deadline - time.monotonic()))
            if isinstance(m, str):
                try:
                    levels.append(json.loads(m).get("level"))
                except ValueError:
                    levels.append("not JSON")
                    break
        C.check(FINAL in levels, "the shot's levels come as level events", repr(levels[:5]))
    except (relight.ProtocolError, relight.ConnectionClosed, TimeoutError) as e:
        C.check(False, "the shot's levels come as level events", "%r after %r" % (e, levels[:5]))
    finally:
        ws.abort()


def check_frames(rep):
    C.section = "replies"
    branches = tags(rep)
    seen = {}
    with FRAMES_LOCK:
        frames = list(FRAMES)
    for section, text, why in frames:
        if text is None:
            C.check(False, "[%s] every text frame is UTF-8" % section, why)
            continue
        shown = text if len(text) < 160 else text[:150] + "..."
        try:
            msg = validate.loads(text)
        except ValueError as e:
            C.check(False, "[%s] every text frame is JSON" % section, "%s: %r" % (e, shown))
            continue
        op = msg.get("op") if isinstance(msg, dict) else None
        errors = rep.errors(msg)
        if C.check(not errors, "[%s] reply.schema.json accepts %s" % (section, shown),
                   "; ".join(errors[:4])):
            seen[op] = seen.get(op, 0) + 1
        C.check(op in branches, "[%s] the op %r has a branch in reply.schema.json" % (section, op))
    C.equal(sorted(o for o in branches if o not in seen), [],
            "every branch of reply.schema.json is seen in the session")
    C.note("%d text frames: %s" % (len(frames), ", ".join("%s %d" % kv
                                                        for kv in sorted(seen.items()))))


def replies(rep):
    shots = harness.bake_shots(relight_exe)
    tmp = tempfile.mkdtemp(prefix="schema-shots-", dir=harness.build_dir())
    d = None
    try:
        # The baked shadows (and its shadow maps), lights32 as a lone RIB that
        # opening bakes, and lights32's shot under the longest name allowed.
        for f in os.listdir(shots):
            if f.startswith("shadows.") or not f.endswith((".rib", ".shot.exr")):
                harness.link_or_copy(os.path.join(shots, f), os.path.join(tmp, f))
        shutil.copyfile(os.path.join(harness.SOURCE_DIR, "examples", "lights32", "lights32.rib"),
                        os.path.join(tmp, "lights32.rib"))
        longest = "n" * 128
        harness.link_or_copy(os.path.join(shots, "lights32.shot.exr"),
                             os.path.join(tmp, longest + ".shot.exr"))
        d = harness.Daemon(relightd, tmp)
        C.run(raw_session, d)
        C.run(client_session, d)
        C.run(echoed_names, d)
        C.run(long_name, d, longest)
        C.run(check_frames, rep)
        d.finish(C)
        d = None
    finally:
        if d is not None:
            d.stop(keep=True)
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    t0 = time.monotonic()
    r = C.run(schemas_and_sources)
    if r:
        req, rep = r
        C.run(requests_vs_codec, req)
        C.run(replies, rep)
    C.note("%.1f s" % (time.monotonic() - t0))
    C.finish()


if __name__ == "__main__":
    main()
