// expect-error: 6:8: uniform variable 'k' is assigned a varying value
surface err_uniform()
{
	uniform float k = 0;
	if (u > 2) Ci = 0;
	k = u * 2;
	Ci = k;
}
