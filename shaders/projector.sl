/*
 * projector: a slide projector. A point source at @from aimed at @to throws
 * the picture @slidename onto what it lights, as a gel or a film frame in a
 * projector does: the slide fills the beam, a rectangle @fov radians across
 * its width and @aspect times narrower up and down, with its top towards
 * @up. The picture's edges are the beam's edges, softened over the outer
 * @edge of each side; the light falls off with the square of the distance.
 * With no slide the beam is white. @blur widens the slide's filter (in
 * slide widths), as texture()'s "blur" does.
 */
light
projector(float intensity = 1;
	  color lightcolor = 1;
	  point from = point "shader" (0, 0, 0);
	  point to = point "shader" (0, 0, 1);
	  vector up = vector "shader" (0, 1, 0);
	  float fov = radians(40);
	  float aspect = 1;
	  float edge = 0.02;
	  string slidename = "";
	  float blur = 0)
{
	uniform vector axis = normalize(to - from);
	uniform vector right = normalize(axis ^ up);
	uniform vector top = right ^ axis;
	uniform float halfw = tan(min(max(fov, 1e-4), 3.1) / 2);
	uniform float halfh = halfw / max(aspect, 1e-4);
	uniform float spread = atan(halfw * sqrt(1 + 1 / (max(aspect, 1e-4) * max(aspect, 1e-4))));

	/* illuminate's cone reaches past the beam, so that the points around a
	 * lit one that its slide's filter region is taken from are lit too (the
	 * renderer takes it from its grid neighbours); the frame is 0 there */
	illuminate(from, axis, min(spread + 0.1, 3.1)) {
		/* the slide's coordinates from Ps itself: their filter region is its change */
		vector D = Ps - from;
		float z = max(D . axis, 1e-6);
		float x = (D . right) / (z * halfw);
		float y = (D . top) / (z * halfh);
		float frame = (1 - smoothstep(1 - edge, 1, abs(x))) *
			      (1 - smoothstep(1 - edge, 1, abs(y)));
		color slide = 1;

		if (slidename != "")
			slide = color texture(slidename, (x + 1) / 2, (1 - y) / 2, "blur", blur);
		Cl = frame * intensity * lightcolor * slide / (L . L);
	}
}
