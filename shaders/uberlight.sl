/*
 * uberlight: a light for cinematography after Barzel's model ("Lighting
 * controls for computer cinematography", JGT 1997): a point source whose
 * beam is shaped, clipped and attenuated by independent controls, each one
 * an everyday tool of a gaffer on a film set.
 *
 * The light sits at the origin of its own ("shader") space. A "spot" light
 * aims down that space's +z axis and lights only the half-space in front of
 * it; an "omni" light shines in all directions and ignores the shaping,
 * barn door and slide controls. On the plane z = 1 in front of a spot, a
 * surface point projects to (x, y) = (X/Z, Y/Z): the shaping and barn door
 * controls are curves and lines on that plane.
 *
 * Controls, applied as a product of factors:
 *   cut-on / cut-off  light only between the depths cuton and cutoff (along
 *                     z for a spot, the distance for an omni), fading in
 *                     over nearedge before cuton and out over faredge after
 *                     cutoff
 *   falloff           (falloffdist / distance) ^ falloff, never more than
 *                     maxintensity: 0 is no falloff, 2 the physical one
 *   beam              the cosine to the axis raised to beamdistribution
 *   shape             fully lit inside the superellipse of half-axes
 *                     (width, height), dark outside the one of half-axes
 *                     (width + wedge, height + hedge), a smooth ramp between;
 *                     roundness 1 makes ellipses, 0 rectangles
 *   barn doors        four flaps: light passes for -barnleft <= x <=
 *                     barnright and -barnbottom <= y <= barntop, fading out
 *                     over barnedge beyond each flap's edge
 *   slide             a colour texture (a cookie or gel) stretched over the
 *                     shape's width x height rectangle
 *   shadow            a depth map: shadowed points get Cl * shadowcolor
 *
 * __category names the light for illuminance() category selection;
 * __nondiffuse and __nonspecular set to 1 keep it out of diffuse() or
 * specular().
 */

/* 0 for x <= a, 1 for x >= b, smooth between; a hard step at b when a >= b. */
float
ul_ramp(float a; float b; float x)
{
	float r;

	if (b > a)
		r = smoothstep(a, b, x);
	else
		r = step(b, x);
	return r;
}

/*
 * The superellipse "radius" of (x, y): 1 on the curve
 * |x|^e + |y|^e = 1 with e = 2 / roundness, and growing linearly along
 * each ray from the origin. Dividing by the larger coordinate first keeps
 * the powers from overflowing when the curve is nearly square.
 */
float
ul_shape_radius(float x; float y; float roundness)
{
	float ax = abs(x), ay = abs(y);
	float m = max(ax, ay);
	float r = m;

	if (roundness > 0.01 && m > 0) {
		float e = 2 / roundness;
		r = m * pow(pow(ax / m, e) + pow(ay / m, e), 1 / e);
	}
	return r;
}

/*
 * How much of the beam passes at (x, y): 1 inside the inner curve, 0
 * outside the outer one, and in between a smooth ramp by the fraction of
 * the way from the inner to the outer curve along the ray through (x, y).
 */
float
ul_shape(float x; float y; float width; float height; float wedge; float hedge;
	 float roundness)
{
	float inner = ul_shape_radius(x / width, y / height, roundness);
	float outer = ul_shape_radius(x / (width + wedge), y / (height + hedge), roundness);
	float pass = 1;

	if (inner >= 1) {
		if (outer >= 1) {
			pass = 0;
		} else {
			/* Both radii scale with the distance along the ray, so the
			 * curves cross it at 1/inner and 1/outer of the way to the point. */
			float f = outer * (inner - 1) / (inner - outer);
			pass = 1 - smoothstep(0, 1, f);
		}
	}
	return pass;
}

/* The four barn doors: their flaps' edges are lines on the plane z = 1. */
float
ul_barndoors(float x; float y; float left; float right; float top; float bottom;
	     float edge)
{
	return ul_ramp(-left - edge, -left, x) * (1 - ul_ramp(right, right + edge, x)) *
	       ul_ramp(-bottom - edge, -bottom, y) * (1 - ul_ramp(top, top + edge, y));
}

light
uberlight(string lighttype = "spot";
	  float intensity = 1;
	  color lightcolor = 1;

	  float cuton = 0.01;
	  float cutoff = 1e30;
	  float nearedge = 0;
	  float faredge = 0;

	  float falloff = 0;
	  float falloffdist = 1;
	  float maxintensity = 1;

	  float beamdistribution = 0;
	  float width = 1;
	  float height = 1;
	  float wedge = 0.1;
	  float hedge = 0.1;
	  float roundness = 1;

	  float barnleft = 1e30;
	  float barnright = 1e30;
	  float barntop = 1e30;
	  float barnbottom = 1e30;
	  float barnedge = 0;

	  string slidename = "";

	  string shadowname = "";
	  float shadowsamples = 16;
	  float shadowblur = 0;
	  float shadowbias = -1;
	  float shadowwidth = 1;
	  color shadowcolor = 0;

	  output uniform string __category = "";
	  output uniform float __nondiffuse = 0;
	  output uniform float __nonspecular = 0)
{
	uniform float spot = (lighttype == "omni") ? 0 : 1;
	uniform point origin = point "shader" (0, 0, 0);
	uniform vector axis = normalize(vector "shader" (0, 0, 1));
	uniform float spread = (spot != 0) ? radians(90) : radians(180);

	illuminate(origin, axis, spread) {
		point PL = transform("shader", Ps);
		float dist = max(length(PL), 1e-6);
		float depth = (spot != 0) ? zcomp(PL) : dist;
		float atten = ul_ramp(cuton - nearedge, cuton, depth) *
			      (1 - ul_ramp(cutoff, cutoff + faredge, depth));
		color slide = 1;

		if (falloff != 0)
			atten *= min(pow(falloffdist / dist, falloff), maxintensity);

		if (spot != 0) {
			float z = max(zcomp(PL), 1e-6);
			float x = xcomp(PL) / z;
			float y = ycomp(PL) / z;

			atten *= pow(z / dist, beamdistribution);
			atten *= ul_shape(x, y, width, height, wedge, hedge, roundness);
			atten *= ul_barndoors(x, y, barnleft, barnright, barntop, barnbottom,
					      barnedge);
			if (slidename != "")
				slide = color texture(slidename, (x / width + 1) / 2,
						      (1 - y / height) / 2);
		}

		Cl = atten * intensity * lightcolor * slide;
		if (shadowname != "") {
			float inshadow = shadow(shadowname, Ps, "samples", shadowsamples,
						"blur", shadowblur, "bias", shadowbias,
						"width", shadowwidth);
			Cl *= mix(color 1, shadowcolor, inshadow);
		}
	}
}
