// Arrays: initializers, varying indices, element writes, whole-array copies.
// grid: 4 1
// idx = floor(2.9u) = 0, 0, 1, 2
// expect: e[0] = 10 ~0
// expect: e[1] = 10 ~0
// expect: e[2] = 20 ~0
// expect: e[3] = 30 ~0
// after c[idx] = u on a copy: c[2] at point 3 is 1, the original unchanged
// expect: w[3] = 1 ~0
// expect: orig[3] = 30 ~0
// color arrays
// expect: cc[0] = 0 1 0 ~0
surface run_arrays(float arr[3] = {10, 20, 30};
		   output varying float e = 0, w = 0, orig = 0; output varying color cc = 0)
{
	float idx = floor(2.9 * u);
	e = arr[idx];
	float c[3];
	c = arr;
	c[idx] = u;
	w = c[2];
	orig = arr[2];
	color cols[2] = {color(1, 0, 0), color(0, 1, 0)};
	cc = cols[1];
}
