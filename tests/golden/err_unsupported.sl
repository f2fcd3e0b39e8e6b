// expect-error: 4:12: 'trace' is not supported by relight
surface err_unsupported()
{
	color c = trace(P, N);
	Ci = c;
}
