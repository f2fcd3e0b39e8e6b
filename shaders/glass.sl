/*
 * Clear glass: the reflected and the refracted ray traced, weighted by the
 * Fresnel factors of a dielectric of index "eta", tinted by Cs, with a
 * specular highlight from the lights. Rays leaving the glass (the normal
 * facing away from the incident ray) cross from eta back to 1.
 */
surface glass(float Ka = 0, Ks = 0.6, Kr = 1, Kt = 1, roughness = 0.05, eta = 1.5)
{
	vector In = normalize(I);
	normal Nn = normalize(N);
	normal Nf = faceforward(Nn, In);
	float ratio = In . Nn < 0 ? 1 / eta : eta;
	float kr = 0, kt = 0;
	vector R = 0, T = 0;
	fresnel(In, Nf, ratio, kr, kt, R, T);
	color c = Kr * kr * trace(P, R);
	if (kt > 0)
		c += Kt * kt * trace(P, T);
	Oi = 1;
	Ci = Cs * (c + Ka * ambient()) + Ks * specular(Nf, -In, roughness);
}
