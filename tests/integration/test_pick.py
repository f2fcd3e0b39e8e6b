"""Picking (op "pick"): what object a pixel shows and which lights reach it.

Checks (exact):
  - the centre of the shadows shot shows an object (an integer id), and the
    lights reaching it are the shot's lights that are on ("1", "2", "3");
  - a muted light no longer reaches it, and does again once unmuted; solo
    leaves the soloed light alone;
  - every pixel of a 16x9 grid over the image answers, with the same object
    at the same pixel asked twice;
  - a pixel outside the image gets a "range" error, a negative or fractional
    coordinate a "range" or "type" error, and the connection stays usable;
  - a viewer may pick.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402
from harness import relight  # noqa: E402

C = harness.Checks("pick")
relightd, relight_exe = harness.args()
shots = harness.bake_shots(relight_exe)
WAIT = 120


def picking(d):
    C.section = "pick"
    c = d.client(timeout=WAIT, token="editor-token-1234")
    o = c.open("shadows", "rgba8")
    W, H = o["width"], o["height"]
    p = c.pick(W // 2, H // 2)
    C.check(isinstance(p.get("object"), int), "the centre shows an object", repr(p))
    C.equal(sorted(p.get("lights", [])), ["1", "2", "3"], "every light reaches it")
    C.equal((p.get("x"), p.get("y")), (W // 2, H // 2), "the reply names the pixel")
    c.wait(c.mute("3"), 0)
    C.equal(sorted(c.pick(W // 2, H // 2).get("lights", [])), ["1", "2"], "a muted light does not")
    c.wait(c.unmute("3"), 0)
    C.equal(sorted(c.pick(W // 2, H // 2).get("lights", [])), ["1", "2", "3"], "unmuted, it does")
    c.wait(c.solo("2"), 0)
    C.equal(c.pick(W // 2, H // 2).get("lights"), ["2"], "solo: the soloed light alone")
    c.wait(c.solo(None), 0)
    grid = {}
    for gy in range(9):
        for gx in range(16):
            x, y = gx * (W - 1) // 15, gy * (H - 1) // 8
            grid[(x, y)] = c.pick(x, y).get("object", "missing")
    C.check("missing" not in grid.values(), "every pixel of the grid answers")
    C.check(all(c.pick(x, y).get("object") == grid[(x, y)] for (x, y) in list(grid)[:20]),
            "the same pixel twice gives the same object")
    for x, y, codes in ((W, 0, ("range",)), (0, H, ("range",)), (-1, 0, ("range", "type")),
                        (0.5, 0, ("type", "range"))):
        try:
            c.pick(x, y)
            C.check(False, "pick (%r, %r) refused" % (x, y))
        except relight.ServerError as e:
            C.check(e.code in codes, "pick (%r, %r) refused" % (x, y), e.code)
    C.check(c.list() is not None, "the connection stays usable")
    c.disconnect()


def viewer_picks(d):
    C.section = "viewer"
    v = d.client(timeout=WAIT, token="viewer-token-5678")
    C.equal(v.role, "viewer", "a viewer token")
    o = v.open("shadows", "rgba8")
    C.check(isinstance(v.pick(o["width"] // 2, o["height"] // 2).get("object"), int),
            "a viewer may pick")
    v.disconnect()


def main():
    d = harness.Daemon(relightd, shots, tokens=["editor-token-1234 editor",
                                                 "viewer-token-5678 viewer"])
    C.run(picking, d)
    C.run(viewer_picks, d)
    d.finish(C)
    C.finish()


if __name__ == "__main__":
    main()
