/*
 * shinymetal: metal plus a mirror reflection of the surroundings looked up
 * in the environment map @texturename along the reflected view direction,
 * expressed in world space so the map stays fixed as the camera moves.
 * With no map it is the metal shader.
 */
surface
shinymetal(float Ka = 1;
	   float Ks = 1;
	   float Kr = 1;
	   float roughness = .1;
	   string texturename = "")
{
	normal Nf = faceforward(normalize(N), I);
	vector V = -normalize(I);
	color Cr = 0;

	if (texturename != "") {
		vector R = vtransform("world", reflect(I, Nf));
		Cr = Kr * color environment(texturename, R);
	}

	Oi = Os;
	Ci = Os * Cs * (Ka * ambient() + Ks * specular(Nf, V, roughness) + Cr);
}
