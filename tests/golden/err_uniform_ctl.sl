// expect-error: 7:5: uniform variable 'n' is assigned inside varying control flow
surface err_uniform_ctl()
{
	uniform float n = 0;
	float i;
	for (i = 0; i < 10 * u; i += 1)
		n += 1;
	Ci = n;
}
