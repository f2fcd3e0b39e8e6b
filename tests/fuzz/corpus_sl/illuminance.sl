surface lit(float Kd = 1)
{
	normal Nf = faceforward(normalize(N), I);
	color C = 0;
	illuminance ("diffuse", P, Nf, PI / 2) {
		C += Cl * normalize(L) . Nf;
	}
	solar () { }
	Ci = Kd * C * Cs;
}
