// expect-error: 6:4: uniform parameter 'k' is assigned a varying value: the renderer hands
// expect-error: 8:5: output uniform parameter 'o' is assigned inside varying control flow
surface err_uniform_param(float k = 0; output uniform float o = 0)
{
	// A parameter's storage class is its interface: it is not promoted.
	k = u;
	if (v > .5)
		o = 1;
	Ci = k;
}
