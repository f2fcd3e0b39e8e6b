/*
 * glow: fog that also scatters the lights towards the eye. The extinction
 * is RISpec's fog; the scattered light is each light's colour at the surface
 * point, scaled by how much fog there is. It reads the lights, so a light
 * edit relights it.
 *
 *   d = 1 - exp(-length(I) / distance)
 *   Ci = mix(Ci, background, d) + d * scatter * (sum over lights of Cl)
 *   Oi = mix(Oi, 1, d)
 */
volume
glow(float distance = 1;
     color background = 0;
     float scatter = 0.1)
{
	float d = 1 - exp(-length(I) / distance);
	color scattered = 0;

	illuminance (P) {
		scattered += Cl;
	}
	Ci = mix(Ci, background, d) + d * scatter * scattered;
	Oi = mix(Oi, color(1, 1, 1), d);
}
