"""A shot keeps working when its project folder moves, and when its shaders
change only in comments or white space; a change of code still invalidates
it.

The project: a RIB and two shaders of its own (a light and a surface, in
PROJECT/shaders, found through $RELIGHT_SHADER_PATH at bake time), baked
into PROJECT/scene.shot.exr.

Checks:
  - with a comment added to the light shader, its lines re-indented and
    blank lines added, the shot still previews, to the same image;
  - moved (renamed) to another folder, with nothing of it left at the old
    path and no $RELIGHT_SHADER_PATH, the shot opens in relightd and shows
    the same final image as before the move, byte for byte, and
    `relight preview` previews it;
  - with a constant of the light's code changed, the preview fails, saying
    the shader changed since the bake.
"""

import os
import shutil
import subprocess
import sys
import tempfile

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import harness  # noqa: E402

C = harness.Checks("moved")
relightd, relight_exe = harness.args()
WAIT = 120
FINAL = 3

RIB = """Format 160 120 1
PixelSamples 2 2
Projection "perspective" "fov" 40
Display "scene.exr" "file" "rgba"
Translate 0 0 5
WorldBegin
  LightSource "projlight" 1 "intensity" 12 "from" [2 3 -3]
  Surface "projsurf" "Kd" 0.8
  Sphere 1 -1 1 360
WorldEnd
"""


def shader(src, old, new):
    with open(os.path.join(harness.SOURCE_DIR, "shaders", src)) as f:
        text = f.read()
    assert old in text
    return text.replace(old, new)


def preview(shot, out):
    env = dict(os.environ)
    env.pop("RELIGHT_SHADER_PATH", None)
    r = subprocess.run([relight_exe, "preview", "-o", out, shot], cwd=os.path.dirname(shot),
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300, env=env)
    return r.returncode, r.stderr.decode(errors="replace")


def read(path):
    with open(path, "rb") as f:
        return f.read()


def final_image(shots):
    d = harness.Daemon(relightd, shots)
    try:
        c = d.client(timeout=WAIT)
        o = c.open("scene", "rgba8")
        img = c.wait(o["edit"], FINAL).copy()
        c.disconnect()
    finally:
        d.finish(C)
    return img


def main():
    tmp = tempfile.mkdtemp(prefix="moved-", dir=harness.build_dir())
    proj = os.path.join(tmp, "project")
    os.makedirs(os.path.join(proj, "shaders"))
    with open(os.path.join(proj, "scene.rib"), "w") as f:
        f.write(RIB)
    light = shader("pointlight.sl", "pointlight(", "projlight(")
    with open(os.path.join(proj, "shaders", "projlight.sl"), "w") as f:
        f.write(light)
    with open(os.path.join(proj, "shaders", "projsurf.sl"), "w") as f:
        f.write(shader("matte.sl", "matte(", "projsurf("))
    env = dict(os.environ, RELIGHT_SHADER_PATH=os.path.join(proj, "shaders"))
    r = subprocess.run([relight_exe, "bake", "-q", "scene.rib"], cwd=proj, env=env,
                       stdout=subprocess.PIPE, stderr=subprocess.PIPE, timeout=300)
    if not C.check(r.returncode == 0, "the project bakes", r.stderr.decode(errors="replace")):
        C.finish()
    C.section = "in place"
    before = final_image(proj)
    status, err = preview(os.path.join(proj, "scene.shot.exr"), os.path.join(tmp, "before.png"))
    C.check(status == 0, "the shot previews in place", err[-600:])

    C.section = "comments"
    path = os.path.join(proj, "shaders", "projlight.sl")
    relaid = "/* edited after the bake: only comments and layout */\n\n" + "\n".join(
        "    " + line.strip() + "   // note" if line.strip() and not line.strip().startswith(("/*", "*"))
        else line for line in light.splitlines()) + "\n\n\n"
    with open(path, "w") as f:
        f.write(relaid)
    status, err = preview(os.path.join(proj, "scene.shot.exr"), os.path.join(tmp, "comments.png"))
    C.check(status == 0, "a shader changed in comments and white space only keeps the shot",
            err[-600:])
    if status == 0 and os.path.exists(os.path.join(tmp, "before.png")):
        C.check(read(os.path.join(tmp, "comments.png")) == read(os.path.join(tmp, "before.png")),
                "to the same image")

    C.section = "moved"
    moved = os.path.join(tmp, "elsewhere", "project-v2")
    os.makedirs(os.path.dirname(moved))
    os.rename(proj, moved)
    C.check(not os.path.exists(proj), "nothing is left at the old path")
    C.run(lambda: C.check(final_image(moved) == before,
                          "relightd shows the moved shot, the same image byte for byte"))
    shot = os.path.join(moved, "scene.shot.exr")
    status, err = preview(shot, os.path.join(tmp, "moved.png"))
    C.check(status == 0, "relight preview previews the moved shot", err[-600:])
    if status == 0 and os.path.exists(os.path.join(tmp, "before.png")):
        C.check(read(os.path.join(tmp, "moved.png")) == read(os.path.join(tmp, "before.png")),
                "to the same image")

    path = os.path.join(moved, "shaders", "projlight.sl")

    C.section = "code"
    with open(path, "w") as f:
        f.write(light.replace("Cl = intensity * lightcolor", "Cl = 0.5 * intensity * lightcolor"))
    status, err = preview(shot, os.path.join(tmp, "code.png"))
    C.check(status != 0, "a shader whose code changed invalidates the shot")
    C.check("changed since the bake" in err, "the error says the shader changed", err[-600:])
    C.finish()


if __name__ == "__main__":
    main()
