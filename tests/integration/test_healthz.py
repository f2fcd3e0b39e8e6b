"""/healthz tells whether the render worker is alive.

A real stall: with Mesa's shader cache off, loading a shot compiles its
programs from scratch (seconds on llvmpipe), one job the worker does not
finish while another client's open waits behind it.

Checks:
  - an idle daemon answers 200 "ok", also after more than --worker-stall
    seconds of idling (idle is not stalled);
  - with --worker-stall 1, while the worker has been on one job for more
    than a second and another job waits, /healthz answers 503 with a reason
    that names --worker-stall;
  - once the jobs are done, 200 "ok" again.
"""

import os
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

C = harness.Checks("healthz")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120


def stall(d):
    C.section = "idle"
    C.equal(d.http("/healthz"), (200, b"ok\n"), "an idle daemon is healthy")
    time.sleep(1.5)
    C.equal(d.http("/healthz"), (200, b"ok\n"), "still healthy after idling past --worker-stall")

    C.section = "stalled"
    a, b = d.client(timeout=WAIT), d.client(timeout=WAIT)
    t0 = time.monotonic()
    ra = a.request_async("open", shot="shadows", format="rgba8")
    time.sleep(0.1)
    rb = b.request_async("open", shot="shadows", format="rgba8")
    seen = None
    while not ra.done():
        status, body = d.http("/healthz")
        if status == 503 and seen is None:
            seen = (time.monotonic() - t0, body.decode(errors="replace"))
        time.sleep(0.05)
    took = time.monotonic() - t0
    C.note("a cold load took %.2f s; 503 seen %s" % (took, "at %.2f s" % seen[0] if seen else "never"))
    if seen is None and took < 1.5:
        harness.skip("the shot loaded in %.2f s, too quickly to stall a worker" % took)
    C.check(seen is not None, "503 while the worker is stuck on one job and another waits",
            "the load took %.2f s" % took)
    C.check(seen and "--worker-stall" in seen[1], "the reason names --worker-stall",
            repr(seen))
    ra.result()
    rb.result()

    C.section = "recovered"
    C.equal(d.http("/healthz"), (200, b"ok\n"), "healthy again once the jobs are done")
    a.disconnect()
    b.disconnect()


def main():
    tmp = tempfile.mkdtemp(prefix="healthz-", dir=harness.build_dir())
    own = os.path.join(tmp, "shots")
    os.mkdir(own)
    for f in ("shadows.shot.exr", "key.shd"):
        harness.link_or_copy(os.path.join(shots, f), os.path.join(own, f))
    os.environ["MESA_SHADER_CACHE_DISABLE"] = "true"
    os.environ["RELIGHT_CACHE_DIR"] = "off"
    d = harness.Daemon(relightd, own, ["--worker-stall", "1"])
    C.run(stall, d)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
