"""The Python client's WebSocket and relight layers, without relightd.

Frames are checked against the byte strings of RFC 6455 section 5.7 and
hand-made ones; the client's side of a conversation is checked against a
scripted server in this file (its own frame reader, so that the client's
encoder is not checked against itself): handshake fields, masking,
fragmentation both ways, ping/pong, close codes, tiles into the image,
superseded tiles dropped, errors raised as ServerError.

Usage: python3 test_client_unit.py [RELIGHTD RELIGHT] (both ignored).
"""

import base64
import hashlib
import json
import os
import queue
import socket
import ssl
import struct
import sys
import threading
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("client-unit")
H = bytes.fromhex


# ---------------------------------------------------------------------------
# Frames
# ---------------------------------------------------------------------------

def frames_section():
    C.section = "frames"
    enc = relight.encode_frame
    key = H("37fa213d")
    # RFC 6455 5.7
    C.equal(enc(relight.OP_TEXT, b"Hello", mask=False), H("810548656c6c6f"), "unmasked text")
    C.equal(enc(relight.OP_TEXT, b"Hello", mask=key), H("818537fa213d7f9f4d5158"), "masked text")
    C.equal(enc(relight.OP_TEXT, b"Hel", fin=False, mask=False), H("010348656c"), "first fragment")
    C.equal(enc(relight.OP_CONTINUATION, b"lo", mask=False), H("80026c6f"), "last fragment")
    C.equal(enc(relight.OP_PING, b"Hello", mask=False), H("890548656c6c6f"), "ping")
    C.equal(enc(relight.OP_PONG, b"Hello", mask=key), H("8a8537fa213d7f9f4d5158"), "masked pong")
    C.equal(enc(relight.OP_BINARY, bytes(256), mask=False)[:4], H("827e0100"), "256-byte length")
    C.equal(enc(relight.OP_BINARY, bytes(65536), mask=False)[:10], H("827f0000000000010000"),
            "64 KiB length")
    C.equal(enc(relight.OP_BINARY, bytes(125), mask=False)[:2], H("827d"), "125: 7-bit length")
    C.equal(enc(relight.OP_BINARY, bytes(126), mask=False)[:4], H("827e007e"), "126: 16-bit length")
    C.equal(enc(relight.OP_BINARY, bytes(65535), mask=False)[:4], H("827effff"), "65535: 16-bit")
    C.equal(enc(relight.OP_TEXT, b"", mask=key), H("818037fa213d"), "empty masked frame")
    # A random key is fresh for every frame and really applied.
    a, b = enc(relight.OP_TEXT, b"x" * 40), enc(relight.OP_TEXT, b"x" * 40)
    C.check(a[2:6] != b[2:6], "random mask keys differ between frames")
    C.check(a[1] & 0x80 and a[6:] != b"x" * 40, "a default frame is masked")
    payload = os.urandom(1000)
    k = os.urandom(4)
    masked = relight.mask_payload(k, payload)
    C.check(all(masked[i] == payload[i] ^ k[i % 4] for i in range(1000)), "mask_payload XORs")
    C.equal(relight.mask_payload(k, masked), payload, "masking twice restores the payload")

    # The decoder, fed one byte at a time.
    stream = (H("810548656c6c6f") + H("010348656c") + H("890548656c6c6f") + H("80026c6f")
              + enc(relight.OP_BINARY, bytes(range(256)) * 300, mask=False))
    d = relight.FrameDecoder()
    got = []
    for i in range(len(stream)):
        d.feed(stream[i:i + 1])
        f = d.next()
        while f is not None:
            got.append(f)
            f = d.next()
    F = relight.Frame
    C.equal(got[:4], [F(True, 1, b"Hello"), F(False, 1, b"Hel"), F(True, 9, b"Hello"),
                      F(True, 0, b"lo")], "decoded frames")
    C.check(len(got) == 5 and got[4].payload == bytes(range(256)) * 300,
            "a 76800-byte frame (64-bit length) decoded")
    C.equal(d.buffered(), 0, "nothing left over")

    def refused(data, code, what, max_frame=1 << 30):
        d = relight.FrameDecoder(max_frame)
        d.feed(data)
        try:
            d.next()
        except relight.ProtocolError as e:
            return C.equal(e.code, code, what)
        return C.check(False, what, "accepted")
    refused(H("c10548656c6c6f"), 1002, "RSV1 set without an extension")
    refused(H("830548656c6c6f"), 1002, "reserved data opcode 3")
    refused(H("8b00"), 1002, "reserved control opcode 0xb")
    refused(H("818537fa213d7f9f4d5158"), 1002, "masked frame from a server")
    refused(H("897e007e") + bytes(126), 1002, "control frame of 126 bytes")
    refused(H("0900"), 1002, "fragmented ping")
    refused(H("827f8000000000000000"), 1002, "64-bit length with the top bit")
    refused(H("827e0400") + bytes(1024), 1009, "frame over max_frame", max_frame=1000)
    d = relight.FrameDecoder()
    d.feed(H("827e01"))
    C.check(d.next() is None, "a cut header waits for more bytes")

    # Close payloads.
    C.equal(relight.encode_close(1000, "bye"), b"\x03\xe8bye", "close payload")
    C.equal(relight.encode_close(None), b"", "close without a code")
    C.equal(len(relight.encode_close(1000, "x" * 300)), 125, "close reason cut to 125 bytes")
    C.equal(relight.decode_close(b""), (1005, ""), "empty close: 1005")
    C.equal(relight.decode_close(b"\x03\xf1too big"), (1009, "too big"), "1009 with a reason")
    C.equal(relight.decode_close(struct.pack("!H", 4000)), (4000, ""), "application code 4000")
    for bad, code, what in ((b"\x03", 1002, "1-byte close"), (struct.pack("!H", 999), 1002, "code 999"),
                            (struct.pack("!H", 1005), 1002, "code 1005 on the wire"),
                            (struct.pack("!H", 5000), 1002, "code 5000"),
                            (b"\x03\xe8\xff", 1007, "reason not UTF-8")):
        try:
            relight.decode_close(bad)
            C.check(False, what + " refused")
        except relight.ProtocolError as e:
            C.equal(e.code, code, what + " refused")


def handshake_section():
    C.section = "handshake"
    # RFC 6455 1.3
    C.equal(relight.accept_key("dGhlIHNhbXBsZSBub25jZQ=="), "s3pPLMBiTxaQ9kYGzzhZRbK+xOo=",
            "accept key of the RFC's example")
    C.equal(relight.parse_url("ws://h:7878/"), (False, "h", 7878, "/ws"), "path defaults to /ws")
    C.equal(relight.parse_url("ws://h:7878"), (False, "h", 7878, "/ws"), "no path")
    C.equal(relight.parse_url("wss://example.org/x?a=1"), (True, "example.org", 443, "/x?a=1"),
            "wss, default port, query kept")
    C.equal(relight.parse_url("http://[::1]:80/ws"), (False, "::1", 80, "/ws"), "IPv6 host")
    try:
        relight.parse_url("ftp://h/")
        C.check(False, "ftp:// refused")
    except ValueError:
        C.check(True, "ftp:// refused")
    req = relight.build_handshake("h:1", "/ws", "KEY", origin="http://o").decode()
    for line in ("GET /ws HTTP/1.1", "Host: h:1", "Upgrade: websocket", "Connection: Upgrade",
                 "Sec-WebSocket-Key: KEY", "Sec-WebSocket-Version: 13",
                 "Sec-WebSocket-Protocol: relight.v1", "Origin: http://o"):
        C.check(line + "\r\n" in req, "request has '%s'" % line)
    C.check(req.endswith("\r\n\r\n"), "request ends with a blank line")

    key = "dGhlIHNhbXBsZSBub25jZQ=="
    good = ("HTTP/1.1 101 Switching Protocols\r\nUpgrade: WebSocket\r\nConnection: keep-alive, Upgrade"
            "\r\nSec-WebSocket-Accept: s3pPLMBiTxaQ9kYGzzhZRbK+xOo=\r\nSec-WebSocket-Protocol: relight.v1")
    proto, hdrs = relight.check_handshake(good.encode(), key)
    C.equal(proto, "relight.v1", "a good reply is accepted")

    def bad(text, what, status=None):
        try:
            relight.check_handshake(text.encode(), key)
            C.check(False, what, "accepted")
        except relight.HandshakeError as e:
            C.check(status is None or e.status == status, what, "status %r" % e.status)
    bad(good.replace("s3pP", "AAAA"), "wrong accept key refused")
    bad(good.replace("Upgrade: WebSocket\r\n", ""), "missing Upgrade refused")
    bad(good.replace("keep-alive, Upgrade", "keep-alive"), "Connection without upgrade refused")
    bad(good.replace("relight.v1", "other"), "another subprotocol refused")
    bad(good.replace("\r\nSec-WebSocket-Protocol: relight.v1", ""), "no subprotocol refused")
    bad(good + "\r\nSec-WebSocket-Extensions: permessage-deflate", "unoffered extension refused")
    bad("HTTP/1.1 403 Forbidden\r\nContent-Length: 0", "HTTP 403 refused with its status", 403)
    bad("SSH-2.0-OpenSSH", "not HTTP refused")


def tiles_section():
    C.section = "tiles"

    def tile(edit, level, fmt, x, y, w, h, px, extra=0):
        return struct.pack("<4s8I", b"RLT1", 36, edit, level, fmt, x, y, w, h) + px + bytes(extra)
    img = relight.Image(5, 3, "rgba8")
    left = bytes(range(48))                    # 4x3 pixels
    right = bytes(range(100, 112))             # 1x3
    t = relight.parse_tile(tile(7, 2, 1, 0, 0, 4, 3, left))
    C.equal((t.edit, t.level, t.format, t.x, t.y, t.width, t.height), (7, 2, "rgba8", 0, 0, 4, 3),
            "header fields")
    img.put(t)
    img.put(relight.parse_tile(tile(7, 2, 1, 4, 0, 1, 3, right)))
    want = b"".join(left[r * 16:(r + 1) * 16] + right[r * 4:(r + 1) * 4] for r in range(3))
    C.equal(img.copy(), want, "two tiles assembled row by row")
    C.equal(img.pixel(4, 2), (108, 109, 110, 111), "pixel (4, 2)")
    C.equal(img.serial, 2, "serial counts tiles")
    h16 = relight.Image(2, 1, "rgba16f")
    h16.put(relight.parse_tile(tile(1, 0, 2, 0, 0, 2, 1, struct.pack("<8e", 1, .5, .25, 1, 0, 2, -1, 0))))
    C.equal(h16.pixel(1, 0), (0.0, 2.0, -1.0, 0.0), "half floats decoded")
    for data, what in ((b"RLT1" + bytes(20), "short frame"),
                       (tile(1, 0, 1, 0, 0, 1, 1, bytes(4)).replace(b"RLT1", b"RLT2"), "bad magic"),
                       (tile(1, 0, 3, 0, 0, 1, 1, bytes(4)), "unknown format"),
                       (tile(1, 0, 1, 0, 0, 1, 1, bytes(4), 1), "one byte too many"),
                       (tile(1, 0, 1, 0, 0, 2, 1, bytes(4)), "too few pixels"),
                       (tile(1, 0, 1, 0, 0, 0, 0, b""), "empty tile")):
        try:
            relight.parse_tile(data)
            C.check(False, what + " refused")
        except relight.ProtocolError:
            C.check(True, what + " refused")
    try:
        img.put(relight.parse_tile(tile(1, 0, 1, 4, 2, 2, 1, bytes(8))))
        C.check(False, "a tile past the image's edge refused")
    except relight.ProtocolError:
        C.check(True, "a tile past the image's edge refused")

    C.section = "params"
    C.equal(relight._params({"from": (1, 2, 3)}, {"intensity": 2, "to_": [0, 0, 1]}),
            {"from": [1.0, 2.0, 3.0], "intensity": 2, "to": [0.0, 0.0, 1.0]},
            "dict, keywords and the trailing underscore")
    for bad, what in (({"a": float("nan")}, "NaN"), ({"a": [1, float("inf")]}, "inf in a list"),
                      ({"a": list(range(17))}, "17 values"), ({"a": []}, "no value")):
        try:
            relight._params(bad, {})
            C.check(False, what + " refused before sending")
        except ValueError:
            C.check(True, what + " refused before sending")
    # A string is a string parameter's value (a map's name), sent as it is: the
    # daemon checks it against the parameter's type.
    C.equal(relight._params({"slidename": "b.tx"}, {}), {"slidename": "b.tx"},
            "a string value sent as a string")
    C.equal(relight._params({"a": "5"}, {}), {"a": "5"}, "a string of digits stays a string")
    try:
        relight._params({"a": "m" * 4096}, {})
        C.check(False, "a string over 4095 bytes refused before sending")
    except ValueError:
        C.check(True, "a string over 4095 bytes refused before sending")
    # Anything else that is not a number, nor a list of numbers: relight.Error.
    for bad, what in (({"a": [1, "2"]}, "[1, '2']"), ({"a": None}, "None"), ({"a": True}, "True")):
        try:
            got = relight._params(bad, {})
            C.check(False, "%s where a number is expected raises relight.Error" % what,
                    "sent as %r" % (got,))
        except relight.Error as e:
            C.check(isinstance(e, ValueError), what + ": the error is also a ValueError")
        except Exception as e:
            C.check(False, "%s where a number is expected raises relight.Error" % what,
                    "raised %r" % e)


# ---------------------------------------------------------------------------
# A scripted server
# ---------------------------------------------------------------------------

class Peer:
    """The server side of one connection, with its own frame reader."""

    def __init__(self, conn):
        self.conn = conn
        self.buf = b""
        self.conn.settimeout(10)

    def _need(self, n):
        while len(self.buf) < n:
            chunk = self.conn.recv(65536)
            if not chunk:
                raise EOFError("client closed")
            self.buf += chunk
        out, self.buf = self.buf[:n], self.buf[n:]
        return out

    def read_head(self):
        while b"\r\n\r\n" not in self.buf:
            chunk = self.conn.recv(4096)
            if not chunk:
                raise EOFError("client closed during the handshake")
            self.buf += chunk
        head, _, self.buf = self.buf.partition(b"\r\n\r\n")
        lines = head.decode().split("\r\n")
        hdr = {}
        for line in lines[1:]:
            k, _, v = line.partition(":")
            hdr[k.strip().lower()] = v.strip()
        return lines[0], hdr

    def accept(self, hdr, protocol="relight.v1", accept=None, extra=""):
        acc = accept or base64.b64encode(hashlib.sha1(
            hdr["sec-websocket-key"].encode() + b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11").digest()).decode()
        resp = ("HTTP/1.1 101 Switching Protocols\r\nUpgrade: websocket\r\nConnection: Upgrade\r\n"
                "Sec-WebSocket-Accept: %s\r\n" % acc)
        if protocol:
            resp += "Sec-WebSocket-Protocol: %s\r\n" % protocol
        self.conn.sendall((resp + extra + "\r\n").encode())

    def frame(self):
        """(fin, opcode, payload, masked) of the next frame, unmasked."""
        b0, b1 = self._need(2)
        n = b1 & 0x7F
        if n == 126:
            n = struct.unpack("!H", self._need(2))[0]
        elif n == 127:
            n = struct.unpack("!Q", self._need(8))[0]
        key = self._need(4) if b1 & 0x80 else None
        data = self._need(n)
        if key:
            data = bytes(c ^ key[i % 4] for i, c in enumerate(data))
        return bool(b0 & 0x80), b0 & 0x0F, data, key is not None

    def message(self):
        """The next data message (text decoded), answering nothing; checks masking."""
        parts, first = [], None
        while True:
            fin, op, data, masked = self.frame()
            if not masked:
                raise AssertionError("unmasked frame from the client")
            if op >= 8:
                return ("control", op, data)
            if first is None:
                first = op
            parts.append(data)
            if fin:
                break
        data = b"".join(parts)
        return ("text", json.loads(data.decode())) if first == 1 else ("binary", data)

    def request(self):
        kind, msg = self.message()[:2]
        if kind != "text":
            raise AssertionError("expected a text request, got %s" % kind)
        return msg

    def send(self, opcode, payload, fin=True):
        if isinstance(payload, str):
            payload = payload.encode()
        self.conn.sendall(relight.encode_frame(opcode, payload, fin, mask=False))

    def send_json(self, obj):
        self.send(1, json.dumps(obj))


class MockServer:
    """Accepts connections on 127.0.0.1 and runs `script(peer)` for each, in a thread.
    Exceptions of the script are kept in `errors`."""

    def __init__(self, script):
        self.script = script
        self.errors = []
        self.done = queue.Queue()
        self.sock = socket.socket()
        self.sock.bind(("127.0.0.1", 0))
        self.sock.listen(4)
        self.url = "ws://127.0.0.1:%d/ws" % self.sock.getsockname()[1]
        threading.Thread(target=self._serve, daemon=True).start()

    def _serve(self):
        conn, _ = self.sock.accept()
        try:
            self.script(Peer(conn))
        except Exception as e:
            self.errors.append(repr(e))
        finally:
            conn.close()
            self.sock.close()
            self.done.put(True)

    def wait(self, what):
        try:
            self.done.get(timeout=15)
        except queue.Empty:
            self.errors.append("script did not finish")
        C.check(not self.errors, what, "; ".join(self.errors))


def tile_frame(edit, level, x, y, w, h, value):
    return struct.pack("<4s8I", b"RLT1", 36, edit, level, 1, x, y, w, h) + bytes([value]) * (w * h * 4)


def conversation_section():
    C.section = "conversation"
    seen = {}

    def script(p):
        line, hdr = p.read_head()
        seen["line"] = line
        seen["hdr"] = hdr
        p.accept(hdr)
        hello = p.request()
        seen["hello"] = hello
        # The reply in three fragments with a ping between them: the client
        # must answer the ping with the same payload and reassemble the reply.
        text = json.dumps({"op": "hello", "version": 1, "role": "viewer", "server": "mock",
                           "limits": {"max_message": 65536, "tile_size": 4}})
        p.send(1, text[:10], fin=False)
        p.send(9, b"are you there")
        p.send(0, text[10:20], fin=False)
        p.send(0, text[20:])
        kind, op, data = p.message()
        seen["pong"] = (op, data)
        r = p.request()
        seen["list"] = r
        p.send_json({"op": "shots", "id": r["id"], "shots": [{"name": "s", "width": 5, "height": 3,
                                                              "baked": True}]})
        r = p.request()
        seen["open"] = r
        p.send_json({"op": "progress", "id": r["id"], "shot": "s", "fraction": 0.5, "what": "baking"})
        p.send_json({"op": "opened", "id": r["id"], "shot": "s", "width": 5, "height": 3, "levels": 4,
                     "edit": 1, "lights": [{"name": "L", "shader": "pointlight", "params": []}]})
        for level in range(4):
            p.conn.sendall(relight.encode_frame(2, tile_frame(1, level, 0, 0, 4, 3, 10 + level), mask=False))
            p.conn.sendall(relight.encode_frame(2, tile_frame(1, level, 4, 0, 1, 3, 20 + level), mask=False))
            p.send_json({"op": "level", "edit": 1, "level": level, "ms": 1.5})
        # A "set" in 4-byte fragments (the client sends it so below).
        kind, msg = p.message()[:2]
        seen["set"] = msg
        p.send_json({"op": "ack", "id": msg["id"], "edit": 2})
        # A stale tile of edit 1 after the ack: the client must drop it.
        p.conn.sendall(relight.encode_frame(2, tile_frame(1, 3, 0, 0, 4, 3, 99), mask=False))
        p.conn.sendall(relight.encode_frame(2, tile_frame(2, 3, 0, 0, 4, 3, 50), mask=False))
        p.conn.sendall(relight.encode_frame(2, tile_frame(2, 3, 4, 0, 1, 3, 51), mask=False))
        p.send_json({"op": "level", "edit": 2, "level": 3, "ms": 2})
        # Malformed messages from the server: dropped, the session goes on.
        p.send(1, "not json")
        p.send(1, "[1, 2]")
        p.conn.sendall(relight.encode_frame(2, b"RLT1" + bytes(10), mask=False))
        p.conn.sendall(relight.encode_frame(2, tile_frame(3, 0, 4, 0, 2, 3, 1), mask=False))
        r = p.request()
        seen["bad"] = r
        p.send_json({"op": "error", "id": r["id"], "code": "unknown_light", "message": "no light 'Z'"})
        r = p.request()
        # A long reply: 16-bit and 64-bit lengths, in two fragments.
        p.conn.sendall(relight.encode_frame(2, tile_frame(4, 0, 0, 0, 1, 1, 1), mask=False))
        big = json.dumps({"op": "stats", "id": r["id"], "pad": "x" * 70000})
        p.send(1, big[:300], fin=False)
        p.send(0, big[300:])
        r = p.request()
        seen["close"] = r
        p.send_json({"op": "closed"})
        fin, op, data, masked = p.frame()
        seen["close_frame"] = (op, data, masked)
        p.send(8, data)

    srv = MockServer(script)
    rec = harness.Recorder()
    closes = []
    progress = []
    c = relight.Client(srv.url, token="tok", timeout=5, on_close=lambda code, r: closes.append(code),
                       on_progress=progress.append, **rec.kw())
    C.equal(seen.get("line"), "GET /ws HTTP/1.1", "request line")
    hdr = seen.get("hdr", {})
    C.equal(hdr.get("sec-websocket-version"), "13", "version 13")
    C.equal(hdr.get("sec-websocket-protocol"), "relight.v1", "subprotocol offered")
    C.equal(len(base64.b64decode(hdr.get("sec-websocket-key", ""))), 16, "key is 16 random bytes")
    C.equal(seen.get("hello"), {"op": "hello", "version": 1, "token": "tok"}, "hello sent")
    C.equal((c.role, c.server, c.limits.get("tile_size")), ("viewer", "mock", 4),
            "hello reply reassembled from fragments")
    C.equal(c.list(), [{"name": "s", "width": 5, "height": 3, "baked": True}], "list")
    C.equal(seen.get("pong"), (10, b"are you there"), "ping answered by a pong with its payload")
    opened = c.open("s", "rgba8")
    C.equal(seen["open"].get("format"), "rgba8", "open sends the format")
    C.equal((opened["width"], opened["edit"]), (5, 1), "opened reply")
    C.equal([m.get("fraction") for m in progress], [0.5], "progress reached on_progress")
    img = c.wait(1, 3, timeout=5)
    want = b"".join(bytes([13]) * 16 + bytes([23]) * 4 for _ in range(3))
    C.equal(img.copy(), want, "final level of edit 1 in the image")
    C.equal((img.edit, img.level), (1, 3), "image edit and level")
    levels = [e[1:] for e in rec.take() if e[0] == "level"]
    C.equal(levels, [(1, 0), (1, 1), (1, 2), (1, 3)], "level callbacks in order")
    # A fragmented request: the client's fragmenting, seen by the server.
    text = json.dumps({"op": "set", "id": 999, "light": "L", "params": {"intensity": 2.5}})
    c.ws.send(text, fragment=4)
    img = c.wait(2, 3, timeout=5)
    C.equal(seen.get("set"), json.loads(text), "a 4-byte-fragment request reassembled")
    want = b"".join(bytes([50]) * 16 + bytes([51]) * 4 for _ in range(3))
    C.equal(img.copy(), want, "stale tile of edit 1 dropped, edit 2 shown")
    C.equal(c.tiles_dropped, 1, "one tile dropped")
    C.raises(lambda: c.set("Z", intensity=1), "unknown_light", "error reply raises ServerError")
    # A callback that waits for a reply would wait for ever: it is refused.
    got = []

    def waiting_callback(tile):
        try:
            c.wait(99, 3, timeout=1)
        except RuntimeError:
            got.append(True)
    c.on_tile = waiting_callback
    C.equal(len(c.stats()["pad"]), 70000, "70 kB fragmented reply")
    C.equal(got, [True], "wait() in a callback raises RuntimeError")
    c.on_tile = None
    C.equal(c.protocol_errors, 4, "non-JSON, non-object, short tile, tile past the edge: dropped")
    C.check(c.connected, "the session survives malformed server messages")
    C.equal(c.close().get("op"), "closed", "close resolved by a reply without id")
    c.disconnect()
    srv.wait("server script ran to its end")
    op, data, masked = seen.get("close_frame", (None, b"", False))
    C.check(op == 8 and data[:2] == b"\x03\xe8" and masked, "disconnect sends a masked close 1000",
            repr(seen.get("close_frame")))
    C.check(harness.wait_until(lambda: closes, 3) and closes[0] == 1000, "on_close(1000)", closes)
    try:
        c.list()
        C.check(False, "a request after disconnect raises ConnectionClosed")
    except relight.ConnectionClosed:
        C.check(True, "a request after disconnect raises ConnectionClosed")


def accept_only(p, **kw):
    line, hdr = p.read_head()
    p.accept(hdr, **kw)
    return hdr


def failures_section():
    C.section = "failures"

    def connect_fails(script, what, status=None):
        srv = MockServer(script)
        try:
            relight.WebSocket.connect(srv.url, timeout=5)
            C.check(False, what, "connected")
        except relight.HandshakeError as e:
            C.check(status is None or e.status == status, what, str(e))
        srv.done.get(timeout=10)

    connect_fails(lambda p: accept_only(p, accept="d3Jvbmc="), "wrong accept key refused")
    connect_fails(lambda p: accept_only(p, protocol=None), "no subprotocol refused")
    connect_fails(lambda p: (p.read_head(), p.conn.sendall(b"HTTP/1.1 403 Forbidden\r\n\r\n")),
                  "403 refused with its status", 403)
    connect_fails(lambda p: p.read_head(), "connection closed during the upgrade")

    # Frames the client must refuse close the connection with the right code.
    def refuse(send, code, what):
        got = {}

        def script(p):
            accept_only(p)
            send(p)
            fin, op, data, masked = p.frame()
            got["close"] = (op, data[:2])
        srv = MockServer(script)
        ws = relight.WebSocket.connect(srv.url, timeout=5)
        try:
            ws.recv(5)
            C.check(False, what, "a message was accepted")
        except relight.ProtocolError as e:
            C.equal(e.code, code, what)
        srv.wait(what + ": server saw the close")
        C.equal(got.get("close"), (8, struct.pack("!H", code)), what + ": close code sent")

    refuse(lambda p: p.conn.sendall(relight.encode_frame(1, b"{}", mask=True)), 1002,
           "masked server frame")
    refuse(lambda p: p.send(1, b"\xff\xfe"), 1007, "invalid UTF-8 text")
    refuse(lambda p: p.send(0, b"x"), 1002, "continuation without a start")
    refuse(lambda p: (p.send(1, b"a", fin=False), p.send(1, b"b")), 1002,
           "new message inside a fragmented one")

    # A close from the server is echoed with its code and reported.
    got = {}

    def script(p):
        accept_only(p)
        p.send(8, struct.pack("!H", 1009) + b"message too big")
        got["echo"] = p.frame()
    srv = MockServer(script)
    ws = relight.WebSocket.connect(srv.url, timeout=5)
    try:
        ws.recv(5)
    except relight.ConnectionClosed as e:
        got["code"] = (e.code, e.reason)
    srv.wait("close script ran")
    C.equal(got.get("code"), (1009, "message too big"), "server close code and reason reported")
    echo = got.get("echo")
    C.check(echo and echo[1] == 8 and echo[2][:2] == struct.pack("!H", 1009),
            "close 1009 echoed", repr(echo))

    # An auth error at hello raises ServerError from the constructor.
    def script(p):
        accept_only(p)
        p.request()
        p.send_json({"op": "error", "code": "auth", "message": "bad token"})
        p.send(8, struct.pack("!H", 1008))
    srv = MockServer(script)
    try:
        relight.Client(srv.url, token="nope", timeout=5)
        C.check(False, "auth error raised")
    except relight.ServerError as e:
        C.equal(e.code, "auth", "auth error raised")
    srv.done.get(timeout=10)

    # A connection dropped without a close frame fails the waiting requests.
    def script(p):
        accept_only(p)
        p.request()
        p.send_json({"op": "hello", "version": 1, "role": "editor"})
        p.request()
        time.sleep(0.1)
    srv = MockServer(script)
    c = relight.Client(srv.url, timeout=5)
    try:
        c.stats()
        C.check(False, "a dropped connection fails the pending request")
    except relight.ConnectionClosed as e:
        C.equal(e.code, 1006, "a dropped connection fails the pending request with 1006")
    except Exception as e:
        C.check(False, "a dropped connection fails the pending request", repr(e))
    try:
        c.wait(5, 3, timeout=1)
        C.check(False, "wait() after the drop raises ConnectionClosed")
    except relight.ConnectionClosed:
        C.check(True, "wait() after the drop raises ConnectionClosed")
    srv.done.get(timeout=10)


def connect_errors_section():
    """A connection that cannot be made raises relight.Error (also an OSError)."""
    C.section = "connect errors"
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()       # nobody listens there now
    for make, what in ((lambda: relight.Client("ws://127.0.0.1:%d/ws" % port, timeout=5),
                        "Client to a closed port"),
                       (lambda: relight.WebSocket.connect("ws://127.0.0.1:%d/ws" % port,
                                                          timeout=5),
                        "WebSocket.connect to a closed port"),
                       (lambda: relight.Client("ws://no-such-host.invalid/ws", timeout=5),
                        "Client to a host that does not resolve"),
                       (lambda: relight.Client("ws://127.0.0.1:99999/ws", timeout=5),
                        "Client to port 99999")):
        try:
            make()
            C.check(False, what + " raises relight.Error", "connected")
        except relight.Error as e:
            C.check(str(e) != "", what + " raises relight.Error with a message")
        except Exception as e:
            C.check(False, what + " raises relight.Error", "raised %r" % e)
    try:
        relight.Client("ws://127.0.0.1:%d/ws" % port, timeout=5)
    except OSError as e:
        C.check(e.errno is not None, "a refused connection keeps its errno", repr(e))
    except Exception as e:
        C.check(False, "a refused connection is also an OSError", repr(e))

    # wss:// to a server that does not speak TLS: relight.Error, also an ssl.SSLError.
    srv = socket.socket()
    srv.bind(("127.0.0.1", 0))
    srv.listen(1)

    def not_tls():
        conn, _ = srv.accept()
        conn.sendall(b"HTTP/1.1 400 Bad Request\r\n\r\n" * 8)
        time.sleep(0.5)
        conn.close()
    threading.Thread(target=not_tls, daemon=True).start()
    try:
        relight.WebSocket.connect("wss://127.0.0.1:%d/ws" % srv.getsockname()[1], timeout=5)
        C.check(False, "a failed TLS handshake raises relight.Error", "connected")
    except relight.Error as e:
        C.check(isinstance(e, ssl.SSLError) and "TLS" in str(e),
                "a failed TLS handshake is relight.Error and ssl.SSLError", repr(e))
    except Exception as e:
        C.check(False, "a failed TLS handshake raises relight.Error", repr(e))
    srv.close()

    # A server that accepts and never answers: the request times out with relight.Error.
    def script(p):
        accept_only(p)
        p.request()
        p.send_json({"op": "hello", "version": 1, "role": "editor"})
        p.request()
        time.sleep(1.5)
    srv = MockServer(script)
    c = relight.Client(srv.url, timeout=0.5)
    try:
        c.stats()
        C.check(False, "a request without a reply times out")
    except relight.Error as e:
        C.check(isinstance(e, TimeoutError), "a reply's timeout is relight.Error and "
                "TimeoutError", repr(e))
    except Exception as e:
        C.check(False, "a reply's timeout raises relight.Error", repr(e))
    c.disconnect(wait=0)
    srv.done.get(timeout=10)


def main():
    for section in (frames_section, handshake_section, tiles_section, conversation_section,
                    failures_section, connect_errors_section):
        C.run(section)
    C.finish()


if __name__ == "__main__":
    main()
