/*
 * fog: exponential extinction along the ray from the eye (RISpec 3.2,
 * Appendix A). A point at distance l is seen through 1 - exp(-l / distance)
 * of fog of the colour background:
 *
 *   d = 1 - exp(-length(I) / distance)
 *   Ci = mix(Ci, background, d),  Oi = mix(Oi, 1, d)
 */
volume
fog(float distance = 1;
    color background = 0)
{
	float d = 1 - exp(-length(I) / distance);

	Ci = mix(Ci, background, d);
	Oi = mix(Oi, color(1, 1, 1), d);
}
