displacement bumps(float Km = 0.1, freq = 4)
{
	float h = Km * noise(transform("shader", P) * freq);
	P += h * normalize(N);
	N = calculatenormal(P);
}
