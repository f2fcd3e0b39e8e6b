// Inlined functions: early return under varying control, output parameters,
// a nested function reading its enclosing function's variable through extern.
// grid: 4 1
// f(u): -u when u <= 0.5, else u*u; b = 2u
// expect: r[0] = 0 ~1e-7
// expect: r[1] = -0.333333343 ~1e-7
// expect: r[2] = 0.444444448 ~1e-6
// expect: r[3] = 1 ~1e-7
// expect: b[3] = 2 ~1e-7
// expect: b[1] = 0.666666687 ~1e-7
// outer(x) = x + 10 * scale, with scale = 3 set by outer and read by inner
// expect: o[2] = 30.6666667 ~1e-5
float f(float a; output float b)
{
	b = a * 2;
	if (a > 0.5)
		return a * a;
	return -a;
}

float outer(float x)
{
	float scale = 3;
	float inner(float y)
	{
		extern float scale;
		return y + 10 * scale;
	}
	return inner(x);
}

surface run_functions(output varying float r = 0, b = 0, o = 0)
{
	r = f(u, b);
	o = outer(u);
}
