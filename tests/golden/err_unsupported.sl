// expect-error: 4:12: 'photonmap' is not supported by relight
surface err_unsupported()
{
	color c = photonmap("caustics", P, N);
	Ci = c;
}
