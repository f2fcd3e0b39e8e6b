/*
 * paintedplastic: plastic whose base colour is multiplied by a texture map
 * read at the surface's (s, t). With no map it is the plastic shader.
 */
surface
paintedplastic(float Ka = 1;
	       float Kd = .5;
	       float Ks = .5;
	       float roughness = .1;
	       color specularcolor = 1;
	       string texturename = "")
{
	normal Nf = faceforward(normalize(N), I);
	vector V = -normalize(I);
	color base = Cs;

	if (texturename != "")
		base *= color texture(texturename);

	Oi = Os;
	Ci = Os * (base * (Ka * ambient() + Kd * diffuse(Nf)) +
		   specularcolor * Ks * specular(Nf, V, roughness));
}
