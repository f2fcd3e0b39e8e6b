/*
 * Plastic whose ambient light is scaled by how much of the sky each point
 * sees: 1 - occlusion() over the hemisphere about the normal ("samples"
 * rays, objects within "maxdist"). The occlusion does not depend on the
 * lights, so the bake keeps it and every light edit relights it exactly.
 */
surface occlusionplastic(float Ka = 1, Kd = 0.5, Ks = 0.5, roughness = 0.1;
			 color specularcolor = 1; float samples = 64, maxdist = 1e30)
{
	normal Nf = faceforward(normalize(N), I);
	vector V = -normalize(I);
	float occ = occlusion(P, Nf, samples, "maxdist", maxdist);
	Oi = Os;
	Ci = Os * (Cs * (Ka * (1 - occ) * ambient() + Kd * diffuse(Nf)) +
		   specularcolor * Ks * specular(Nf, V, roughness));
}
