"""relightd's access control: tokens and roles, shot names, Origin.

Checks, each with its tolerance (none: exact):
  - with a token file: a request before hello, a hello without a token, a
    wrong token (and near misses: a prefix, the token with its role, the
    token with NUL and more after it, an empty one) each get an "auth"
    error (or "malformed" for the NUL) and then the connection is closed with 1008, within 5 s;
  - an editor token gives role editor (also with the role left out), a
    viewer token role viewer; a viewer can list and open and gets the
    tiles of the editor's edits (its final image equals the editor's byte
    for byte), but each of set, mute, solo, add_light, remove_light and
    freeze gets "forbidden" and changes nothing, and its connection stays;
  - shot names that leave the shots folder or are no names ("../shadows",
    "/etc/passwd", "a/b", "..", "shadows/../shadows", ...) get an error
    reply (unknown_shot, range or type), never "opened", even where a shot
    file exists at that path; the connection stays usable;
  - an Origin not in --allow-origin is refused at the handshake (an HTTP
    error, or the connection closed without a reply); a listed one and
    none at all are accepted;
  - refused connections are counted in relight_connections_refused_total;
  - relightd refuses to start on a token file with a token under 8 bytes.
"""

import json
import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("security")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)

EDITOR = "editor-token-1234"
VIEWER = "viewer-token-5678"
PLAIN = "plain-token-0000"
GOOD_ORIGIN = "http://good.example"
WAIT = 60


def expect_auth_close(d, first, what, codes=("auth",)):
    """Send `first` (a dict) as the first frame; expect an error (auth), then close 1008."""
    ws = d.ws()
    ws.send(json.dumps(first))
    reply, code = None, None
    try:
        while True:
            m = ws.recv(5)
            if isinstance(m, str) and reply is None:
                reply = json.loads(m)
    except relight.ConnectionClosed as e:
        code = e.code
    except TimeoutError:
        pass
    C.equal((reply or {}).get("op"), "error", what + ": error reply")
    C.check((reply or {}).get("code") in codes, what + ": code " + " or ".join(codes),
            "got %r" % (reply or {}).get("code"))
    C.equal(code, 1008, what + ": connection closed with 1008")
    ws.abort()


def auth(d):
    C.section = "auth"
    expect_auth_close(d, {"op": "list", "id": 1}, "request before hello")
    expect_auth_close(d, {"op": "hello", "version": 1}, "hello without a token")
    expect_auth_close(d, {"op": "hello", "version": 1, "token": "wrong-token-999"}, "wrong token")
    expect_auth_close(d, {"op": "hello", "version": 1, "token": EDITOR[:-1]}, "a prefix of a token")
    expect_auth_close(d, {"op": "hello", "version": 1, "token": EDITOR + " editor"},
                      "a token with its role")
    expect_auth_close(d, {"op": "hello", "version": 1, "token": ""}, "an empty token")
    # JSON strings may hold NUL: the token must not end at it (the codec
    # refuses any string with one as malformed).
    expect_auth_close(d, {"op": "hello", "version": 1, "token": EDITOR + "\u0000x"},
                      "a token followed by NUL and more", codes=("auth", "malformed"))
    try:
        relight.Client(d.url, token="nope-nope-nope", timeout=10)
        C.check(False, "Client() with a bad token raises ServerError auth")
    except relight.ServerError as e:
        C.equal(e.code, "auth", "Client() with a bad token raises ServerError auth")
    for i in range(30):
        try:
            relight.Client(d.url, token="guess-%08d" % i, timeout=10)
        except relight.ServerError:
            pass
    refused = d.metric("relight_connections_refused_total")
    C.check(refused is not None and refused >= 38, "refused connections counted (>= 38)",
            repr(refused))
    C.check(d.alive(), "relightd alive after 38 refused clients")


def roles(d):
    C.section = "roles"
    ed = d.client(token=EDITOR, timeout=WAIT)
    C.equal(ed.role, "editor", "editor token")
    pl = d.client(token=PLAIN, timeout=WAIT)
    C.equal(pl.role, "editor", "token without a role is an editor")
    pl.disconnect()
    vw = d.client(token=VIEWER, timeout=WAIT)
    C.equal(vw.role, "viewer", "viewer token")
    C.check("shadows" in [s["name"] for s in vw.list()], "a viewer can list")
    eo = ed.open("shadows")
    ed.wait(eo["edit"], 3)
    vo = vw.open("shadows")
    C.equal((vo["width"], vo["height"]), (640, 360), "a viewer can open")
    vw.wait(vo["edit"], 3)
    C.equal(vw.image.copy(), ed.image.copy(), "the viewer's first image equals the editor's")
    before = ed.image.copy()
    for what, fn in (("set", lambda: vw.set("2", intensity=5)),
                     ("mute", lambda: vw.mute("2")),
                     ("solo", lambda: vw.solo("3")),
                     ("add_light", lambda: vw.add_light("x", "pointlight")),
                     ("remove_light", lambda: vw.remove_light("2")),
                     ("freeze", lambda: vw.freeze("2"))):
        C.raises(fn, "forbidden", "a viewer's %s is forbidden" % what)
    C.check(vw.connected and vw.list(), "the viewer's connection stays open")
    e = ed.set("2", intensity=45)
    ed.wait(e, 3)
    vw.wait(e, 3)
    C.equal(vw.image.copy(), ed.image.copy(), "the viewer gets the editor's edit, final level")
    C.check(vw.image.copy() != before, "the editor's edit changed the image")
    # The viewer's refused edits changed nothing: the editor's image is that
    # of its own edit alone.
    w, h, px = harness.preview_png(relight_exe, shots, "shadows", ["2.intensity=45.0"])
    C.equal(harness.max_diff(ed.image.copy(), px)[0], 0,
            "the image is relight preview's with the editor's edit alone")
    vw.disconnect()
    ed.disconnect()


def names(d):
    C.section = "shot names"
    c = d.client(token=EDITOR, timeout=WAIT)
    listed = [s["name"] for s in c.list()]
    C.check("outside" not in listed and "shadows" in listed,
            "list shows the shots folder only", repr(listed))
    for name in ("../shadows", "../outside", "/etc/passwd", "a/b", "..", ".", "shadows/../shadows",
                 "", ".hidden", "shadows\x00", "..\\outside", "%2e%2e/outside", "~root",
                 os.path.join(d.shots, "shadows"), "shadows/", "x" * 129):
        try:
            r = c.open(name)
            C.check(False, "open %r refused" % name, "opened %r" % r.get("shot"))
        except relight.ServerError as e:
            C.check(e.code in ("unknown_shot", "range", "type", "limit", "malformed"),
                    "open %r refused" % name, "code %s: %s" % (e.code, e.message))
    C.check(c.connected and c.list(), "the connection stays usable")
    o = c.open("shadows")
    C.equal(o.get("shot"), "shadows", "a good name still opens")
    c.disconnect()


def origins(d):
    C.section = "origin"
    try:
        ws = d.ws(origin="http://evil.example")
        C.check(False, "a foreign Origin is refused at the handshake")
        ws.abort()
    except relight.HandshakeError as e:
        # An HTTP error or the connection closed without a reply (status 0).
        C.check(e.status != 101, "a foreign Origin is refused at the handshake",
                "status %d" % e.status)
        if e.status == 0:
            C.note("a foreign Origin: the connection is closed without an HTTP reply")
    for origin in (GOOD_ORIGIN, None):
        try:
            ws = d.ws(origin=origin)
            ws.send(json.dumps({"op": "hello", "version": 1, "token": EDITOR}))
            C.equal(json.loads(ws.recv(10)).get("role"), "editor", "Origin %r is accepted" % origin)
            ws.close(1000, wait=2)
        except relight.Error as e:
            C.check(False, "Origin %r is accepted" % origin, repr(e))


def bad_token_file():
    C.section = "token file"
    tmp = tempfile.mkdtemp(prefix="tokens-", dir=harness.build_dir())
    try:
        path = os.path.join(tmp, "tokens")
        with open(path, "w") as f:
            f.write("%s editor\nshort viewer\n" % EDITOR)
        r = subprocess.run([relightd, "--listen", "127.0.0.1:0", "--shots", shots,
                            "--token-file", path], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=30)
        err = r.stderr.decode(errors="replace")
        C.check(r.returncode not in (0, None) and path in err and ":2" in err,
                "a token under 8 bytes: relightd refuses to start, naming the file and line",
                "status %d, stderr %r" % (r.returncode, err[:300]))
        C.equal(r.stdout, b"", "nothing on stdout (no listening line)")
    except subprocess.TimeoutExpired:
        C.check(False, "relightd refuses a bad token file at once")
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def main():
    tmp = tempfile.mkdtemp(prefix="security-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    # The shot and its shadow map, and a shot file just outside the folder
    # that "../outside" would reach.
    for f in ("shadows.shot.exr", "key.shd"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own, f))
    harness.link_or_copy(os.path.join(shots, "shadows.shot.exr"), os.path.join(tmp, "outside.shot.exr"))
    d = harness.Daemon(relightd, own, ["--allow-origin", GOOD_ORIGIN],
                       tokens=[EDITOR + " editor", VIEWER + " viewer", PLAIN, "# a comment", ""])
    C.run(auth, d)
    C.run(roles, d)
    C.run(names, d)
    C.run(origins, d)
    d.finish(C)
    C.run(bad_token_file)
    shutil.rmtree(tmp, ignore_errors=True)
    C.finish()


if __name__ == "__main__":
    main()
