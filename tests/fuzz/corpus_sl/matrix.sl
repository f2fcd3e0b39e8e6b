surface mat()
{
	matrix m = matrix "shader" (1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1);
	matrix n = 1 / m;
	point p = transform(m * n, P);
	vector v = (1, 2, 3) ^ vector(0, 1, 0);
	Ci = color(xcomp(p), ycomp(v), 0);
}
