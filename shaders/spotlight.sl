/*
 * spotlight: a point light at @from aimed at @to and limited to a cone of
 * half-angle @coneangle. The beam fades out smoothly over the outer
 * @conedeltaangle radians of the cone, is brightest on its axis (the cosine
 * to the axis raised to @beamdistribution) and falls off with the square of
 * the distance.
 */
light
spotlight(float intensity = 1;
	  color lightcolor = 1;
	  point from = point "shader" (0, 0, 0);
	  point to = point "shader" (0, 0, 1);
	  float coneangle = radians(30);
	  float conedeltaangle = radians(5);
	  float beamdistribution = 2)
{
	uniform vector axis = normalize(to - from);
	uniform float outer = cos(coneangle);
	uniform float inner = cos(coneangle - conedeltaangle);

	illuminate(from, axis, coneangle) {
		float dist2 = L . L;
		float cosaxis = (L . axis) / sqrt(dist2);
		float atten = pow(cosaxis, beamdistribution) / dist2;

		atten *= smoothstep(outer, inner, cosaxis);
		Cl = atten * intensity * lightcolor;
	}
}
