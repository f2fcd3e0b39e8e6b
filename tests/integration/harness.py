"""Shared pieces of the relightd integration tests.

A test runs as `python3 test_NAME.py PATH/TO/relightd PATH/TO/relight`. It
counts checks with Checks, bakes the example shots once per build folder
(bake_shots), starts daemons on a free port (Daemon) and compares images
with those `relight preview` writes (preview_png, decode_png).
"""

import fcntl
import os
import shutil
import signal
import socket
import struct
import subprocess
import sys
import tempfile
import threading
import time
import traceback
import zlib

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE_DIR = os.environ.get("RELIGHT_SOURCE_DIR") or os.path.dirname(os.path.dirname(HERE))
sys.path.insert(0, os.path.join(SOURCE_DIR, "clients", "python"))

import relight  # noqa: E402

SKIP = 77

# The examples the tests serve, and the RIB of each.
EXAMPLES = {"shadows": "shadows.rib", "lights32": "lights32.rib"}


def build_dir():
    d = os.environ.get("RELIGHT_BUILD_DIR")
    if d:
        return d
    return os.path.join(tempfile.gettempdir(), "relight-integration")


class Checks:
    """Counts checks and failures; finish() prints the summary and exits."""

    def __init__(self, name):
        self.name = name
        self.checks = 0
        self.failures = 0
        self.section = ""

    def check(self, cond, what, detail=""):
        self.checks += 1
        if not cond:
            self.failures += 1
            msg = "%s: [%s] FAIL: %s" % (self.name, self.section, what)
            if detail:
                msg += " (%s)" % detail
            print(msg, file=sys.stderr, flush=True)
        return bool(cond)

    def equal(self, got, want, what):
        if got == want:
            return self.check(True, what)
        if isinstance(got, (bytes, bytearray)) and isinstance(want, (bytes, bytearray)):
            d, at = max_diff(got, want)
            return self.check(False, what, "%d and %d bytes, %d differ, the most (%d) at byte %d"
                              % (len(got), len(want), count_diff(got, want), d, at))
        g, w = repr(got), repr(want)
        return self.check(False, what, "got %s, expected %s" % (g[:300], w[:300]))

    def raises(self, fn, code, what):
        """fn() must raise relight.ServerError with `code` (None: any code)."""
        try:
            fn()
        except relight.ServerError as e:
            return self.check(code is None or e.code == code, what,
                              "error %s: %s, expected %s" % (e.code, e.message, code))
        except Exception as e:
            return self.check(False, what, "raised %r, expected error %s" % (e, code))
        return self.check(False, what, "no error, expected %s" % code)

    def run(self, fn, *args):
        """Call a section; an exception counts as a failed check and the
        test goes on with the next section."""
        try:
            return fn(*args)
        except Exception:
            self.check(False, "%s raised" % fn.__name__, traceback.format_exc(limit=6))
        return None

    def note(self, text):
        print("%s: %s" % (self.name, text), flush=True)

    def finish(self):
        print("%s: %d checks, %d failed" % (self.name, self.checks, self.failures), flush=True)
        sys.exit(1 if self.failures else 0)


def skip(why):
    print("SKIP: " + why, flush=True)
    sys.exit(SKIP)


def args():
    """(relightd, relight) from the command line, as absolute paths."""
    if len(sys.argv) < 3:
        sys.exit("usage: %s PATH/TO/relightd PATH/TO/relight" % sys.argv[0])
    return os.path.abspath(sys.argv[1]), os.path.abspath(sys.argv[2])


# ---------------------------------------------------------------------------
# Shots
# ---------------------------------------------------------------------------


def bake_shots(relight_exe):
    """The folder of baked example shots (BUILD/integration-shots): each
    example's RIB copied there and baked with `relight bake`, once; again
    when the example's RIB or the relight that bakes is newer than its shot
    (a rebuilt renderer may bake other values). Tests run in parallel, so a
    lock file serialises the baking."""
    shots = os.path.join(build_dir(), "integration-shots")
    os.makedirs(shots, exist_ok=True)
    with open(os.path.join(build_dir(), "integration-shots.lock"), "w") as lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        for name, rib in EXAMPLES.items():
            src = os.path.join(SOURCE_DIR, "examples", name, rib)
            shot = os.path.join(shots, name + ".shot.exr")
            newest = max(os.path.getmtime(src), os.path.getmtime(relight_exe))
            if os.path.exists(shot) and os.path.getmtime(shot) >= newest:
                continue
            shutil.copyfile(src, os.path.join(shots, rib))
            r = subprocess.run([relight_exe, "bake", "-q", rib], cwd=shots,
                               stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300)
            if r.returncode != 0 or not os.path.exists(shot):
                sys.exit("cannot bake %s (status %d): %s"
                         % (rib, r.returncode, r.stderr.decode(errors="replace")[:2000]))
    return shots


def link_or_copy(src, dst):
    try:
        os.link(src, dst)
    except OSError:
        shutil.copyfile(src, dst)


# ---------------------------------------------------------------------------
# The daemon
# ---------------------------------------------------------------------------


class Daemon:
    """relightd on 127.0.0.1 and a free port, with its own snapshot folder.

    `extra` are more command-line options; `tokens` (lines "TOKEN ROLE")
    become a token file. Exits 77 (skip) when the daemon cannot get an EGL
    context. stop() sends SIGTERM and returns the problems found: a status
    other than 0, sanitizer reports in stderr.
    """

    def __init__(self, relightd, shots, extra=(), tokens=None, start_timeout=60, env=None):
        self.tmp = tempfile.mkdtemp(prefix="relightd-", dir=build_dir())
        self.snapshots = os.path.join(self.tmp, "snapshots")
        os.mkdir(self.snapshots)
        self.shots = shots
        cmd = [relightd, "--listen", "127.0.0.1:0", "--shots", shots,
               "--snapshots", self.snapshots]
        if tokens is not None:
            self.token_file = os.path.join(self.tmp, "tokens")
            with open(self.token_file, "w") as f:
                f.write("".join(line + "\n" for line in tokens))
            cmd += ["--token-file", self.token_file]
        cmd += list(extra)
        # More options for debugging a run, e.g. "--log-level debug".
        cmd += os.environ.get("RELIGHT_DAEMON_ARGS", "").split()
        self.cmd = cmd
        self.stderr_path = os.path.join(self.tmp, "stderr")
        self._stderr = open(self.stderr_path, "wb")
        full_env = None
        if env:
            full_env = dict(os.environ)
            full_env.update(env)
        self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=self._stderr,
                                     cwd=self.tmp, env=full_env)
        self.port = None
        line = self._read_line(start_timeout)
        if line is None:
            status = self.proc.poll()
            if status is None:
                self.proc.kill()
                self.proc.wait()
            err = self.stderr()
            if "EGL" in err:
                skip("relightd cannot get an EGL context: " + err[:300])
            raise RuntimeError("relightd did not start (status %s): %s" % (status, err[:2000]))
        prefix = "relightd: listening on "
        scheme = line[len(prefix):].split("://", 1)[0]
        if not line.startswith(prefix) or scheme not in ("http", "https"):
            self.proc.kill()
            raise RuntimeError("relightd printed %r, not its listening line" % line)
        hostport = line[len(prefix) + len(scheme) + 3:].rstrip("/")
        self.port = int(hostport.rsplit(":", 1)[1])
        self.url = "%s://127.0.0.1:%d/ws" % ("wss" if scheme == "https" else "ws", self.port)
        self.pid = self.proc.pid
        # Keep stdout drained: a daemon that writes more must never block on it.
        self._out = threading.Thread(target=self.proc.stdout.read, daemon=True)
        self._out.start()

    def _read_line(self, timeout):
        result = []

        def read():
            result.append(self.proc.stdout.readline().decode(errors="replace"))

        t = threading.Thread(target=read, daemon=True)
        t.start()
        t.join(timeout)
        if not result or not result[0].endswith("\n"):
            return None
        return result[0].strip()

    def stderr(self):
        if not self._stderr.closed:
            self._stderr.flush()
        with open(self.stderr_path, "rb") as f:
            return f.read().decode(errors="replace")

    def alive(self):
        return self.proc.poll() is None

    def client(self, **kw):
        return relight.Client(self.url, **kw)

    def ws(self, **kw):
        """A raw WebSocket to /ws, no hello sent."""
        return relight.WebSocket.connect(self.url, **kw)

    def http(self, path, timeout=10):
        """(status, body) of a plain HTTP/1.0 GET."""
        s = socket.create_connection(("127.0.0.1", self.port), timeout=timeout)
        try:
            s.sendall(("GET %s HTTP/1.0\r\nHost: 127.0.0.1\r\n\r\n" % path).encode())
            data = b""
            while True:
                chunk = s.recv(65536)
                if not chunk:
                    break
                data += chunk
        finally:
            s.close()
        head, _, body = data.partition(b"\r\n\r\n")
        parts = head.split(b" ", 2)
        return (int(parts[1]) if len(parts) > 1 and parts[1].isdigit() else 0), body

    def metric(self, name):
        """A counter or gauge from /metrics (the sum over its label sets), or None."""
        status, body = self.http("/metrics")
        total = None
        for line in body.decode(errors="replace").splitlines():
            if line.startswith("#"):
                continue
            key, _, value = line.rpartition(" ")
            if key.split("{")[0] == name:
                total = (total or 0) + float(value)
        return total

    def sanitized(self):
        """Whether the daemon runs with AddressSanitizer."""
        try:
            with open("/proc/%d/maps" % self.pid) as f:
                return "libasan" in f.read()
        except OSError:
            return False

    def rss_kb(self):
        """VmRSS of the daemon, in kB."""
        with open("/proc/%d/status" % self.pid) as f:
            for line in f:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
        return 0

    def stop(self, timeout=30, keep=False):
        """SIGTERM; the problems found (empty when it exited 0 cleanly).
        Its stderr is kept (and named) when there are problems or `keep`."""
        problems = []
        if self.proc.poll() is not None:
            problems.append("relightd had already exited with status %d" % self.proc.returncode)
        else:
            self.proc.send_signal(signal.SIGTERM)
            try:
                self.proc.wait(timeout)
            except subprocess.TimeoutExpired:
                problems.append("relightd did not exit within %d s of SIGTERM" % timeout)
                self.proc.kill()
                self.proc.wait()
        if self.proc.returncode != 0 and not problems:
            problems.append("relightd exited with status %d after SIGTERM" % self.proc.returncode)
        err = self.stderr()
        bad = [line for line in err.splitlines()
               if "AddressSanitizer" in line or "LeakSanitizer" in line or "runtime error" in line]
        if bad:
            problems.append("sanitizer report in stderr: " + " | ".join(bad[:5]))
        self._stderr.close()
        if not problems and not keep:
            shutil.rmtree(self.tmp, ignore_errors=True)
        else:
            print("relightd's stderr is kept in " + self.stderr_path, file=sys.stderr)
        return problems

    def finish(self, checks):
        """stop() and count its outcome as a check."""
        problems = self.stop(keep=checks.failures > 0)
        checks.check(not problems, "relightd stops cleanly on SIGTERM", "; ".join(problems))


# ---------------------------------------------------------------------------
# Reference images
# ---------------------------------------------------------------------------


def decode_png(data):
    """(width, height, channels, pixels) of an 8-bit, non-interlaced PNG
    (grey, grey+alpha, RGB or RGBA), every filter type undone."""
    if data[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("not a PNG")
    pos, idat, ihdr = 8, [], None
    while pos < len(data):
        n, kind = struct.unpack_from(">I4s", data, pos)
        body = data[pos + 8:pos + 8 + n]
        crc = struct.unpack_from(">I", data, pos + 8 + n)[0]
        if zlib.crc32(kind + body) != crc:
            raise ValueError("bad CRC in chunk %r" % kind)
        if kind == b"IHDR":
            ihdr = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            idat.append(body)
        elif kind == b"IEND":
            break
        pos += 12 + n
    w, h, depth, ctype, _, _, interlace = ihdr
    channels = {0: 1, 4: 2, 2: 3, 6: 4}[ctype]
    if depth != 8 or interlace:
        raise ValueError("only 8-bit non-interlaced PNGs")
    raw = zlib.decompress(b"".join(idat))
    stride = w * channels
    out = bytearray(stride * h)
    prev = bytearray(stride)
    for y in range(h):
        f = raw[y * (stride + 1)]
        line = bytearray(raw[y * (stride + 1) + 1:(y + 1) * (stride + 1)])
        for i in range(stride if f else 0):
            a = line[i - channels] if i >= channels else 0
            b = prev[i]
            c = prev[i - channels] if i >= channels else 0
            if f == 1:
                line[i] = (line[i] + a) & 255
            elif f == 2:
                line[i] = (line[i] + b) & 255
            elif f == 3:
                line[i] = (line[i] + (a + b) // 2) & 255
            elif f == 4:
                p = a + b - c
                pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                line[i] = (line[i] + pred) & 255
            elif f != 0:
                raise ValueError("bad filter type %d" % f)
        out[y * stride:(y + 1) * stride] = line
        prev = line
    return w, h, channels, bytes(out)


def preview_png(relight_exe, shots, shot, sets=()):
    """(width, height, rgba bytes) of `relight preview --set ... -o x.png`,
    run in the shots folder (where the shadow maps are)."""
    tmp = tempfile.mkdtemp(prefix="preview-", dir=build_dir())
    try:
        out = os.path.join(tmp, "x.png")
        cmd = [relight_exe, "preview", "-q"]
        for s in sets:
            cmd += ["--set", s]
        cmd += ["-o", out, shot + ".shot.exr"]
        r = subprocess.run(cmd, cwd=shots, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                           timeout=120)
        if r.returncode != 0:
            raise RuntimeError("relight preview failed (%d): %s"
                               % (r.returncode, r.stderr.decode(errors="replace")[:1000]))
        with open(out, "rb") as f:
            w, h, ch, px = decode_png(f.read())
        if ch != 4:
            raise RuntimeError("preview PNG has %d channels, not 4" % ch)
        return w, h, px
    finally:
        shutil.rmtree(tmp, ignore_errors=True)


def max_diff(a, b):
    """Largest per-byte difference of two equal-size byte strings, and where (byte index)."""
    worst, at = 0, -1
    if len(a) != len(b):
        return 256, -1
    if a == b:
        return 0, -1
    for i in range(len(a)):
        d = abs(a[i] - b[i])
        if d > worst:
            worst, at = d, i
    return worst, at


def count_diff(a, b):
    """How many bytes differ."""
    return sum(1 for x, y in zip(a, b) if x != y)


def mean(px, channel=None, stride=4):
    """Mean byte value (of one channel when `channel` is given)."""
    if channel is not None:
        px = px[channel::stride]
    return sum(px) / max(1, len(px))


def srgb8(linear):
    """An sRGB-encoded 8-bit value, as the runtime's rgba8 output computes it."""
    if not linear > 0:
        return 0
    if linear >= 1:
        return 255
    if linear <= 0.0031308:
        e = 12.92 * linear
    else:
        e = 1.055 * linear ** (1 / 2.4) - 0.055
    return int(255 * e + 0.5)


class Recorder:
    """Client callbacks that record the event stream: ("tile", Tile-without-data)
    and ("level", edit, level) entries, in arrival order."""

    def __init__(self):
        self.events = []
        self.lock = threading.Lock()

    def on_tile(self, t):
        with self.lock:
            self.events.append(("tile", t.edit, t.level, t.x, t.y, t.width, t.height))

    def on_level(self, m):
        with self.lock:
            self.events.append(("level", m.get("edit"), m.get("level")))

    def take(self):
        with self.lock:
            ev, self.events = self.events, []
        return ev

    def kw(self):
        return {"on_tile": self.on_tile, "on_level": self.on_level}


def wait_until(pred, timeout, step=0.02):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if pred():
            return True
        time.sleep(step)
    return pred()
