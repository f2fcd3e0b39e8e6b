// Operators and conversions, checked at point 5 of a 4x4 grid (u = v = 1/3).
// expect: f1[5] = 7 ~0
// expect: f2[5] = 0 ~0
// dot and cross of (1,2,3) and (4,5,6): 32 and (-3, 6, -3)
// expect: d[0] = 32 ~0
// expect: x[0] = -3 6 -3 ~0
// float promoted to color, componentwise product, division by zero gives 0
// expect: c[0] = 2 0 1.5 ~0
// comparisons and logic, ?: on varying u
// expect: sel[0] = 1 ~0
// expect: sel[15] = 2 ~0
// expect: lg[5] = 1 ~0
// compound assignment and ++/--
// expect: inc[0] = 12 ~0
// point - point is a vector; casts between triples
// expect: pv[0] = 1 1 1 ~0
surface run_operators(output varying float f1 = 0, f2 = 0, sel = 0, lg = 0;
		      output uniform float d = 0, inc = 0;
		      output uniform vector x = 0, pv = 0; output uniform color c = 0)
{
	f1 = 1 + 2 * 3;
	f2 = 1 / 0;
	vector a = vector(1, 2, 3), b = vector(4, 5, 6);
	d = a . b;
	x = a ^ b;
	c = color(4, 1, 3) * 0.5 / color(1, 0, 1);
	sel = u < 0.5 ? 1 : 2;
	lg = (u > 0.3 && v > 0.3) || u > 5 ? 1 : 0;
	uniform float q = 10;
	q += 4;
	q -= 3;
	q++;
	inc = q;
	point p1 = point(2, 3, 4), p0 = point(1, 2, 3);
	pv = p1 - p0;
}
