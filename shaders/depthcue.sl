/*
 * depthcue: a linear blend towards the background colour with depth in
 * camera space (RISpec 3.2, Appendix A): nothing at mindistance, all of it
 * at maxdistance and beyond.
 *
 *   d = clamp((depth(P) - mindistance) / (maxdistance - mindistance), 0, 1)
 *   Ci = mix(Ci, background, d),  Oi = mix(Oi, 1, d)
 */
volume
depthcue(float mindistance = 0;
	 float maxdistance = 1;
	 color background = 0)
{
	float d = clamp((depth(P) - mindistance) / (maxdistance - mindistance), 0, 1);

	Ci = mix(Ci, background, d);
	Oi = mix(Oi, color(1, 1, 1), d);
}
