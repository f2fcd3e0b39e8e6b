/*
 * A shiny metal whose reflections are ray traced: shinymetal's look with
 * trace() along the reflected ray instead of an environment map. "samples"
 * rays in a cone of half-angle "blur" (radians) blur the reflection.
 */
surface raymetal(float Ka = 1, Ks = 1, Kr = 1, roughness = 0.1; float samples = 1, blur = 0)
{
	normal Nf = faceforward(normalize(N), I);
	vector V = -normalize(I);
	vector R = reflect(normalize(I), Nf);
	color reflection = trace(P, R, "samples", samples, "samplecone", blur);
	Oi = Os;
	Ci = Os * Cs * (Ka * ambient() + Ks * specular(Nf, V, roughness) + Kr * reflection);
}
