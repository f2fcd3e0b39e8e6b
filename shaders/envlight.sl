/*
 * envlight: light from all around, out of an environment map, for diffuse
 * surfaces (the PRMan environment-light idiom). A solar() without arguments
 * shines along the normal each surface evaluates its lights with (Ns) and
 * carries the irradiance about that normal:
 *
 *   Cl = intensity * lightcolor * E,  E = integral over the hemisphere about Ns
 *                                         of env(w) (Ns . w) dw
 *
 * so diffuse(N) gives E: a Lambertian surface's answer to the environment,
 * unshadowed. E is a cosine-weighted quadrature. The unit disk under the
 * hemisphere is cut into rings of equal area, each into sectors; a cell is
 * projected up onto the hemisphere (Malley's method) and the map is looked
 * up over the cell's four corners. Every cell weighs PI / cells, so the
 * weights sum to PI and an environment of constant radiance L gives E = PI L.
 * @samples is the number of cells asked for, rounded to 4 r^2 (r rings of
 * 4 r sectors). The map is looked up with the directions in @envspace; an
 * @envname of "" is a constant environment of radiance 1 (E = PI), so the
 * light is then a uniform sky of intensity * lightcolor.
 */
light
envlight(float intensity = 1;
	 color lightcolor = 1;
	 string envname = "";
	 string envspace = "world";
	 float samples = 64;
	 string __category = "")
{
	/* A direction of the hemisphere about n, from polar coordinates on the disk. */
	vector updisk(float r; float phi; vector t; vector b; vector n)
	{
		return r * cos(phi) * t + r * sin(phi) * b + sqrt(max(0, 1 - r * r)) * n;
	}

	uniform float rings = max(1, floor(sqrt(samples / 4) + 0.5));
	uniform float sectors = 4 * rings;
	uniform float w = PI / (rings * sectors);

	solar() {
		color E = PI;
		if (envname != "") {
			vector n = normalize(vector Ns);
			/* Any frame about n: the axis least along it, crossed with it. */
			vector a = abs(zcomp(n)) < 0.9 ? vector(0, 0, 1) : vector(1, 0, 0);
			vector t = normalize(a ^ n);
			vector b = n ^ t;
			/* The frame in the map's space: each direction is a sum over it. */
			t = vtransform(envspace, t);
			b = vtransform(envspace, b);
			n = vtransform(envspace, n);
			float i, j;
			E = 0;
			for (i = 0; i < rings; i += 1) {
				float r0 = sqrt(i / rings), r1 = sqrt((i + 1) / rings);
				for (j = 0; j < sectors; j += 1) {
					float p0 = 2 * PI * j / sectors, p1 = 2 * PI * (j + 1) / sectors;
					vector d1 = updisk(r0, p0, t, b, n);
					vector d2 = updisk(r1, p0, t, b, n);
					vector d3 = updisk(r1, p1, t, b, n);
					vector d4 = updisk(r0, p1, t, b, n);
					E += w * color environment(envname, d1, d2, d3, d4);
				}
			}
		}
		Cl = intensity * lightcolor * E;
	}
}
