#!/usr/bin/env python3
"""Writes the example scenes of examples/ (RIB). Run from the repository root:
    python3 examples/tools/make_examples.py [--hair-full DIR]
The scenes are committed; this script documents how they were made. With --hair-full
it also writes DIR/hair/, the hair example at lightspeed-2007's 720x389 instead of the
committed 360x195 (for `relight bench --examples DIR hair`)."""
import gzip, math, os, sys

def normalize(v):
    l = math.sqrt(sum(c * c for c in v))
    return [c / l for c in v]

def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]

def look_at(eye, target, up=(0, 1, 0)):
    """World-to-camera for RenderMan's camera (x right, y up, z forward), row vectors."""
    z = normalize([t - e for t, e in zip(target, eye)])
    x = normalize(cross(up, z))
    y = cross(z, x)
    dot = lambda a, b: sum(p * q for p, q in zip(a, b))
    m = [x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
         -dot(eye, x), -dot(eye, y), -dot(eye, z), 1]
    return "Transform [" + " ".join("%.6g" % v for v in m) + "]"

def place(eye, target, up=(0, 1, 0)):
    """Camera-to-world: puts a light that shines down its own +z at eye, aimed at target."""
    z = normalize([t - e for t, e in zip(target, eye)])
    x = normalize(cross(up, z))
    y = cross(z, x)
    m = x + [0] + y + [0] + z + [0] + list(eye) + [1]
    return "ConcatTransform [" + " ".join("%.6g" % v for v in m) + "]"

def quad(y, half):
    return ('Polygon "P" [%g %g %g  %g %g %g  %g %g %g  %g %g %g]'
            % (-half, y, -half, -half, y, half, half, y, half, half, y, -half))

def write(path, text):
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as f:
        f.write(text)

# ---- shadows: the benchmark scene; a shadow pass, MakeShadow, the beauty pass ----
key_from, key_to = (4, 6, -3), (0, 0.5, 2)
cone = 0.45
shadow = """##RenderMan RIB
# A few primitives, plastic surfaces and a shadow-mapped spot light, 640x360 at 4x4
# samples. Frame 1 renders depth from the light; MakeShadow turns it into a map;
# frame 2 renders the view with the map.
version 3.04
FrameBegin 1
  Format 512 512 1
  PixelSamples 1 1
  PixelFilter "box" 1 1
  Hider "hidden" "depthfilter" "midpoint"
  Projection "perspective" "fov" %(fov)g
  Display "key.z" "zfile" "z"
  %(light_cam)s
  WorldBegin
    ShadingRate 4
    Surface "constant"
%(geometry)s
  WorldEnd
FrameEnd
MakeShadow "key.z" "key.shd"
FrameBegin 2
  Format 640 360 1
  PixelSamples 4 4
  PixelFilter "gaussian" 2 2
  Projection "perspective" "fov" 40
  Display "shadows.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "ambientlight" 1 "intensity" 0.08
    LightSource "shadowspot" 2 "intensity" 60 "from" [%(kf)s] "to" [%(kt)s]
        "coneangle" %(cone)g "conedeltaangle" 0.08 "shadowname" "key.shd"
        "samples" 16 "blur" 0.004
    LightSource "pointlight" 3 "intensity" 6 "from" [-4 3 -2] "lightcolor" [0.4 0.5 0.8]
    Surface "plastic" "Kd" 0.7 "Ks" 0.4 "roughness" 0.08
%(geometry)s
  WorldEnd
FrameEnd
"""
geometry = """    AttributeBegin
      Color [0.8 0.8 0.75]
      %s
    AttributeEnd
    AttributeBegin
      Color [0.9 0.25 0.2]
      Translate -0.8 0.7 2
      Sphere 0.7 -0.7 0.7 360
    AttributeEnd
    AttributeBegin
      Color [0.2 0.5 0.9]
      Translate 0.9 0 2.6
      Rotate -90 1 0 0
      Cylinder 0.45 0 1.4 360
      Translate 0 0 1.4
      Disk 0 0.45 360
    AttributeEnd
    AttributeBegin
      Color [0.3 0.8 0.3]
      Translate 0.2 0.25 1.2
      Rotate 90 1 0 0
      Torus 0.35 0.12 0 360 360
    AttributeEnd""" % quad(0, 4)
write("examples/shadows/shadows.rib", shadow % dict(
    fov=2 * math.degrees(cone) + 6, light_cam=look_at(key_from, key_to),
    cam=look_at((0, 2.2, -3.5), (0, 0.6, 2)), geometry=geometry,
    kf="%g %g %g" % key_from, kt="%g %g %g" % key_to, cone=cone))

# ---- lights32: a set lit by 36 lights, several surface shaders ----
lights = ['    LightSource "ambientlight" 1 "intensity" 0.05',
          '    LightSource "distantlight" 2 "intensity" 0.15 "from" [0 1 0] "to" [0.3 0 0.5]']
h = 3
for i in range(24):
    a = 2 * math.pi * i / 24
    c = [0.5 + 0.5 * math.cos(a), 0.5 + 0.5 * math.cos(a + 2.1), 0.5 + 0.5 * math.cos(a + 4.2)]
    lights.append('    LightSource "pointlight" %d "intensity" 0.1 "from" [%.3f 2.2 %.3f] '
                  '"lightcolor" [%.3f %.3f %.3f]' % (h, 3.2 * math.cos(a), 3 + 3.2 * math.sin(a), *c))
    h += 1
for i in range(8):
    a = 2 * math.pi * (i + 0.5) / 8
    f = (2.5 * math.cos(a), 3.5, 3 + 2.5 * math.sin(a))
    lights.append('    LightSource "spotlight" %d "intensity" 1.2 "from" [%.3f %.3f %.3f] '
                  '"to" [%.3f 0 %.3f] "coneangle" 0.35 "conedeltaangle" 0.1'
                  % (h, *f, 0.8 * math.cos(a), 3 + 0.8 * math.sin(a)))
    h += 1
lights.append('    TransformBegin\n      %s\n      LightSource "uberlight" %d "intensity" 0.8'
              ' "width" 0.6 "height" 0.4 "roundness" 0.5\n    TransformEnd'
              % (place((0.01, 4, 0), (0, 0, 3)), h))
h += 1
lights.append('    TransformBegin\n      %s\n      LightSource "uberlight" %d "intensity" 0.6'
              ' "cuton" 0.5 "cutoff" 8 "barnleft" 0.3 "barnedge" 0.05\n    TransformEnd'
              % (place((-3, 1, 1), (0, 0.5, 3)), h))
lights32 = """##RenderMan RIB
# A set lit by %(n)d lights (ambient, distant, 24 point, 8 spot, 2 uberlights) with
# several surface shaders. 320x180, 2x2 samples.
version 3.04
FrameBegin 1
  Format 320 180 1
  PixelSamples 2 2
  Projection "perspective" "fov" 45
  Display "lights32.exr" "file" "rgba"
  %(cam)s
  WorldBegin
%(lights)s
    AttributeBegin
      Surface "matte"
      Color [0.7 0.7 0.7]
      %(floor)s
    AttributeEnd
    AttributeBegin
      Surface "plastic" "roughness" 0.05
      Color [0.9 0.9 0.9]
      Translate 0 0.6 3
      Sphere 0.6 -0.6 0.6 360
    AttributeEnd
    AttributeBegin
      Surface "metal" "roughness" 0.15
      Color [0.9 0.7 0.3]
      Translate -1.6 0.4 3.5
      Sphere 0.4 -0.4 0.4 360
    AttributeEnd
    AttributeBegin
      Surface "defaultsurface"
      Translate 1.5 0 3.4
      Rotate -90 1 0 0
      Cone 1.2 0.5 360
    AttributeEnd
    AttributeBegin
      Surface "paintedplastic" "Kd" 0.8
      Color [0.3 0.6 0.9]
      Translate 0.2 0.3 1.8
      Rotate 60 1 0 0
      Torus 0.3 0.1 0 360 360
    AttributeEnd
  WorldEnd
FrameEnd
""" % dict(n=len(lights), cam=look_at((0, 1.6, -1.5), (0, 0.4, 3)), lights="\n".join(lights),
           floor=quad(0, 6).replace("Polygon", "Polygon").replace(" 6 ", " 6 "))
write("examples/lights32/lights32.rib", lights32)

# ---- motion: motion blur and transparency at 8x8 samples ----
motion = """##RenderMan RIB
# Motion blur and transparency: two moving spheres behind a 40%%-opaque pane,
# 8x8 samples. 320x180.
version 3.04
FrameBegin 1
  Format 320 180 1
  PixelSamples 8 8
  Shutter 0 1
  Projection "perspective" "fov" 40
  Display "motion.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "distantlight" 1 "intensity" 0.9 "from" [-1 2 -1] "to" [0 0 0]
    LightSource "ambientlight" 2 "intensity" 0.15
    Surface "plastic"
    AttributeBegin
      Color [0.6 0.6 0.6]
      %(floor)s
    AttributeEnd
    AttributeBegin
      Color [0.9 0.3 0.1]
      MotionBegin [0 1]
        Translate -1.2 0.5 3
        Translate 0.4 0.5 3
      MotionEnd
      Sphere 0.5 -0.5 0.5 360
    AttributeEnd
    AttributeBegin
      Color [0.2 0.4 0.9]
      MotionBegin [0 1]
        Translate 1 0.35 2.5
        Translate 1 1.0 2.5
      MotionEnd
      Sphere 0.35 -0.35 0.35 360
    AttributeEnd
    AttributeBegin
      Surface "constant"
      Color [0.7 0.9 0.7]
      Opacity [0.4 0.4 0.4]
      Polygon "P" [-0.8 0 1.6  0.2 0 1.6  0.2 1.3 1.6  -0.8 1.3 1.6]
    AttributeEnd
  WorldEnd
FrameEnd
""" % dict(cam=look_at((0, 1.2, -1.5), (0, 0.5, 3)), floor=quad(0, 5))
write("examples/motion/motion.rib", motion)

# ---- lens: depth of field and a moving camera ----
lens = """##RenderMan RIB
# Depth of field and camera motion: a row of spheres receding along a floor,
# seen through a lens (f/2.8, focal length 0.35) focused on the third, while
# the camera slides sideways over the shutter and one sphere moves with it.
# The floor starts in front of the camera: what lies near the eye plane
# blurs over the whole frame through a lens, at a cost to match.
# 4x4 samples. 320x180.
version 3.04
FrameBegin 1
  Format 320 180 1
  PixelSamples 4 4
  Shutter 0 1
  Projection "perspective" "fov" 40
  DepthOfField 2.8 0.35 5.6
  Display "lens.exr" "file" "rgba"
  MotionBegin [0 1]
    %(cam0)s
    %(cam1)s
  MotionEnd
  WorldBegin
    LightSource "distantlight" 1 "intensity" 0.8 "from" [-1 2 -1] "to" [0 0 0]
    LightSource "ambientlight" 2 "intensity" 0.15
    LightSource "spotlight" 3 "intensity" 30 "from" [1.5 4 1] "to" [0 0 4]
        "coneangle" 0.5 "conedeltaangle" 0.1
    Surface "plastic"
    AttributeBegin
      Color [0.6 0.6 0.6]
      %(floor)s
    AttributeEnd
%(spheres)s
    AttributeBegin
      Color [0.9 0.8 0.2]
      MotionBegin [0 1]
        Translate 0.9 0.3 3.2
        Translate 1.2 0.3 3.2
      MotionEnd
      Sphere 0.3 -0.3 0.3 360
    AttributeEnd
  WorldEnd
FrameEnd
"""
lens_spheres = []
for (x, z, r, col) in [(-0.9, 0.8, 0.35, (0.9, 0.3, 0.1)), (-0.3, 2.2, 0.4, (0.2, 0.7, 0.3)),
                       (0.2, 4, 0.5, (0.2, 0.4, 0.9)), (0.9, 7, 0.6, (0.8, 0.3, 0.7)),
                       (1.8, 11, 0.8, (0.3, 0.8, 0.8))]:
    lens_spheres.append("""    AttributeBegin
      Color [%g %g %g]
      Translate %g %g %g
      Sphere %g -%g %g 360
    AttributeEnd""" % (col + (x, r, z, r, r, r)))
lens = lens % dict(cam0=look_at((-0.06, 1.0, -1.6), (0.1, 0.4, 4)),
                   cam1=look_at((0.06, 1.0, -1.6), (0.1, 0.4, 4)),
                   floor='Polygon "P" [-7 0 0.4  -7 0 16  7 0 16  7 0 0.4]',
                   spheres="\n".join(lens_spheres))
write("examples/lens/lens.rib", lens)

# ---- displaced: a displaced sphere on a displaced ground ----
displaced = """##RenderMan RIB
# Displacement: noise-displaced sphere and ground (noisebump), with a matching
# displacementbound. 320x240.
version 3.04
FrameBegin 1
  Format 320 240 1
  PixelSamples 3 3
  Projection "perspective" "fov" 40
  Display "displaced.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "distantlight" 1 "intensity" 1 "from" [-2 3 -1] "to" [0 0 2]
    LightSource "ambientlight" 2 "intensity" 0.1
    AttributeBegin
      Surface "plastic" "roughness" 0.2
      Color [0.8 0.6 0.4]
      Attribute "displacementbound" "sphere" [0.15]
      Displacement "noisebump" "Km" 0.15 "frequency" 3 "octaves" 3
      Translate 0 1 3
      Sphere 0.9 -0.9 0.9 360
    AttributeEnd
    AttributeBegin
      Surface "matte"
      Color [0.5 0.6 0.5]
      Attribute "displacementbound" "sphere" [0.1]
      Displacement "noisebump" "Km" 0.1 "frequency" 1.5
      %(floor)s
    AttributeEnd
  WorldEnd
FrameEnd
""" % dict(cam=look_at((0, 2, -1.5), (0, 0.8, 3)), floor=quad(0, 5))
write("examples/displaced/displaced.rib", displaced)

# ---- fog: atmospheres, one of them lit ----
fog_scene = """##RenderMan RIB
# %(what)s 240x135.
version 3.04
FrameBegin 1
  Format 240 135 1
  PixelSamples 2 2
  Projection "perspective" "fov" 45
  Display "%(name)s.exr" "file" "rgba"
%(option)s  %(cam)s
  WorldBegin
    LightSource "pointlight" 1 "intensity" 6 "from" [-1.5 2.5 2]
    LightSource "spotlight" 2 "intensity" 12 "from" [2 3 1] "to" [0 0 5] "coneangle" 0.5
    LightSource "ambientlight" 3 "intensity" 0.05
    %(atmosphere)s
    AttributeBegin
      Surface "matte"
      Color [0.6 0.6 0.55]
      %(floor)s
    AttributeEnd
%(spheres)s  WorldEnd
FrameEnd
"""
fog_spheres = ""
for i, (x, z, c) in enumerate([(-1.2, 2.5, "0.9 0.3 0.2"), (0.4, 4.5, "0.2 0.6 0.9"),
                               (1.6, 7.5, "0.9 0.8 0.3"), (-0.6, 11, "0.4 0.9 0.4")]):
    fog_spheres += """    AttributeBegin
      Surface "plastic" "roughness" 0.15
      Color [%s]
      Translate %g 0.6 %g
      Sphere 0.6 -0.6 0.6 360
    AttributeEnd
""" % (c, x, z)
fog_common = dict(cam=look_at((0, 1.2, -1), (0, 0.6, 5)), floor=quad(0, 14), spheres=fog_spheres)
write("examples/fog/fog.rib", fog_scene % dict(fog_common, name="fog", option="",
    what="Atmosphere: RISpec's fog (exponential, bluish) over plastic spheres receding along a\n"
         "# matte floor, a point, a spot and an ambient light.",
    atmosphere='Atmosphere "fog" "distance" 8 "background" [0.35 0.4 0.5]'))
write("examples/fog/glow.rib", fog_scene % dict(fog_common, name="glow",
    option='  Option "searchpath" "shader" ".:@"\n',
    what="An atmosphere that reads the lights: glow.sl (beside this file) is fog plus the light\n"
         "# it scatters towards the eye; the same set as fog.rib.",
    atmosphere='Atmosphere "glow" "distance" 8 "background" [0.1 0.1 0.12] "scatter" 0.04'))

# ---- crowd: a street crowd at 8x8 samples, most of what is shaded hidden ----
def lcg(seed):
    """A small deterministic generator, so the scene does not depend on Python's."""
    state = [seed]
    def next_value():
        state[0] = (state[0] * 1103515245 + 12345) % 2147483648
        return state[0] / 2147483648.0
    return next_value

rnd = lcg(2007)
clothes = [(0.55, 0.12, 0.1), (0.15, 0.25, 0.5), (0.3, 0.3, 0.32), (0.6, 0.5, 0.25),
           (0.2, 0.4, 0.25), (0.7, 0.7, 0.68), (0.4, 0.2, 0.35), (0.1, 0.1, 0.12)]
skins = [(0.85, 0.65, 0.5), (0.6, 0.42, 0.3), (0.45, 0.3, 0.2), (0.9, 0.75, 0.62)]

def figure(x, z, turn, height, body, skin, surface, motion=None):
    """A figure: a body (cylinder with a rounded top), a neck and a head; with
    motion, (dx, dz) is how far it moves while the shutter is open."""
    lines = ["    AttributeBegin"]
    if motion:
        lines += ["      MotionBegin [0 0.5]",
                  "        Translate %.3f 0 %.3f" % (x, z),
                  "        Translate %.3f 0 %.3f" % (x + motion[0], z + motion[1]),
                  "      MotionEnd"]
    else:
        lines.append("      Translate %.3f 0 %.3f" % (x, z))
    shoulders = 0.78 * height
    lines += ["      Rotate %.1f 0 1 0" % turn,
              "      %s" % surface,
              "      Color [%.3f %.3f %.3f]" % body,
              "      AttributeBegin",
              "        Scale 1 1 0.7",
              "        Rotate -90 1 0 0",
              "        Cylinder 0.2 0 %.3f 360" % shoulders,
              "        Translate 0 0 %.3f" % shoulders,
              "        Sphere 0.2 0 0.2 360",
              "      AttributeEnd",
              "      Color [%.3f %.3f %.3f]" % skin,
              "      Translate 0 %.3f 0" % (shoulders + 0.16),
              "      Rotate -90 1 0 0",
              "      Cylinder 0.05 0 0.08 360",
              "      Translate 0 0 0.19",
              "      Sphere 0.12 -0.12 0.12 360",
              "    AttributeEnd"]
    return "\n".join(lines)

people = []
rows = [(3.0, 3), (4.2, 5), (5.5, 5), (7.0, 6), (8.8, 6), (11.0, 7), (14.0, 6)]
n = 0
for z, count in rows:
    # spread each row over about the width the camera sees at that depth
    width = 0.75 * (z + 1.0) * 2
    for i in range(count):
        x = -width / 2 + width * (i + 0.5 + 0.6 * (rnd() - 0.5)) / count
        zz = z + 0.8 * (rnd() - 0.5)
        height = 1.55 + 0.25 * rnd()
        turn = 360 * rnd()
        body = clothes[n % len(clothes)]
        skin = skins[(n * 3 + 1) % len(skins)]
        surface = ('Surface "plastic" "Kd" 0.7 "Ks" 0.25 "roughness" %.2f' % (0.08 + 0.2 * rnd())
                   if n % 3 else 'Surface "matte"')
        # a few walk across the frame, one runs
        motion = {4: (0.12, 0.0), 9: (-0.1, -0.05), 13: (0.5, 0.0), 18: (-0.15, 0.05)}.get(n)
        people.append(figure(x, zz, turn, height, body, skin, surface, motion))
        n += 1

props = []
# lamp posts down the right side of the street, and their lamps
for i, z in enumerate((5.0, 11.0, 17.0)):
    props.append("""    AttributeBegin
      Surface "metal" "roughness" 0.15
      Color [0.5 0.5 0.55]
      Translate 3.2 0 %g
      Rotate -90 1 0 0
      Cylinder 0.06 0 3.6 360
      Translate 0 0 3.6
      Sphere 0.16 -0.16 0.16 360
    AttributeEnd""" % z)
# a bench (bilinear patches on metal legs), left foreground
props.append("""    AttributeBegin
      Surface "plastic" "Kd" 0.6 "Ks" 0.2 "roughness" 0.2
      Color [0.45 0.3 0.18]
      Translate -2.3 0 2.6
      Rotate 20 0 1 0
      Patch "bilinear" "P" [-0.9 0.45 -0.2  0.9 0.45 -0.2  -0.9 0.45 0.2  0.9 0.45 0.2]
      Patch "bilinear" "P" [-0.9 0.45 0.2  0.9 0.45 0.2  -0.9 0.9 0.25  0.9 0.9 0.25]
      Surface "metal" "roughness" 0.2
      Color [0.3 0.3 0.3]
      Translate -0.8 0 0
      Rotate -90 1 0 0
      Cylinder 0.04 0 0.45 360
      Translate 1.6 0 0
      Cylinder 0.04 0 0.45 360
    AttributeEnd""")
# a glass shelter panel in front of the crowd on the right, and a balloon
props.append("""    AttributeBegin
      Surface "plastic" "Kd" 0.3 "Ks" 0.6 "roughness" 0.05
      Color [0.6 0.75 0.8]
      Opacity [0.3 0.3 0.3]
      Translate 1.7 0 3.0
      Rotate -25 0 1 0
      Patch "bilinear" "P" [-0.7 2.1 0  0.7 2.1 0  -0.7 0.2 0  0.7 0.2 0]
    AttributeEnd
    AttributeBegin
      Surface "plastic" "Kd" 0.6 "Ks" 0.5 "roughness" 0.05
      Color [0.9 0.2 0.3]
      Opacity [0.75 0.75 0.75]
      Translate -0.6 2.5 7.0
      Sphere 0.3 -0.3 0.3 360
    AttributeEnd""")

# windows and doors on the building's front
openings = []
for floor in range(4):
    for col in range(-8, 8):
        x = 2.6 * col + 0.65
        if floor == 0:
            if col % 3:
                continue
            y0, y1 = 0, 2.6
        else:
            y0, y1 = 3.6 * floor, 3.6 * floor + 2.0
        openings.append('      Patch "bilinear" "P" [%g %g 21.95  %g %g 21.95  %g %g 21.95  %g %g 21.95]'
                        % (x, y1, x + 1.3, y1, x, y0, x + 1.3, y0))
props.insert(0, """    AttributeBegin
      Surface "plastic" "Kd" 0.3 "Ks" 0.7 "roughness" 0.04
      Color [0.12 0.14 0.17]
%s
    AttributeEnd""" % "\n".join(openings))

crowd = """##RenderMan RIB
# A street crowd: %(n)d figures in rows at several depths (a few walking, one
# running, motion-blurred), lamp posts, a bench, a glass panel and a balloon in
# front of a building, on a street that runs out of frame. Sun, sky fill, a
# spot on the middle of the crowd and a warm street lamp. 320x180 at 8x8 samples,
# shading rate 1: like a production shot, most of what is shaded ends up hidden.
version 3.04
FrameBegin 1
  Format 320 180 1
  PixelSamples 8 8
  ShadingRate 1
  Shutter 0 0.5
  Projection "perspective" "fov" 40
  Display "crowd.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "ambientlight" 1 "intensity" 0.12 "lightcolor" [0.6 0.7 1]
    LightSource "distantlight" 2 "intensity" 0.9 "lightcolor" [1 0.92 0.8]
        "from" [-4 6 -2] "to" [0 0 4]
    LightSource "spotlight" 3 "intensity" 40 "from" [1.5 7 2] "to" [0 0.8 7.5]
        "coneangle" 0.3 "conedeltaangle" 0.1
    LightSource "pointlight" 4 "intensity" 2.5 "from" [3 3.3 11] "lightcolor" [1 0.75 0.45]
    AttributeBegin
      Surface "matte"
      Color [0.42 0.41 0.4]
      Polygon "P" [-40 0 -5  -40 0 60  40 0 60  40 0 -5]
    AttributeEnd
    AttributeBegin
      Surface "plastic" "Kd" 0.6 "Ks" 0.1 "roughness" 0.3
      Color [0.62 0.55 0.48]
      Patch "bilinear" "P" [-30 14 22  30 14 22  -30 0 22  30 0 22]
    AttributeEnd
%(props)s
%(people)s
  WorldEnd
FrameEnd
""" % dict(n=len(people), cam=look_at((0, 1.75, -1.5), (0.2, 1.2, 10)),
           props="\n".join(props), people="\n".join(people))
write("examples/crowd/crowd.rib", crowd)

# ---- textured_lights: slides, a cookie, a projector, environment lights, fog, an imager ----
def pattern_frame(n, display, width, height, cells, filt="\"box\" 1 1"):
    """A frame that renders colour cells to @display (@filt softens their edges): an
    image for MakeTexture."""
    a = width / height
    out = ["FrameBegin %d" % n,
           "  Format %d %d 1" % (width, height),
           "  PixelSamples 1 1",
           '  PixelFilter %s' % filt,
           '  Projection "orthographic"',
           '  Display "%s" "file" "rgb"' % display,
           "  WorldBegin",
           '    Surface "constant"']
    nx, ny = len(cells[0]), len(cells)
    for j in range(ny):
        for i in range(nx):
            x0, x1 = -a + 2 * a * i / nx, -a + 2 * a * (i + 1) / nx
            y1, y0 = 1 - 2 * j / ny, 1 - 2 * (j + 1) / ny
            out.append("    Color [%s]" % " ".join("%.3g" % c for c in cells[j][i]))
            out.append('    Polygon "P" [%g %g 1  %g %g 1  %g %g 1  %g %g 1]'
                       % (x0, y0, x0, y1, x1, y1, x1, y0))
    out += ["  WorldEnd", "FrameEnd"]
    return "\n".join(out)

palette = [(0.95, 0.2, 0.15), (0.2, 0.8, 0.25), (0.2, 0.35, 0.95), (0.95, 0.85, 0.2),
           (0.9, 0.3, 0.85), (0.2, 0.85, 0.9), (1, 1, 1), (0.15, 0.15, 0.15)]
slide_a = [[palette[(i + 2 * j) % 8] for i in range(4)] for j in range(4)]
slide_b = [[palette[(3 * i + 1) % 8] for i in range(8)]]
cookie = [[(1, 1, 1) if (i % 2 == 0 and j % 2 == 0) else (0.05, 0.05, 0.05) for i in range(6)]
          for j in range(6)]
sky = [(0.9, 0.55, 0.3), (1, 0.9, 0.6), (0.5, 0.8, 1), (0.3, 0.4, 0.9)]
env = [[[sky[j][c] * (0.6 + 0.4 * ((i * 3 + j) % 4) / 3) for c in range(3)] for i in range(8)]
       for j in range(4)]
# Slides with edges a few texels soft: a texel edge that sharp, magnified on a wall, is
# where the bake's filter regions and the render's differ most.
soft = '"gaussian" 6 6'
maps = "##RenderMan RIB\n" \
    "# The pictures of the textured_lights example, flat colour cells: render this file in\n" \
    "# this folder (relight render maps.rib) to remake the committed .exr files.\n" \
    "version 3.04\n" + "\n".join([pattern_frame(1, "slide_a.exr", 64, 64, slide_a, soft),
                                  pattern_frame(2, "slide_b.exr", 64, 64, slide_b, soft),
                                  pattern_frame(3, "cookie.exr", 48, 48, cookie),
                                  pattern_frame(4, "env.exr", 128, 64, env)]) + "\n"
write("examples/textured_lights/maps/maps.rib", maps)
textured = """##RenderMan RIB
# Lights that read textures: an uberlight with a slide, a spot through a cookie (gobo), a
# slide projector, a point light coloured by a latitude-longitude environment map and an
# environment light (envlight: the irradiance of the same map), under thin fog (RISpec's
# fog as the atmosphere) and composited over a night blue by RISpec's background imager;
# 320x180 at 2x2 samples. The pictures are maps/*.exr (maps/maps.rib renders them);
# MakeTexture and MakeLatLongEnvironment turn them into maps in the current directory.
version 3.04
MakeTexture "maps/slide_a.exr" "slide_a.tx" "black" "black" "box" 1 1
MakeTexture "maps/slide_b.exr" "slide_b.tx" "black" "black" "box" 1 1
MakeTexture "maps/cookie.exr" "cookie.tx" "periodic" "periodic" "box" 1 1
MakeLatLongEnvironment "maps/env.exr" "env.tx" "box" 1 1
FrameBegin 1
  Format 320 180 1
  PixelSamples 2 2
  PixelFilter "gaussian" 2 2
  Projection "perspective" "fov" 45
  Display "textured_lights.exr" "file" "rgba"
  Imager "background" "color bgcolor" [0.05 0.07 0.14]
  %(cam)s
  WorldBegin
    LightSource "ambientlight" 1 "intensity" 0.05
    TransformBegin
      %(slide_place)s
      LightSource "uberlight" 2 "intensity" 1.5 "slidename" "slide_a.tx"
          "width" 0.35 "height" 0.35 "wedge" 0.05 "hedge" 0.05
    TransformEnd
    LightSource "cookielight" 3 "intensity" 25 "from" [3.5 5 0.5] "to" [0.8 0 3.5]
        "coneangle" 0.35 "conedeltaangle" 0.05 "cookiename" "cookie.tx" "cookiescale" 1.5
        "blur" 0.01
    LightSource "projector" 4 "intensity" 14 "from" [0.3 2.2 -1.2] "to" [0 1.6 6]
        "fov" 0.5 "aspect" 1.5 "slidename" "slide_b.tx"
    LightSource "envcolorlight" 5 "intensity" 1.2 "from" [-0.6 1.1 2.4] "envname" "env.tx"
    LightSource "envlight" 6 "intensity" 0.12 "envname" "env.tx" "samples" 16
    Surface "plastic" "Kd" 0.75 "Ks" 0.2 "roughness" 0.15
    Atmosphere "fog" "distance" 40 "background" [0.05 0.07 0.14]
    AttributeBegin
      Color [0.8 0.8 0.78]
      Polygon "P" [-5 0 -3  -5 0 7  5 0 7  5 0 -3]
      Polygon "P" [-5 0 7  -5 5 7  5 5 7  5 0 7]
    AttributeEnd
    AttributeBegin
      Color [0.85 0.85 0.85]
      Translate 0.9 0.6 3.6
      Sphere 0.6 -0.6 0.6 360
    AttributeEnd
    AttributeBegin
      Surface "matte" "Kd" 0.8
      Color [0.7 0.72 0.75]
      Translate -1.3 0 4.4
      Rotate -90 1 0 0
      Cylinder 0.4 0 1.2 360
      Translate 0 0 1.2
      Disk 0 0.4 360
    AttributeEnd
  WorldEnd
FrameEnd
""" % dict(cam=look_at((0, 1.6, -2.2), (0, 1.0, 5)),
           slide_place=place((-3, 3.5, 0), (-0.5, 1.2, 6.5)))
write("examples/textured_lights/textured_lights.rib", textured)

# ---- geometry: every production primitive in one shot, shadows included ----
def grass(rng, n, x0, z0, radius):
    """A tuft of n tapered cubic b-spline blades around (x0, 0, z0)."""
    counts, P, w = [], [], []
    for i in range(n):
        a, r = 2 * math.pi * rng(), radius * math.sqrt(rng())
        x, z = x0 + r * math.cos(a), z0 + r * math.sin(a)
        h = 0.35 + 0.3 * rng()
        lean = (0.25 * (rng() - 0.5), 0.25 * (rng() - 0.5))
        counts.append(5)
        for k in range(5):
            f = k / 4
            P += [x + lean[0] * f * f, h * f, z + lean[1] * f * f]
        w += [0.012, 0.009, 0.005]
    return ('Curves "cubic" [%s] "nonperiodic" "P" [%s] "width" [%s]'
            % (" ".join(map(str, counts)), " ".join("%.4g" % v for v in P),
               " ".join("%g" % v for v in w)))

def circle_trim(cx, cy, r, ccw):
    """A TrimCurve loop: the rational quadratic circle of 9 points (order 3)."""
    k = "0 0 0 .25 .25 .5 .5 .75 .75 1 1 1"
    s2 = math.sqrt(0.5)
    pts = [(1, 0, 1), (s2, s2, s2), (0, 1, 1), (-s2, s2, s2), (-1, 0, 1), (-s2, -s2, s2),
           (0, -1, 1), (s2, -s2, s2), (1, 0, 1)]
    if not ccw:
        pts = [(x, -y, w) for x, y, w in pts]
    u = " ".join("%.9g" % ((cx * w + r * x)) for x, y, w in pts)
    v = " ".join("%.9g" % ((cy * w + r * y)) for x, y, w in pts)
    ws = " ".join("%.9g" % w for x, y, w in pts)
    return k, u, v, ws

def geometry_world(rng):
    ko, uo, vo, wo = circle_trim(0.5, 0.5, 0.45, True)
    ki, ui, vi, wi = circle_trim(0.5, 0.5, 0.2, False)
    trim = ('TrimCurve [1 1] [3 3] [%s %s] [0 0] [1 1] [9 9]\n          [%s %s]\n          [%s %s]\n'
            '          [%s %s]' % (ko, ki, uo, ui, vo, vi, wo, wi))
    return """    AttributeBegin
      Color [0.75 0.75 0.7]
      %(floor)s
    AttributeEnd
    AttributeBegin
      # A Catmull-Clark cube, one edge creased
      Color [0.85 0.55 0.3]
      Translate -1.5 0.55 3.2
      Rotate 25 0 1 0
      Scale 0.5 0.5 0.5
      SubdivisionMesh "catmull-clark" [4 4 4 4 4 4]
        [0 1 3 2  2 3 5 4  4 5 7 6  6 7 1 0  1 7 5 3  6 0 2 4]
        ["crease" "interpolateboundary"] [2 1  0 0] [2 3] [4]
        "P" [-1 -1 1  1 -1 1  -1 1 1  1 1 1  -1 1 -1  1 1 -1  -1 -1 -1  1 -1 -1]
    AttributeEnd
    AttributeBegin
      # A sphere with a bite: CSG difference; the cut shows the biter's colour
      Translate 0 0.6 3.6
      SolidBegin "difference"
        SolidBegin "primitive"
          Color [0.3 0.5 0.9]
          Sphere 0.6 -0.6 0.6 360
        SolidEnd
        SolidBegin "primitive"
          Color [0.95 0.85 0.4]
          Translate -0.3 0.25 -0.45
          Sphere 0.35 -0.35 0.35 360
        SolidEnd
      SolidEnd
    AttributeEnd
    AttributeBegin
      # A trimmed NuPatch: an annulus standing on the floor
      Color [0.8 0.2 0.25]
      Translate 1.9 0.75 4.3
      Rotate -25 0 1 0
      %(trim)s
      NuPatch 2 2 [0 0 1 1] 0 1 2 2 [0 0 1 1] 0 1 "P" [-0.75 -0.75 0  0.75 -0.75 0  -0.75 0.75 0  0.75 0.75 0]
    AttributeEnd
    AttributeBegin
      # Blobby: two ellipsoids and a segment, added
      Color [0.4 0.8 0.4]
      Translate 1.05 0.28 2.3
      Scale 0.55 0.55 0.55
      Blobby 3 [1001 0 1001 16 1002 32 0 3 0 1 2]
        [1.2 0 0 0  0 1.2 0 0  0 0 1.2 0  -0.3 0 0 1
         1 0 0 0  0 1 0 0  0 0 1 0  0.3 0.15 0 1
         0 0 -0.4  0 0 0.4  0.5
         1 0 0 0  0 1 0 0  0 0 1 0  0.05 -0.2 0 1] [""]
    AttributeEnd
    AttributeBegin
      # The teapot, read when its bound is needed
      Color [0.9 0.9 0.85]
      Translate -0.75 0 2.2
      Rotate -90 1 0 0
      Rotate 30 0 0 1
      Scale 0.17 0.17 0.17
      Procedural "DelayedReadArchive" ["archives/teapot.rib"] [-3 3.5 -2 2 0 3.2]
    AttributeEnd
    AttributeBegin
      # Grass and seeds: Curves and Points
      Color [0.45 0.7 0.25]
      Basis "b-spline" 1 "b-spline" 1
      %(grass)s
      Color [0.95 0.9 0.6]
      Opacity [0.7 0.7 0.7]
      Points "P" [%(seeds)s] "constantwidth" [0.05]
    AttributeEnd""" % dict(floor=quad(0, 6), trim=trim, grass=grass(rng, 160, 0.15, 1.7, 0.35),
                          seeds=" ".join("%.3f" % v for i in range(12) for v in
                                         (0.15 + 0.8 * (rng() - 0.5), 0.55 + 0.35 * rng(),
                                          1.7 + 0.6 * (rng() - 0.5))))

geometry_from, geometry_to = (3.5, 5.5, -0.5), (0, 0.3, 2.8)
geometry_scene = """##RenderMan RIB
# Every production primitive in one shot: a Catmull-Clark subdivision cube with a crease,
# a sphere with a bite taken out (CSG difference), a trimmed NuPatch, a Blobby, the teapot
# through a DelayedReadArchive, and grass and seeds (Curves, Points), all casting a
# shadow-mapped spot light's shadow. 320x180 at 4x4 samples.
version 3.04
FrameBegin 1
  Format 512 512 1
  PixelSamples 1 1
  PixelFilter "box" 1 1
  Hider "hidden" "depthfilter" "midpoint"
  Projection "perspective" "fov" %(fov)g
  Display "key.z" "zfile" "z"
  %(light_cam)s
  WorldBegin
    ShadingRate 4
    Surface "constant"
%(world)s
  WorldEnd
FrameEnd
MakeShadow "key.z" "key.shd"
FrameBegin 2
  Format 320 180 1
  PixelSamples 4 4
  Projection "perspective" "fov" 40
  Display "geometry.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "ambientlight" 1 "intensity" 0.08
    LightSource "shadowspot" 2 "intensity" 45 "from" [%(kf)s] "to" [%(kt)s]
        "coneangle" 0.5 "conedeltaangle" 0.08 "shadowname" "key.shd"
        "samples" 16 "blur" 0.004
    LightSource "pointlight" 3 "intensity" 5 "from" [-3 3 0] "lightcolor" [0.5 0.6 0.9]
    Surface "plastic" "Kd" 0.7 "Ks" 0.35 "roughness" 0.1
%(world)s
  WorldEnd
FrameEnd
"""
write("examples/geometry/geometry.rib", geometry_scene % dict(
    fov=2 * math.degrees(0.5) + 6, light_cam=look_at(geometry_from, geometry_to),
    cam=look_at((0, 1.7, -0.8), (0, 0.5, 3)), world=geometry_world(lcg(20)),
    kf="%g %g %g" % geometry_from, kt="%g %g %g" % geometry_to))
write("examples/geometry/archives/teapot.rib", """##RenderMan RIB
# The archive examples/geometry/geometry.rib reads through a DelayedReadArchive.
Geometry "teapot"
""")

# ---- hair: tens of thousands of transparent curves under a deep-shadowed key ----
def hair_strand(rnd, length, cvs):
    """One hair's control points: a root on the upper half of the unit head (not on the
    face), its strand lying over the scalp towards the back and sides, then falling."""
    while True:
        y = 0.05 + 0.95 * rnd()
        phi = 2 * math.pi * rnd()
        r = math.sqrt(1 - y * y)
        root = (r * math.cos(phi), y, r * math.sin(phi))
        # the face looks towards -z: leave the forehead and below bare
        if not (root[2] < -0.35 and root[1] < 0.55):
            break
    # the direction it is combed: away from the face, round the head, a little down
    side = [root[0], 0.0, root[2] + 0.45]
    side = normalize(side) if abs(side[0]) + abs(side[2]) > 1e-3 else [0.0, 0.0, 1.0]
    target = normalize([side[0], -0.25, side[2]])
    lift = 0.05 * rnd()
    pts = []
    # A B-spline passes near its second and next-to-last vertices: those are the root
    # and the tip, the first and last vertices lie beyond them along the strand.
    for k in range(cvs):
        s = (k - 1.0) / (cvs - 3.0) * length
        over = min(1.0, max(0.0, s) / 0.9)    # over the scalp for the first 0.9
        d = normalize([a + (b - a) * over for a, b in zip(root, target)])
        # clear of the scalp by more than the spline's sag between vertices this far apart
        rad = 1.06 + lift * min(1.0, 4 * s / length) if s >= 0 else 0.95
        p = [c * rad for c in d]
        p[1] -= max(0.0, s - 0.9)             # then it falls
        j = 0.03 * max(0.0, s) / length
        pts.append([p[0] + j * (rnd() - 0.5), p[1] + j * (rnd() - 0.5), p[2] + j * (rnd() - 0.5)])
    return pts

def hair_curves(seed, count, batch, cvs):
    """Curves requests of @batch hairs each, B-spline, tapered, a colour per batch."""
    rnd = lcg(seed)
    out = []
    for b0 in range(0, count, batch):
        n = min(batch, count - b0)
        shade = 0.85 + 0.3 * rnd()
        colour = (0.25 * shade, 0.13 * shade, 0.06 * shade)
        p, w = [], []
        for _ in range(n):
            length = 1.3 + 0.5 * rnd()
            p.append("  ".join("%.3f %.3f %.3f" % tuple(q) for q in hair_strand(rnd, length, cvs)))
            w.append(" ".join("%g" % (0.006 - 0.0045 * k / (cvs - 3)) for k in range(cvs - 2)))
        out.append('    AttributeBegin\n      Color [%.3f %.3f %.3f]\n'
                   '      Curves "cubic" [%s] "nonperiodic"\n        "P" [%s]\n'
                   '        "width" [%s]\n    AttributeEnd'
                   % (colour + (" ".join([str(cvs)] * n), "\n          ".join(p), " ".join(w))))
    return "\n".join(out)

hair_key_from, hair_key_to = (3.6, 4.5, 0.8), (0, -0.3, 0)
hair_cone = 0.42
hair = """##RenderMan RIB
# A head of hair: %(count)d B-spline curves (6 vertices, tapered from 0.006 to 0.0015)
# of opacity 0.6 on a skin-coloured head over a floor, %(width)dx%(height)d at 8x8
# samples (lightspeed-2007's hair frame is 720x389). Frame 1 renders a deep shadow map from the key light;
# frame 2 renders the view lit by that key (shadowspot reading the map), a fill and a
# rim light.
version 3.04
FrameBegin 1
  Format 256 256 1
  PixelSamples 4 4
  PixelFilter "box" 1 1
  Projection "perspective" "fov" %(fov)g
  Display "key.dsm" "deepshad" "deepopacity"
  %(light_cam)s
  WorldBegin
    ShadingRate 4
    Surface "constant"
%(shadow_geometry)s
  WorldEnd
FrameEnd
FrameBegin 2
  Format %(width)d %(height)d 1
  PixelSamples 8 8
  PixelFilter "gaussian" 2 2
  Projection "perspective" "fov" 40
  Display "hair.exr" "file" "rgba"
  %(cam)s
  WorldBegin
    LightSource "ambientlight" 1 "intensity" 0.04
    LightSource "shadowspot" 2 "intensity" 45 "from" [%(kf)s] "to" [%(kt)s]
        "coneangle" %(cone)g "conedeltaangle" 0.1 "shadowname" "key.dsm"
        "samples" 16 "blur" 0.002
    LightSource "pointlight" 3 "intensity" 5 "from" [-4 1 3] "lightcolor" [0.45 0.55 0.8]
    LightSource "spotlight" 4 "intensity" 25 "from" [-1.8 3.2 -4.2] "to" [0 0 0]
        "coneangle" 0.5 "conedeltaangle" 0.1 "lightcolor" [1 0.95 0.85]
    Surface "plastic" "Kd" 0.7 "Ks" 0.4 "roughness" 0.08
%(geometry)s
  WorldEnd
FrameEnd
"""
hair_count = 20000
hair_geometry = """    AttributeBegin
      Color [0.5 0.5 0.52]
      %(floor)s
    AttributeEnd
    AttributeBegin
      Color [0.85 0.62 0.5]
      Sphere 1 -1 1 360
    AttributeEnd
    AttributeBegin
      Basis "b-spline" 1 "b-spline" 1
      Opacity [0.6 0.6 0.6]
      %(hair_surface)s
      ReadArchive "strands.rib.gz"
    AttributeEnd"""
# The hairs, read by both frames: gzip-compressed (the RIB reader takes it as it is),
# written without a time stamp so that the file is the same every run.
strands = ("##RenderMan RIB\n# The hairs of hair.rib, written by tools/make_examples.py.\n"
           + hair_curves(2007, hair_count, 1000, 6) + "\n")

def write_hair(folder, width, height):
    os.makedirs(folder, exist_ok=True)
    with open(os.path.join(folder, "strands.rib.gz"), "wb") as f:
        f.write(gzip.compress(strands.encode(), 9, mtime=0))
    write(os.path.join(folder, "hair.rib"), hair % dict(
        count=hair_count, width=width, height=height, fov=2 * math.degrees(hair_cone) + 6,
        light_cam=look_at(hair_key_from, hair_key_to),
        cam=look_at((3.0, 0.7, 3.7), (0, -0.3, 0)),
        shadow_geometry=hair_geometry % dict(floor=quad(-2.0, 5),
                                             hair_surface='Surface "constant"'),
        geometry=hair_geometry % dict(floor=quad(-2.0, 5), hair_surface=
                                      'Surface "hair" "Kd" 0.6 "Ks" 0.12 "roughness" 0.05'),
        kf="%g %g %g" % hair_key_from, kt="%g %g %g" % hair_key_to, cone=hair_cone))

# Committed at half the paper's frame each way: at 720x389 (and 30,000 hairs, a 512x512
# map) the render took over five minutes under AddressSanitizer here, past the examples
# test's limit (examples/README.md).
write_hair("examples/hair", 360, 195)
if len(sys.argv) == 3 and sys.argv[1] == "--hair-full":
    write_hair(os.path.join(sys.argv[2], "hair"), 720, 389)
elif len(sys.argv) > 1:
    sys.exit("usage: make_examples.py [--hair-full DIR]")
