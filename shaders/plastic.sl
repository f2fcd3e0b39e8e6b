/*
 * plastic: a diffuse base tinted by the surface colour under a clear
 * glossy coat whose highlights keep the colour of the light (scaled by
 * @specularcolor).
 */
surface
plastic(float Ka = 1;
	float Kd = .5;
	float Ks = .5;
	float roughness = .1;
	color specularcolor = 1)
{
	normal Nf = faceforward(normalize(N), I);
	vector V = -normalize(I);
	color diffusepart = Cs * (Ka * ambient() + Kd * diffuse(Nf));
	color glosspart = specularcolor * Ks * specular(Nf, V, roughness);

	Oi = Os;
	Ci = Os * (diffusepart + glosspart);
}
