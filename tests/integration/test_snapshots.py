"""Snapshots are bounded: per client by a rate, per folder by a quota, and a
snapshot whose client has gone is not written.

Checks:
  - a client that asks for 25 snapshots at once with the default
    --snapshot-rate (20 a minute) gets 20 written and the rest refused with
    code "limit", naming the flag; another client still gets its own;
  - a client that asks for 15 snapshots and disconnects at once leaves at
    most 3 written (its queued snapshots are dropped, not run);
  - with --snapshot-max-count 3, the fourth snapshot is refused ("limit",
    naming the flag) and the folder holds 3;
  - with --snapshot-max-bytes 4 and 5 MB of .exr files already in the
    folder, a snapshot is refused ("limit", naming the flag) and the files
    there are untouched.
"""

import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
import relight  # noqa: E402

C = harness.Checks("snapshots")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120


def exr_files(d):
    return sorted(f for f in os.listdir(d.snapshots) if f.endswith(".exr"))


def outcomes(reqs):
    ok, refused, other = 0, [], []
    for r in reqs:
        try:
            r.result()
            ok += 1
        except relight.ServerError as e:
            (refused if e.code == "limit" else other).append(e)
    return ok, refused, other


def rate(d):
    C.section = "rate"
    c = d.client(timeout=WAIT)
    c.open("shadows", "rgba8")
    reqs = [c.request_async("snapshot") for _ in range(25)]
    ok, refused, other = outcomes(reqs)
    C.equal(ok, 20, "20 of 25 snapshots at once are written (--snapshot-rate 20)")
    C.equal(len(refused), 5, "the other 5 are refused with code 'limit'")
    C.check(not other, "no other error", repr(other[:2]))
    C.check(refused and "--snapshot-rate" in refused[0].message,
            "the refusal names --snapshot-rate", refused[0].message if refused else "")
    C.equal(len(exr_files(d)), 20, "the folder holds the 20 written")
    c2 = d.client(timeout=WAIT)
    c2.open("shadows", "rgba8")
    C.check(c2.snapshot(), "another client's snapshot is written (the rate is per client)")
    c2.disconnect()
    c.disconnect()


def gone(d):
    C.section = "client gone"
    before = len(exr_files(d))
    c = d.client(timeout=WAIT)
    c.open("lights32", "rgba8")
    for _ in range(15):
        c.request_async("snapshot")
    c.ws.abort()
    # A later request on the same shot is done after what was queued before it.
    c2 = d.client(timeout=WAIT)
    c2.open("lights32", "rgba8")
    c2.pick(0, 0)
    c2.disconnect()
    written = len(exr_files(d)) - before
    C.check(written <= 3, "at most 3 of the 15 snapshots of a client gone are written",
            "%d written" % written)
    C.note("snapshots of a client gone: %d of 15 written" % written)


def count_quota(d):
    C.section = "count quota"
    c = d.client(timeout=WAIT)
    c.open("shadows", "rgba8")
    for i in range(3):
        c.snapshot()
    C.raises(c.snapshot, "limit", "the fourth snapshot is refused")
    try:
        c.snapshot()
    except relight.ServerError as e:
        C.check("--snapshot-max-count" in e.message, "the refusal names --snapshot-max-count",
                e.message)
    C.equal(len(exr_files(d)), 3, "the folder holds 3 snapshots")
    c.disconnect()


def bytes_quota(d):
    C.section = "bytes quota"
    junk = os.path.join(d.snapshots, "earlier.exr")
    with open(junk, "wb") as f:
        f.write(b"\0" * (5 << 20))
    c = d.client(timeout=WAIT)
    c.open("shadows", "rgba8")
    try:
        c.snapshot()
        C.check(False, "a snapshot over --snapshot-max-bytes is refused")
    except relight.ServerError as e:
        C.equal(e.code, "limit", "a snapshot over --snapshot-max-bytes is refused")
        C.check("--snapshot-max-bytes" in e.message, "the refusal names --snapshot-max-bytes",
                e.message)
    C.equal(exr_files(d), ["earlier.exr"], "the folder's files are untouched")
    C.equal(os.path.getsize(junk), 5 << 20, "the earlier file keeps its size")
    c.disconnect()


def main():
    tmp = tempfile.mkdtemp(prefix="snapshots-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd", "lights32.shot.exr"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own, f))
    d = harness.Daemon(relightd, own)
    C.run(rate, d)
    C.run(gone, d)
    d.finish(C)
    d = harness.Daemon(relightd, own, ["--snapshot-max-count", "3", "--snapshot-rate", "1000"])
    C.run(count_quota, d)
    d.finish(C)
    d = harness.Daemon(relightd, own, ["--snapshot-max-bytes", "4"])
    C.run(bytes_quota, d)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
