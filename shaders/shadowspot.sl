/*
 * shadowspot: the spotlight with shadows from a depth map. @shadowname
 * names the map (rendered from the light); with no map it is the plain
 * spotlight. The lookup's options:
 *   samples  points taken in the filter region (more: smoother, slower)
 *   blur     extra softening, as a fraction of the map's width
 *   bias     depth offset against self-shadowing; negative means the
 *            map's own bias
 *   width    multiplies the filter region
 */
light
shadowspot(float intensity = 1;
	   color lightcolor = 1;
	   point from = point "shader" (0, 0, 0);
	   point to = point "shader" (0, 0, 1);
	   float coneangle = radians(30);
	   float conedeltaangle = radians(5);
	   float beamdistribution = 2;
	   string shadowname = "";
	   float samples = 16;
	   float blur = 0;
	   float bias = -1;
	   float width = 1)
{
	uniform vector axis = normalize(to - from);
	uniform float outer = cos(coneangle);
	uniform float inner = cos(coneangle - conedeltaangle);

	illuminate(from, axis, coneangle) {
		float dist2 = L . L;
		float cosaxis = (L . axis) / sqrt(dist2);
		float atten = pow(cosaxis, beamdistribution) / dist2;

		atten *= smoothstep(outer, inner, cosaxis);
		if (shadowname != "")
			atten *= 1 - shadow(shadowname, Ps, "samples", samples,
					    "blur", blur, "bias", bias, "width", width);
		Cl = atten * intensity * lightcolor;
	}
}
