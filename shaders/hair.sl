/*
 * hair: a strand lit as a thin cylinder (Kajiya and Kay, "Rendering Fur with
 * Three Dimensional Textures", 1989). Its tangent is dPdv, the curve's
 * direction (v runs from root to tip), so the normal of the ribbon, which
 * only faces the camera, plays no part. Diffuse light goes as the sine of the
 * angle between the strand and the light; the highlight is brightest where the
 * eye lies on the cone of directions the strand reflects the light into, and
 * @roughness widens it. The strand darkens towards its root by @rootdarken.
 */
surface
hair(float Ka = 1;
     float Kd = .6;
     float Ks = .35;
     float roughness = .15;
     float rootdarken = .4;
     color specularcolor = 1)
{
	vector T = normalize(dPdv);
	vector V = -normalize(I);
	float tv = T . V;
	float sinv = sqrt(max(0, 1 - tv * tv));
	color diff = 0, spec = 0;

	illuminance(P) {
		float tl = T . normalize(L);
		float sinl = sqrt(max(0, 1 - tl * tl));
		diff += Cl * sinl;
		spec += Cl * pow(max(0, sinl * sinv - tl * tv), 1 / roughness);
	}
	color base = Cs * mix(1 - rootdarken, 1, v);
	Oi = Os;
	Ci = Os * (base * (Ka * ambient() + Kd * diff) + Ks * specularcolor * spec);
}
