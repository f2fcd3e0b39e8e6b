/*
 * cookielight: a spot light (as spotlight.sl, without the beam
 * distribution) whose beam passes through a cookie, a gobo: the first
 * channel of the texture @cookiename masks the light, 1 letting it through
 * and 0 stopping it. The cookie stands square to the beam and spans the
 * cone's width @cookiescale times across (a periodic texture repeats), its
 * top towards @up. @blur widens
 * the cookie's filter, as texture()'s "blur" does. With no cookie it is a
 * plain spot.
 */
light
cookielight(float intensity = 1;
	    color lightcolor = 1;
	    point from = point "shader" (0, 0, 0);
	    point to = point "shader" (0, 0, 1);
	    float coneangle = radians(30);
	    float conedeltaangle = radians(5);
	    string cookiename = "";
	    vector up = vector "shader" (0, 1, 0);
	    float cookiescale = 1;
	    float blur = 0)
{
	uniform vector axis = normalize(to - from);
	uniform vector right = normalize(axis ^ up);
	uniform vector top = right ^ axis;
	uniform float outer = cos(coneangle);
	uniform float inner = cos(coneangle - conedeltaangle);
	uniform float halfw = tan(min(max(coneangle, 1e-4), 1.5));

	/* The lit cone is coneangle wide; illuminate's is wider, so that the
	 * points around a lit one that its cookie's filter region is taken
	 * from are lit too (the renderer takes it from its grid neighbours). */
	illuminate(from, axis, min(coneangle + 0.1, 3.1)) {
		float dist2 = L . L;
		float cosaxis = (L . axis) / sqrt(dist2);
		float atten = (cosaxis > outer) ? smoothstep(outer, inner, cosaxis) / dist2 : 0;

		if (cookiename != "") {
			/* the cookie's coordinates from Ps itself: their filter region is its change */
			vector D = Ps - from;
			float z = max(D . axis, 1e-6);
			float x = cookiescale * (D . right) / (z * halfw);
			float y = cookiescale * (D . top) / (z * halfw);
			atten *= float texture(cookiename, (x + 1) / 2, (1 - y) / 2, "blur", blur);
		}
		Cl = atten * intensity * lightcolor;
	}
}
