// With no lights, illuminance runs no body and diffuse() is black.
// expect: Ci[*] = 0.25 0.25 0.25 ~0
surface run_illuminance_none()
{
	Ci = 0.25;
	illuminance(P, N, PI / 2)
		Ci += 1;
	Ci += diffuse(N);
	Oi = 1;
}
