/*
 * matte: an ideal diffuse (Lambertian) surface.
 *
 *   Ci = Os * Cs * (Ka * ambient + Kd * sum over lights of Cl * max(0, Nf . L))
 */
surface
matte(float Ka = 1;
      float Kd = 1)
{
	normal Nf = faceforward(normalize(N), I);

	Oi = Os;
	Ci = Os * Cs * (Ka * ambient() + Kd * diffuse(Nf));
}
