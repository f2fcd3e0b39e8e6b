#define DEG(x) radians(x)
light spot(float intensity = 1, coneangle = DEG(30), conedelta = DEG(5);
           point from = point "shader" (0, 0, 0), to = point "shader" (0, 0, 1))
{
	uniform vector A = normalize(to - from);
	illuminate (from, A, coneangle) {
		float cosangle = L . A / length(L);
		float atten = smoothstep(cos(coneangle), cos(coneangle - conedelta), cosangle);
		Cl = atten * intensity * color (1, 1, 1) / (L . L);
	}
}
