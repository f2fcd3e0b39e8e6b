/*
 * defaultsurface: what a surface looks like when it has no shader of its
 * own. It needs no lights: it is lit as if by a lamp at the eye, brightest
 * where the surface faces the camera and never fully black, so the shape
 * reads in any scene.
 */
surface
defaultsurface(float Kd = .8;
	       float Ka = .2)
{
	float facing = normalize(I) . normalize(N);

	Oi = Os;
	Ci = Os * Cs * (Ka + Kd * facing * facing);
}
