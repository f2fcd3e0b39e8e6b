// expect-error: 2:37: the default of uniform parameter 'k' is varying
surface err_param_default(float k = u)
{
	Ci = k;
}
