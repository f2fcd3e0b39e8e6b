"""A client for relightd, the relight daemon (protocol version 1).

One file, Python 3.8 or newer, standard library only, so that it can be
dropped into the Python of a DCC application (Maya, Houdini, Katana, Nuke).
It carries its own small WebSocket client (RFC 6455: ws:// and wss://,
masking, fragmentation, ping/pong, the closing handshake).

    import relight
    c = relight.Client("ws://127.0.0.1:7878/ws", token=None)
    c.open("shadows")                     # format "rgba8" or "rgba16f"
    edit = c.set("2", intensity=60.0, from_=[1, 4, -2])
    image = c.wait(edit, level=3)         # relight.Image: width, height, pixels
    c.disconnect()

A background thread reads everything the daemon sends: replies complete the
requests waiting for them, tiles are written into `Client.image` and, like
level messages, handed to the callbacks given to Client. Callbacks run on
that thread: a GUI must hand them over to its own thread before touching
widgets. Requests may be sent from any thread; `set_async` returns at once.
"""

import base64
import collections
import hashlib
import json
import logging
import math
import numbers
import os
import selectors
import socket
import ssl
import struct
import threading
import time
from urllib.parse import urlsplit

__all__ = [
    "Client", "Image", "Tile", "Request", "WebSocket", "FrameDecoder", "Frame",
    "Error", "ServerError", "ProtocolError", "HandshakeError", "ConnectionClosed",
    "ConnectError", "TLSError", "Timeout", "ArgumentError",
    "encode_frame", "parse_tile", "accept_key",
]

__version__ = "0.1.0"

PROTOCOL_VERSION = 1
SUBPROTOCOL = "relight.v1"

log = logging.getLogger("relight")

# ---------------------------------------------------------------------------
# Errors
# ---------------------------------------------------------------------------


class Error(Exception):
    """Base of every error this module raises."""


class ServerError(Error):
    """An {"op":"error"} reply: `code` ("range", "auth", ...) and `message`."""

    def __init__(self, code, message, id=None):
        super().__init__("%s: %s" % (code, message))
        self.code = code
        self.message = message
        self.id = id


class ProtocolError(Error):
    """The peer broke RFC 6455 or the relight protocol; `code` is the close code sent."""

    def __init__(self, message, code=1002):
        super().__init__(message)
        self.code = code


class HandshakeError(Error):
    """The server refused or botched the WebSocket upgrade (`status` 0: no HTTP reply)."""

    def __init__(self, message, status=0, headers=None):
        super().__init__(message)
        self.status = status
        self.headers = headers or {}


class ConnectError(Error, OSError):
    """The connection could not be made: refused, unreachable, an unknown host, a
    failed TLS handshake (`errno` as the system gave it, or None)."""

    def __init__(self, message, errno=None):
        super().__init__(message)
        self.errno = errno


class TLSError(ConnectError, ssl.SSLError):
    """The TLS handshake failed (an untrusted certificate, say); also an ssl.SSLError."""

    def __init__(self, message, errno=None):
        super().__init__(message, errno)
        self.message = message

    def __str__(self):
        return self.message


class Timeout(Error, TimeoutError):
    """No reply or message came in time."""


class ArgumentError(Error, ValueError, TypeError):
    """A value the protocol cannot carry, found before sending: a string or None
    where a number is expected, NaN or an infinity, the wrong count of values."""


class ConnectionClosed(Error):
    """The connection is closed: `code` and `reason` of the close frame (1006: none came)."""

    def __init__(self, code=1006, reason=""):
        super().__init__("connection closed (%d%s)" % (code, ": " + reason if reason else ""))
        self.code = code
        self.reason = reason


# ---------------------------------------------------------------------------
# WebSocket frames (RFC 6455 section 5)
# ---------------------------------------------------------------------------

OP_CONTINUATION = 0x0
OP_TEXT = 0x1
OP_BINARY = 0x2
OP_CLOSE = 0x8
OP_PING = 0x9
OP_PONG = 0xA

_GUID = b"258EAFA5-E914-47DA-95CA-C5AB0DC85B11"

Frame = collections.namedtuple("Frame", "fin opcode payload")
Frame.__doc__ = "One decoded frame: fin flag, opcode, unmasked payload (bytes)."


def accept_key(key):
    """The Sec-WebSocket-Accept value a server must answer to Sec-WebSocket-Key `key`."""
    if isinstance(key, str):
        key = key.encode("ascii")
    return base64.b64encode(hashlib.sha1(key + _GUID).digest()).decode("ascii")


def mask_payload(mask, data):
    """XOR `data` with the 4-byte `mask` repeated (masking and unmasking alike)."""
    n = len(data)
    if n == 0:
        return b""
    # One big-integer XOR runs in C: far faster than a Python loop over bytes.
    key = (bytes(mask) * (n // 4 + 1))[:n]
    return (int.from_bytes(data, "big") ^ int.from_bytes(key, "big")).to_bytes(n, "big")


def encode_frame(opcode, payload=b"", fin=True, mask=True):
    """Encode one frame. `mask`: True for a random key (clients must mask),
    False for none, or 4 bytes to use as the key."""
    if isinstance(payload, str):
        payload = payload.encode("utf-8")
    payload = bytes(payload)
    n = len(payload)
    head = bytearray([(0x80 if fin else 0) | (opcode & 0x0F)])
    bit = 0x80 if mask is not False else 0
    if n < 126:
        head.append(bit | n)
    elif n < 65536:
        head.append(bit | 126)
        head += struct.pack("!H", n)
    else:
        head.append(bit | 127)
        head += struct.pack("!Q", n)
    if mask is False:
        return bytes(head) + payload
    key = os.urandom(4) if mask is True else bytes(mask)
    if len(key) != 4:
        raise ValueError("a mask key is 4 bytes")
    return bytes(head) + key + mask_payload(key, payload)


def encode_close(code=1000, reason=""):
    """The payload of a close frame: the code (None: no payload) and a UTF-8 reason."""
    if code is None:
        return b""
    data = struct.pack("!H", code) + reason.encode("utf-8")
    return data[:125]


def decode_close(payload):
    """(code, reason) of a close frame's payload; 1005 when it has no code."""
    if len(payload) == 0:
        return 1005, ""
    if len(payload) == 1:
        raise ProtocolError("close frame with a 1-byte payload")
    code = struct.unpack("!H", payload[:2])[0]
    # 1005, 1006 and 1015 are for reporting only; 1004 is reserved; codes
    # below 1000 and from 1016 to 2999 are not assigned.
    if code < 1000 or code in (1004, 1005, 1006, 1015) or 1016 <= code < 3000 or code >= 5000:
        raise ProtocolError("close frame with the invalid code %d" % code)
    try:
        reason = bytes(payload[2:]).decode("utf-8")
    except UnicodeDecodeError:
        raise ProtocolError("close reason is not UTF-8", 1007)
    return code, reason


class FrameDecoder:
    """Split a byte stream from a server into frames.

    feed() adds bytes; next() returns the next complete Frame or None.
    Raises ProtocolError for what a client must refuse: reserved bits (no
    extension is negotiated), reserved opcodes, masked frames, fragmented or
    long control frames, and frames over `max_frame` bytes (code 1009).
    """

    def __init__(self, max_frame=1 << 30):
        self.max_frame = max_frame
        self._buf = bytearray()
        self._pos = 0

    def feed(self, data):
        if self._pos and self._pos >= len(self._buf) // 2:
            del self._buf[:self._pos]
            self._pos = 0
        self._buf += data

    def buffered(self):
        """Bytes received and not yet returned as frames."""
        return len(self._buf) - self._pos

    def next(self):
        buf, p = self._buf, self._pos
        avail = len(buf) - p
        if avail < 2:
            return None
        b0, b1 = buf[p], buf[p + 1]
        fin, rsv, opcode = bool(b0 & 0x80), b0 & 0x70, b0 & 0x0F
        masked, n = bool(b1 & 0x80), b1 & 0x7F
        if rsv:
            raise ProtocolError("frame with reserved bits set (no extension was agreed)")
        if opcode not in (OP_CONTINUATION, OP_TEXT, OP_BINARY, OP_CLOSE, OP_PING, OP_PONG):
            raise ProtocolError("frame with the reserved opcode 0x%x" % opcode)
        if masked:
            raise ProtocolError("masked frame from the server")
        if opcode >= OP_CLOSE and (not fin or n > 125):
            raise ProtocolError("fragmented or long control frame")
        head = 2
        if n == 126:
            if avail < 4:
                return None
            n = struct.unpack_from("!H", buf, p + 2)[0]
            head = 4
        elif n == 127:
            if avail < 10:
                return None
            n = struct.unpack_from("!Q", buf, p + 2)[0]
            if n >> 63:
                raise ProtocolError("frame length with the top bit set")
            head = 10
        if n > self.max_frame:
            raise ProtocolError("frame of %d bytes, over the %d-byte limit" % (n, self.max_frame),
                                1009)
        if avail < head + n:
            return None
        payload = bytes(buf[p + head:p + head + n])
        self._pos = p + head + n
        return Frame(fin, opcode, payload)


# ---------------------------------------------------------------------------
# WebSocket connection (RFC 6455 sections 4 to 7)
# ---------------------------------------------------------------------------


def parse_url(url):
    """(tls, host, port, path) of a ws://, wss://, http:// or https:// URL.
    The path defaults to /ws, relightd's WebSocket endpoint."""
    u = urlsplit(url)
    scheme = u.scheme.lower()
    if scheme not in ("ws", "wss", "http", "https"):
        raise ArgumentError("%s: not a ws:// or wss:// URL" % url)
    if not u.hostname:
        raise ArgumentError("%s: no host" % url)
    tls = scheme in ("wss", "https")
    try:
        port = u.port or (443 if tls else 80)
    except ValueError:
        raise ArgumentError("%s: the port must be 1 to 65535" % url)
    path = u.path if u.path not in ("", "/") else "/ws"
    if u.query:
        path += "?" + u.query
    return tls, u.hostname, port, path


def _header_host(host, port, tls):
    h = "[%s]" % host if ":" in host else host
    return h if port == (443 if tls else 80) else "%s:%d" % (h, port)


def build_handshake(host, path, key, subprotocols=(SUBPROTOCOL,), origin=None, headers=None):
    """The HTTP upgrade request (bytes). `host` is the Host header's value."""
    lines = [
        "GET %s HTTP/1.1" % path,
        "Host: %s" % host,
        "Upgrade: websocket",
        "Connection: Upgrade",
        "Sec-WebSocket-Key: %s" % key,
        "Sec-WebSocket-Version: 13",
    ]
    if subprotocols:
        lines.append("Sec-WebSocket-Protocol: %s" % ", ".join(subprotocols))
    if origin:
        lines.append("Origin: %s" % origin)
    for k, v in (headers or {}).items():
        lines.append("%s: %s" % (k, v))
    return ("\r\n".join(lines) + "\r\n\r\n").encode("latin-1")


def check_handshake(response, key, subprotocols=(SUBPROTOCOL,)):
    """Check a server's reply head (bytes up to and without the blank line).
    Returns (subprotocol, headers); raises HandshakeError."""
    text = response.decode("latin-1")
    lines = text.split("\r\n")
    parts = lines[0].split(" ", 2)
    if len(parts) < 2 or not parts[0].startswith("HTTP/") or not parts[1].isdigit():
        raise HandshakeError("not an HTTP reply: %r" % lines[0][:80])
    status = int(parts[1])
    headers = {}
    for line in lines[1:]:
        if not line:
            continue
        name, sep, value = line.partition(":")
        if not sep:
            raise HandshakeError("bad header line in the reply: %r" % line[:80], status)
        name = name.strip().lower()
        value = value.strip()
        headers[name] = headers[name] + ", " + value if name in headers else value
    if status != 101:
        raise HandshakeError("the server refused the WebSocket upgrade: HTTP %d %s"
                             % (status, parts[2] if len(parts) > 2 else ""), status, headers)
    if headers.get("upgrade", "").lower() != "websocket":
        raise HandshakeError("reply without 'Upgrade: websocket'", status, headers)
    tokens = [t.strip().lower() for t in headers.get("connection", "").split(",")]
    if "upgrade" not in tokens:
        raise HandshakeError("reply without 'Connection: Upgrade'", status, headers)
    if headers.get("sec-websocket-accept") != accept_key(key):
        raise HandshakeError("wrong Sec-WebSocket-Accept", status, headers)
    if headers.get("sec-websocket-extensions"):
        raise HandshakeError("the server imposed extensions that were not offered: %s"
                             % headers["sec-websocket-extensions"], status, headers)
    proto = headers.get("sec-websocket-protocol")
    if subprotocols:
        if proto not in subprotocols:
            raise HandshakeError("the server did not accept subprotocol %s (got %r)"
                                 % (", ".join(subprotocols), proto), status, headers)
    elif proto:
        raise HandshakeError("the server chose subprotocol %r, none was offered" % proto,
                             status, headers)
    return proto, headers


class WebSocket:
    """A client WebSocket connection.

    Sending is thread-safe. Receiving (recv) belongs to one thread at a time.
    Pings are answered, and a close frame is answered and ends the
    connection, inside recv().
    """

    def __init__(self, sock, leftover=b"", subprotocol=None, tls=False, timeout=10.0,
                 max_message=1 << 30):
        self.sock = sock
        self.subprotocol = subprotocol
        self.timeout = timeout
        self.max_message = max_message
        self.close_code = None      # set once the connection is closed
        self.close_reason = ""
        self.pongs = 0
        self._tls = tls
        self._decoder = FrameDecoder(max_message)
        self._decoder.feed(leftover)
        self._wlock = threading.Lock()
        self._close_sent = False
        self._fragments = []
        self._frag_opcode = None
        self._frag_size = 0
        self._sel = selectors.DefaultSelector()
        self._sel.register(sock, selectors.EVENT_READ)

    @classmethod
    def connect(cls, url, timeout=10.0, subprotocols=(SUBPROTOCOL,), origin=None,
                headers=None, ssl_context=None):
        """Open a connection: TCP (and TLS for wss://), then the upgrade."""
        tls, host, port, path = parse_url(url)
        where = _header_host(host, port, tls)
        try:
            sock = socket.create_connection((host, port), timeout=timeout)
        except socket.timeout:
            raise ConnectError("cannot connect to %s: no answer within %g s" % (where, timeout))
        except OSError as e:
            raise ConnectError("cannot connect to %s: %s" % (where, e.strerror or e), e.errno)
        try:
            # Small JSON requests must leave at once, not wait on Nagle.
            sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            try:
                if tls:
                    ctx = ssl_context or ssl.create_default_context()
                    sock = ctx.wrap_socket(sock, server_hostname=host)
                key = base64.b64encode(os.urandom(16)).decode("ascii")
                sock.sendall(build_handshake(where, path, key, subprotocols, origin, headers))
            except socket.timeout:
                raise ConnectError("cannot connect to %s: no answer within %g s"
                                   % (where, timeout))
            except ssl.SSLError as e:
                raise TLSError("cannot connect to %s: TLS: %s"
                               % (where, getattr(e, "verify_message", None) or e.reason or e),
                               e.errno)
            except OSError as e:
                raise ConnectError("cannot connect to %s: %s" % (where, e.strerror or e),
                                   e.errno)
            data = b""
            deadline = time.monotonic() + timeout
            while b"\r\n\r\n" not in data:
                if len(data) > 65536:
                    raise HandshakeError("HTTP reply head over 64 KB")
                sock.settimeout(max(0.001, deadline - time.monotonic()))
                try:
                    chunk = sock.recv(4096)
                except socket.timeout:
                    raise HandshakeError("no reply to the upgrade within %g s" % timeout)
                except OSError as e:
                    raise ConnectError("cannot connect to %s: %s" % (where, e.strerror or e),
                                       e.errno)
                if not chunk:
                    raise HandshakeError("connection closed during the upgrade")
                data += chunk
            head, _, rest = data.partition(b"\r\n\r\n")
            proto, _ = check_handshake(head, key, subprotocols)
            sock.settimeout(timeout)
            return cls(sock, rest, proto, tls, timeout)
        except BaseException:
            sock.close()
            raise

    # -- sending --

    def send_frame(self, opcode, payload=b"", fin=True):
        """Send one raw frame (masked)."""
        data = encode_frame(opcode, payload, fin)
        with self._wlock:
            if self._close_sent and opcode != OP_CLOSE:
                raise ConnectionClosed(self.close_code or 1006, "closing")
            try:
                self.sock.sendall(data)
            except OSError as e:
                raise ConnectionClosed(1006, str(e))

    def send(self, data, fragment=0):
        """Send a message: str as text, bytes as binary. `fragment` > 0
        splits it into frames of that many bytes (continuation frames)."""
        opcode = OP_TEXT if isinstance(data, str) else OP_BINARY
        if isinstance(data, str):
            data = data.encode("utf-8")
        if fragment <= 0 or len(data) <= fragment:
            self.send_frame(opcode, data)
            return
        # Whole messages only: the lock spans every fragment, so that another
        # thread's message cannot land between them.
        frames = []
        for i in range(0, len(data), fragment):
            last = i + fragment >= len(data)
            frames.append(encode_frame(opcode if i == 0 else OP_CONTINUATION,
                                       data[i:i + fragment], last))
        with self._wlock:
            if self._close_sent:
                raise ConnectionClosed(self.close_code or 1006, "closing")
            try:
                for f in frames:
                    self.sock.sendall(f)
            except OSError as e:
                raise ConnectionClosed(1006, str(e))

    def ping(self, payload=b""):
        self.send_frame(OP_PING, payload)

    def close(self, code=1000, reason="", wait=0.0):
        """Start the closing handshake. With `wait` > 0 (only when no other
        thread reads), read until the server's close frame or `wait` seconds,
        then close the socket."""
        with self._wlock:
            if not self._close_sent:
                self._close_sent = True
                try:
                    self.sock.sendall(encode_frame(OP_CLOSE, encode_close(code, reason)))
                except OSError:
                    pass
        if wait > 0:
            deadline = time.monotonic() + wait
            try:
                while self.close_code is None:
                    left = deadline - time.monotonic()
                    if left <= 0:
                        break
                    self.recv(left)
            except (ConnectionClosed, ProtocolError, TimeoutError):
                pass
            self.abort()

    def abort(self):
        """Close the socket without a closing handshake."""
        if self.close_code is None:
            self.close_code = 1006
        try:
            self._sel.close()
        except (OSError, ValueError, KeyError):
            pass
        try:
            self.sock.close()
        except OSError:
            pass

    # -- receiving --

    def _fill(self, timeout):
        """Read what the socket has; False when `timeout` passed first."""
        if not (self._tls and self.sock.pending()):
            try:
                ready = self._sel.select(timeout)
            except (OSError, ValueError):
                # Another thread closed the connection under us.
                raise ConnectionClosed(self.close_code or 1006, self.close_reason)
            if not ready:
                return False
        try:
            if self._tls:
                # OpenSSL objects are not safe for a read and a write at once.
                with self._wlock:
                    data = self.sock.recv(262144)
            else:
                data = self.sock.recv(262144)
        except (ssl.SSLWantReadError, socket.timeout):
            return True
        except OSError as e:
            self.abort()
            raise ConnectionClosed(1006, str(e))
        if not data:
            self.abort()
            raise ConnectionClosed(1006, "the server closed the connection without a close frame")
        self._decoder.feed(data)
        return True

    def _fail(self, err):
        """Close with err's code after a protocol violation; re-raise it."""
        self.close(err.code, str(err)[:100])
        self.abort()
        self.close_code = err.code
        raise err

    def recv(self, timeout=None):
        """The next message: str for text, bytes for binary. Raises
        relight.Timeout (a TimeoutError) after `timeout` seconds (None: wait
        for ever) and ConnectionClosed when the connection ends."""
        deadline = None if timeout is None else time.monotonic() + timeout
        while True:
            if self.close_code is not None:
                raise ConnectionClosed(self.close_code, self.close_reason)
            try:
                frame = self._decoder.next()
            except ProtocolError as e:
                self._fail(e)
            if frame is None:
                left = None if deadline is None else max(0.0, deadline - time.monotonic())
                if not self._fill(left) and left is not None and left <= 0:
                    raise Timeout("no message within %g s" % timeout)
                continue
            msg = self._frame(frame)
            if msg is not None:
                return msg

    def _frame(self, f):
        if f.opcode == OP_PING:
            try:
                self.send_frame(OP_PONG, f.payload)
            except ConnectionClosed:
                pass
            return None
        if f.opcode == OP_PONG:
            self.pongs += 1
            return None
        if f.opcode == OP_CLOSE:
            try:
                code, reason = decode_close(f.payload)
            except ProtocolError as e:
                self._fail(e)
            # Echo the code, as RFC 6455 5.5.1 asks, unless we closed first.
            self.close(code if code != 1005 else None, "")
            self.abort()
            self.close_code, self.close_reason = code, reason
            raise ConnectionClosed(code, reason)
        if f.opcode == OP_CONTINUATION:
            if self._frag_opcode is None:
                self._fail(ProtocolError("continuation frame without a message to continue"))
        elif self._frag_opcode is not None:
            self._fail(ProtocolError("new message inside a fragmented one"))
        else:
            self._frag_opcode = f.opcode
        self._frag_size += len(f.payload)
        if self._frag_size > self.max_message:
            self._fail(ProtocolError("message over %d bytes" % self.max_message, 1009))
        if not f.fin:
            self._fragments.append(f.payload)
            return None
        if self._fragments:
            self._fragments.append(f.payload)
            data = b"".join(self._fragments)
        else:
            data = f.payload
        opcode = self._frag_opcode
        self._fragments, self._frag_opcode, self._frag_size = [], None, 0
        if opcode == OP_TEXT:
            try:
                return data.decode("utf-8")
            except UnicodeDecodeError:
                self._fail(ProtocolError("text message is not UTF-8", 1007))
        return data


# ---------------------------------------------------------------------------
# relight tiles and images
# ---------------------------------------------------------------------------

TILE_MAGIC = b"RLT1"
TILE_HEADER = struct.Struct("<4s8I")
FORMATS = {1: "rgba8", 2: "rgba16f"}
FORMAT_IDS = {"rgba8": 1, "rgba16f": 2}
BYTES_PER_PIXEL = {"rgba8": 4, "rgba16f": 8}


class Tile(collections.namedtuple("Tile", "edit level format x y width height data")):
    """A decoded tile frame: where it goes and its pixels (bytes, rows top first)."""


def parse_tile(frame):
    """Decode a binary tile frame; ProtocolError when it is not one."""
    if len(frame) < TILE_HEADER.size:
        raise ProtocolError("tile frame of %d bytes, shorter than its header" % len(frame))
    magic, hsize, edit, level, fmt, x, y, w, h = TILE_HEADER.unpack_from(frame)
    if magic != TILE_MAGIC or hsize != TILE_HEADER.size:
        raise ProtocolError("not a tile frame (magic %r, header %d bytes)" % (magic, hsize))
    if fmt not in FORMATS:
        raise ProtocolError("tile of unknown format %d" % fmt)
    name = FORMATS[fmt]
    if w == 0 or h == 0 or len(frame) - hsize != w * h * BYTES_PER_PIXEL[name]:
        raise ProtocolError("tile %dx%d with %d pixel bytes" % (w, h, len(frame) - hsize))
    return Tile(edit, level, name, x, y, w, h, memoryview(frame)[hsize:])


class Image:
    """The newest image of a shot in one format, updated tile by tile.

    `pixels` is a bytearray, rows top first (4 bytes a pixel for rgba8:
    sRGB over black and alpha; 8 for rgba16f: linear premultiplied half
    floats). `edit` and `level` name the last level completed (-1: none yet);
    `serial` counts the tiles written, so a GUI timer can tell when to
    redraw. Hold `lock` (or use copy()) to read pixels while tiles arrive.
    """

    def __init__(self, width, height, format="rgba8"):
        self.width, self.height, self.format = width, height, format
        self.bytes_per_pixel = BYTES_PER_PIXEL[format]
        self.pixels = bytearray(width * height * self.bytes_per_pixel)
        self.edit = -1
        self.level = -1
        self.serial = 0
        self.lock = threading.Lock()

    def put(self, tile):
        """Write a tile's pixels; ProtocolError when it lies outside the image."""
        if tile.format != self.format:
            raise ProtocolError("%s tile for an %s image" % (tile.format, self.format))
        if tile.x + tile.width > self.width or tile.y + tile.height > self.height:
            raise ProtocolError("tile %dx%d at (%d, %d) outside the %dx%d image"
                                % (tile.width, tile.height, tile.x, tile.y, self.width,
                                   self.height))
        bpp = self.bytes_per_pixel
        row, stride = tile.width * bpp, self.width * bpp
        start = tile.y * stride + tile.x * bpp
        data = tile.data
        with self.lock:
            if tile.width == self.width:
                self.pixels[start:start + row * tile.height] = data
            else:
                for r in range(tile.height):
                    o = start + r * stride
                    self.pixels[o:o + row] = data[r * row:(r + 1) * row]
            self.serial += 1

    def copy(self):
        """The pixels as bytes, read consistently."""
        with self.lock:
            return bytes(self.pixels)

    def pixel(self, x, y):
        """The 4 channels of pixel (x, y): ints (rgba8) or floats (rgba16f)."""
        o = (y * self.width + x) * self.bytes_per_pixel
        with self.lock:
            if self.format == "rgba8":
                return tuple(self.pixels[o:o + 4])
            return struct.unpack_from("<4e", self.pixels, o)


# ---------------------------------------------------------------------------
# The relight client
# ---------------------------------------------------------------------------


class Request:
    """A request on its way: result() waits for the reply (a dict) and raises
    ServerError for an error reply."""

    def __init__(self, id, op, timeout):
        self.id, self.op, self.timeout = id, op, timeout
        self._event = threading.Event()
        self._reply = None
        self._error = None
        self._callbacks = []
        self._lock = threading.Lock()
        self._reader = None               # the thread that completes it
        self.touched = time.monotonic()   # progress messages push the deadline back

    def done(self):
        return self._event.is_set()

    def result(self, timeout=None):
        """The reply; waits `timeout` seconds (default: the client's) after
        the last sign of progress."""
        timeout = self.timeout if timeout is None else timeout
        if not self.done() and threading.current_thread() is self._reader:
            raise RuntimeError("%s: a callback cannot wait for a reply (the reply comes on "
                               "its own thread): use the *_async calls there" % self.op)
        while not self._event.wait(max(0.0, self.touched + timeout - time.monotonic())):
            if time.monotonic() >= self.touched + timeout:
                raise Timeout("%s: no reply within %g s" % (self.op, timeout))
        if self._error is not None:
            raise self._error
        return self._reply

    def add_done_callback(self, fn):
        """Call fn(request) once it is done (on the reader thread, or now if it is)."""
        with self._lock:
            if not self._event.is_set():
                self._callbacks.append(fn)
                return
        fn(self)

    def _finish(self, reply=None, error=None):
        with self._lock:
            if self._event.is_set():
                return
            self._reply, self._error = reply, error
            self._event.set()
            callbacks, self._callbacks = self._callbacks, []
        for fn in callbacks:
            try:
                fn(self)
            except Exception:
                log.exception("relight: request callback failed")


def _param_name(name):
    # Python keywords cannot be keyword arguments: from_=[...] sends "from".
    return name[:-1] if name.endswith("_") and not name.endswith("__") else name


def _is_number(x):
    # numbers.Real takes numpy's scalars too; a bool is not a value of a light
    return isinstance(x, numbers.Real) and not isinstance(x, bool)


def _param_value(name, v):
    if isinstance(v, str):
        # a string parameter's value: a texture or environment map's name
        if len(v.encode()) > 4095:
            raise ArgumentError("parameter %r: a string of at most 4095 bytes" % name)
        return v
    if _is_number(v):
        values = [float(v)]
    elif isinstance(v, (str, bytes, bytearray, dict)) or not hasattr(v, "__iter__"):
        raise ArgumentError("parameter %r: a number, a sequence of numbers or a string, not %r"
                            % (name, v))
    else:
        values = list(v)
        if not 1 <= len(values) <= 16:
            raise ArgumentError("parameter %r: 1 to 16 values, not %d" % (name, len(values)))
        for x in values:
            if not _is_number(x):
                raise ArgumentError("parameter %r: %r is not a number" % (name, x))
        values = [float(x) for x in values]
    for x in values:
        if not math.isfinite(x):
            raise ArgumentError("parameter %r: %r is not a finite number" % (name, x))
    if not _is_number(v):
        return values
    return v if type(v) in (int, float) else values[0]


def _params(params, kw):
    out = {}
    for k, v in dict(params or {}).items():
        out[k] = _param_value(k, v)
    for k, v in kw.items():
        out[_param_name(k)] = _param_value(k, v)
    return out


class Client:
    """A connection to relightd; `hello` is done when it is created.

    url: ws://HOST:PORT/ws or wss://... (path /ws by default). token: the
    token when the daemon has a token file. timeout: seconds to wait for a
    reply. Callbacks, all called on the reader thread:
      on_tile(tile)        every tile kept (relight.Tile), after it is in the image
      on_level(msg)        {"op":"level","edit","level","ms"}
      on_progress(msg)     {"op":"progress","shot","fraction","what"} while a RIB bakes
      on_event(msg)        any other message nobody waits for (errors without id...)
      on_close(code, reason)
    Attributes: role ("editor" or "viewer"), server, limits, shot (the
    "opened" reply of the open shot or None), edit (newest edit seen),
    images (format -> Image) and image (the open format's Image).
    """

    def __init__(self, url, token=None, timeout=10.0, origin=None, ssl_context=None,
                 on_tile=None, on_level=None, on_progress=None, on_event=None, on_close=None):
        self.url, self.timeout = url, timeout
        self.on_tile, self.on_level, self.on_progress = on_tile, on_level, on_progress
        self.on_event, self.on_close = on_event, on_close
        self.shot = None
        self.format = None
        self.images = {}
        self.edit = -1
        self.tiles_received = 0
        self.tiles_dropped = 0
        self.protocol_errors = 0        # messages from the server dropped as malformed
        self._levels_done = {}          # edit -> highest level completed
        self._pending = {}
        self._next_id = 1
        self._lock = threading.Lock()
        self._cond = threading.Condition(self._lock)
        self._closed = None             # ConnectionClosed once the connection is gone
        self.ws = WebSocket.connect(url, timeout, origin=origin, ssl_context=ssl_context)
        try:
            self._hello(token)
        except BaseException:
            self.ws.abort()
            raise
        self._reader = threading.Thread(target=self._read_loop, name="relight-reader",
                                        daemon=True)
        self._reader.start()

    def _hello(self, token):
        msg = {"op": "hello", "version": PROTOCOL_VERSION}
        if token is not None:
            msg["token"] = token
        self.ws.send(json.dumps(msg))
        deadline = time.monotonic() + self.timeout
        while True:
            try:
                text = self.ws.recv(max(0.0, deadline - time.monotonic()))
            except ConnectionClosed as e:
                raise ConnectionClosed(e.code, e.reason or "closed before the hello reply")
            if not isinstance(text, str):
                continue
            reply = json.loads(text)
            if reply.get("op") == "error":
                raise ServerError(reply.get("code"), reply.get("message", ""), reply.get("id"))
            if reply.get("op") == "hello":
                break
        self.role = reply.get("role")
        self.server = reply.get("server")
        self.limits = reply.get("limits", {})
        self.version = reply.get("version")

    # -- context manager and teardown --

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.disconnect()

    @property
    def connected(self):
        return self._closed is None

    @property
    def image(self):
        """The Image of the open shot in the format it was opened with (None before open)."""
        return self.images.get(self.format)

    def disconnect(self, code=1000, reason="", wait=2.0):
        """Close the connection (closing handshake, up to `wait` seconds)."""
        self.ws.close(code, reason)
        if threading.current_thread() is not self._reader:
            self._reader.join(wait)
        self.ws.abort()

    # -- requests --

    def request_async(self, op, **fields):
        """Send {"op": op, "id": N, **fields}; returns its Request at once."""
        return self._send(op, fields)

    def _send(self, op, fields, **attrs):
        msg = dict(fields)
        msg["op"] = op
        with self._lock:
            if self._closed is not None:
                raise self._closed
            rid = self._next_id
            self._next_id += 1
        msg["id"] = rid
        try:
            text = json.dumps(msg, allow_nan=False)
        except ValueError as e:
            raise ArgumentError("%s: %s" % (op, e))
        req = Request(rid, op, self.timeout)
        req._reader = self._reader
        for k, v in attrs.items():
            setattr(req, k, v)
        with self._lock:
            self._pending[rid] = req
        try:
            self.ws.send(text)
        except ConnectionClosed:
            with self._lock:
                self._pending.pop(rid, None)
            raise
        return req

    def request(self, op, **fields):
        """Send a request and wait for its reply (a dict)."""
        return self.request_async(op, **fields).result()

    def list(self):
        """The shots: [{"name", "width", "height", "baked"}]."""
        return self.request("list")["shots"]

    def open(self, shot, format="rgba8", on_progress=None):
        """Open a shot (closing the one open); returns the "opened" reply:
        width, height, levels, edit and lights (name, shader, params with
        value, min and max). A RIB not baked yet is baked first; its progress
        goes to on_progress and keeps the request alive."""
        if format not in FORMAT_IDS:
            raise ArgumentError("format is 'rgba8' or 'rgba16f', not %r" % (format,))
        return self._send("open", {"shot": shot, "format": format}, format=format,
                          on_progress=on_progress).result()

    def set_async(self, light, params=None, **kw):
        """Send a "set" and return its Request at once (result()["edit"] is
        the edit number). For GUI callbacks: nothing here waits."""
        return self.request_async("set", light=light, params=_params(params, kw))

    def set(self, light, params=None, **kw):
        """Edit light parameters: set("2", intensity=3, lightcolor=[1, .9, .8]),
        or a dict for names Python cannot take (or from_=...). Returns the
        edit number once acknowledged; the tiles follow on the reader thread."""
        return self.set_async(light, params, **kw).result()["edit"]

    def mute(self, light, mute=True):
        """Mute (or unmute) a light; returns the edit number."""
        return self.request("mute", light=light, mute=bool(mute))["edit"]

    def unmute(self, light):
        return self.mute(light, False)

    def solo(self, light=None):
        """Solo a light (None: solo off); returns the edit number."""
        return self.request("solo", light=light)["edit"]

    def freeze(self, light, freeze=True):
        """Freeze (or unfreeze) a light; returns the ack (no image change, no tiles)."""
        return self.request("freeze", light=light, freeze=bool(freeze))

    def unfreeze(self, light):
        return self.freeze(light, False)

    def add_light(self, light, shader, params=None, **kw):
        """Add a light named `light` running `shader`; returns the edit number."""
        return self.request("add_light", light=light, shader=shader,
                            params=_params(params, kw))["edit"]

    def remove_light(self, light):
        return self.request("remove_light", light=light)["edit"]

    def close(self):
        """Close the open shot (the connection stays open; see disconnect())."""
        return self.request("close")

    def snapshot(self):
        """Have the daemon write an OpenEXR of the current state; returns its path there."""
        return self.request("snapshot")["path"]

    def pick(self, x, y):
        """What pixel (x, y) shows: {"object": id or None, "lights": [names reaching it]}."""
        return self.request("pick", x=x, y=y)

    def stats(self):
        """This session's counters (edits, tiles_sent, tiles_dropped, bytes_sent, ...)."""
        return self.request("stats")

    def wait(self, edit=None, level=3, timeout=None):
        """Wait until `level` of `edit` (or of a newer edit, which supersedes
        it) is complete, and return the Image. `edit`: a number, a Request
        of an edit, or None for the newest edit seen."""
        if isinstance(edit, Request):
            edit = edit.result()["edit"]
        timeout = self.timeout if timeout is None else timeout
        deadline = time.monotonic() + timeout
        if threading.current_thread() is self._reader:
            raise RuntimeError("wait() in a callback would wait for ever: the levels "
                               "arrive on the thread that runs it")
        with self._cond:
            if edit is None:
                edit = self.edit
            while not any(e >= edit and lv >= level for e, lv in self._levels_done.items()):
                if self._closed is not None:
                    raise self._closed
                left = deadline - time.monotonic()
                if left <= 0:
                    raise Timeout("level %d of edit %d not complete within %g s"
                                  % (level, edit, timeout))
                self._cond.wait(left)
            return self.images.get(self.format)

    # -- the reader thread --

    def _call(self, fn, *args):
        if fn is None:
            return
        try:
            fn(*args)
        except Exception:
            log.exception("relight: callback %r failed", fn)

    def _read_loop(self):
        err = None
        try:
            while True:
                try:
                    msg = self.ws.recv(1.0)
                except TimeoutError:
                    continue
                try:
                    if isinstance(msg, str):
                        self._on_text(msg)
                    else:
                        self._on_binary(msg)
                except ProtocolError as e:
                    # A bad message from the server is dropped, the session goes on.
                    self.protocol_errors += 1
                    log.warning("relight: %s", e)
        except ConnectionClosed as e:
            err = e
        except ProtocolError as e:
            # recv() has already closed the connection with e.code.
            err = ConnectionClosed(e.code, str(e))
        except Exception as e:       # a bug must not leave waiters hanging
            log.exception("relight: reader failed")
            err = ConnectionClosed(1006, "reader failed: %s" % e)
            self.ws.abort()
        with self._cond:
            self._closed = err
            pending, self._pending = self._pending, {}
            self._cond.notify_all()
        for req in pending.values():
            req._finish(error=err)
        self._call(self.on_close, err.code, err.reason)

    def _on_text(self, text):
        try:
            msg = json.loads(text)
        except ValueError:
            raise ProtocolError("the server sent text that is not JSON: %r" % text[:80], 1007)
        if not isinstance(msg, dict):
            raise ProtocolError("the server sent JSON that is not an object", 1007)
        op = msg.get("op")
        rid = msg.get("id")
        req = None
        with self._cond:
            if rid is not None and rid in self._pending:
                req = self._pending[rid]
                if op == "progress":
                    req.touched = time.monotonic()
                else:
                    del self._pending[rid]
            elif op == "closed":
                # The protocol's "closed" reply carries no id: it answers the
                # oldest close request.
                for k, r in sorted(self._pending.items()):
                    if r.op == "close":
                        req = self._pending.pop(k)
                        break
            if op == "ack" and isinstance(msg.get("edit"), int):
                self.edit = max(self.edit, msg["edit"])
            elif op == "opened":
                fmt = getattr(req, "format", None) or msg.get("format") or "rgba8"
                self.shot, self.format = msg, fmt
                self.edit = msg.get("edit", 0)
                self._levels_done = {}
                self.images[fmt] = Image(msg["width"], msg["height"], fmt)
            elif op == "closed":
                self.shot = None
                self._levels_done = {}
            elif op == "level":
                e, lv = msg.get("edit"), msg.get("level")
                if isinstance(e, int) and isinstance(lv, int):
                    self.edit = max(self.edit, e)
                    self._levels_done[e] = max(self._levels_done.get(e, -1), lv)
                    if len(self._levels_done) > 64:
                        for old in sorted(self._levels_done)[:-32]:
                            del self._levels_done[old]
                    img = self.images.get(self.format)
                    if img is not None and e >= img.edit:
                        img.edit, img.level = e, lv
                self._cond.notify_all()
        if op == "progress":
            cb = getattr(req, "on_progress", None) or self.on_progress
            self._call(cb, msg)
        elif op == "level":
            self._call(self.on_level, msg)
        elif req is not None:
            if op == "error":
                req._finish(error=ServerError(msg.get("code"), msg.get("message", ""), rid))
            else:
                req._finish(reply=msg)
        else:
            self._call(self.on_event, msg)

    def _on_binary(self, data):
        tile = parse_tile(data)
        with self._cond:
            # Tiles of an edit older than the newest one known are superseded.
            if tile.edit < self.edit:
                self.tiles_dropped += 1
                return
            img = self.images.get(tile.format)
        if img is not None:
            img.put(tile)
        with self._cond:
            self.edit = max(self.edit, tile.edit)
        self.tiles_received += 1
        self._call(self.on_tile, tile)
