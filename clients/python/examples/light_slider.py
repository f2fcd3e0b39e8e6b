"""Drive a light's parameter from a slider, as a DCC tool would.

The pattern a DCC application needs: the GUI thread only *sends*
(set_async returns at once, whatever the network does); the client's
reader thread *receives* tiles and level messages and never touches the
GUI; it leaves results in a queue.Queue and in client.image, which the GUI
thread polls from a timer (tkinter's after(); in Maya or Houdini, their own
idle or timer callbacks).

    python3 light_slider.py --url ws://127.0.0.1:7878/ws --shot shadows --light 2
    python3 light_slider.py --shot shadows --light 2 --steps 20    # headless

Headless, it sends N edits spread over the parameter's range, one after the
other, and prints for each the time to its ack, its first level (0) and its
final level (3).
"""

import argparse
import os
import queue
import statistics
import sys
import time

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
import relight  # noqa: E402


def param_range(opened, light, param):
    """(value, min, max) of a light parameter from the "opened" reply."""
    for l in opened["lights"]:
        if l["name"] == light:
            for p in l["params"]:
                if p["name"] == param:
                    v = p["value"]
                    return (v[0] if isinstance(v, list) else v), p["min"], p["max"]
    raise SystemExit("shot %s has no parameter %s.%s" % (opened["shot"], light, param))


def slider_range(value, lo, hi):
    """A range to slide over: the parameter's, narrowed to [0, 2 x value]
    (or [value - 1, value + 1]) where its bounds are far away or absent."""
    a = max(lo, 0.0 if value >= 0 else 2 * value)
    b = min(hi, 2 * value if value > 0 else a + 1.0)
    return a, b


def headless(client, args, lo, hi):
    rows = []
    for i in range(args.steps):
        value = lo + (hi - lo) * i / max(1, args.steps - 1)
        t0 = time.monotonic()
        edit = client.set_async(args.light, {args.param: value}).result()["edit"]
        t_ack = time.monotonic()
        client.wait(edit, level=0)
        t_first = time.monotonic()
        client.wait(edit, level=3)
        t_final = time.monotonic()
        rows.append(((t_ack - t0) * 1e3, (t_first - t0) * 1e3, (t_final - t0) * 1e3))
        print("edit %4d  %s=%-10.4g ack %6.1f ms   level 0 %6.1f ms   final %6.1f ms"
              % ((edit, args.param, value) + rows[-1]))
    if rows:
        med = [statistics.median(r[k] for r in rows) for k in range(3)]
        print("median of %d edits: ack %.1f ms, level 0 %.1f ms, final %.1f ms"
              % (len(rows), med[0], med[1], med[2]))


def gui(client, args, value, lo, hi, events):
    import tkinter as tk

    root = tk.Tk()
    root.title("relight: %s light %s %s" % (args.shot, args.light, args.param))
    img = client.image
    photo = tk.PhotoImage(width=img.width, height=img.height)
    tk.Label(root, image=photo).pack()
    status = tk.StringVar(value="drag the slider")
    tk.Label(root, textvariable=status, anchor="w").pack(fill="x")
    sent = {}                      # request id -> time sent (GUI thread only)

    def on_slide(text):
        # GUI thread: send and return; the ack and tiles arrive on the reader thread.
        req = client.set_async(args.light, {args.param: float(text)})
        sent[req.id] = time.monotonic()
        req.add_done_callback(lambda r: events.put(("ack", r)))

    scale = tk.Scale(root, from_=lo, to=hi, resolution=(hi - lo) / 500, orient="horizontal",
                     length=img.width, label=args.param, command=on_slide)
    scale.set(value)
    scale.pack()
    edit_sent = {}
    shown = [-1]

    def poll():
        # GUI thread: drain what the reader thread left, redraw if tiles came.
        while True:
            try:
                kind, x = events.get_nowait()
            except queue.Empty:
                break
            if kind == "ack" and x.done():
                try:
                    edit_sent[x.result()["edit"]] = sent.pop(x.id, time.monotonic())
                except relight.Error as e:
                    status.set("refused: %s" % e)
            elif kind == "level" and x["edit"] in edit_sent:
                status.set("edit %d: level %d after %.0f ms" % (
                    x["edit"], x["level"], (time.monotonic() - edit_sent[x["edit"]]) * 1e3))
        if img.serial != shown[0]:
            shown[0] = img.serial
            px = img.copy()
            rgb = bytearray(img.width * img.height * 3)
            rgb[0::3], rgb[1::3], rgb[2::3] = px[0::4], px[1::4], px[2::4]
            photo.configure(data=b"P6 %d %d 255\n" % (img.width, img.height) + bytes(rgb),
                            format="ppm")
        root.after(15, poll)

    poll()
    root.mainloop()


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--url", default="ws://127.0.0.1:7878/ws")
    ap.add_argument("--token", default=None)
    ap.add_argument("--shot", required=True)
    ap.add_argument("--light", required=True)
    ap.add_argument("--param", default="intensity")
    ap.add_argument("--steps", type=int, default=0, help="headless: send N edits, print latencies")
    args = ap.parse_args()

    events = queue.Queue()         # reader thread -> GUI thread
    client = relight.Client(args.url, token=args.token, timeout=60,
                            on_level=lambda m: events.put(("level", m)))
    opened = client.open(args.shot, "rgba8")
    client.wait(opened["edit"], level=3)
    value, lo, hi = param_range(opened, args.light, args.param)
    lo, hi = slider_range(value, lo, hi)
    print("%s: %dx%d, %s.%s = %g, sliding over [%g, %g], role %s"
          % (args.shot, opened["width"], opened["height"], args.light, args.param, value, lo, hi,
             client.role))
    try:
        if args.steps > 0:
            headless(client, args, lo, hi)
        else:
            try:
                import tkinter
            except ImportError as e:
                raise SystemExit("no tkinter here (%s): run with --steps N" % e)
            try:
                gui(client, args, value, lo, hi, events)
            except tkinter.TclError as e:
                raise SystemExit("no display here (%s): run with --steps N" % e)
    finally:
        client.disconnect()


if __name__ == "__main__":
    main()
