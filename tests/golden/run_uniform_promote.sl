// A local declared uniform that is given a varying value, or assigned under
// varying control flow, is promoted to varying, as prman and aqsl do: it then
// holds one value per point. On a 4x1 grid u = 0, 1/3, 2/3, 1 at points 0..3.
// grid: 4 1
// kk = 2u
// expect: k[0] = 0 ~1e-6
// expect: k[1] = 0.6666667 ~1e-6
// expect: k[3] = 2 ~1e-6
// nn counts the trips of a loop that runs 1, 2, 3, 4 times
// expect: n[0] = 1 ~0
// expect: n[1] = 2 ~0
// expect: n[2] = 3 ~0
// expect: n[3] = 4 ~0
// a uniform counter of a loop with a varying condition: j stops at 1, 2, 3, 4
// expect: m[0] = 1 ~0
// expect: m[2] = 3 ~0
// expect: m[3] = 4 ~0
// a uniform that nothing makes vary stays one value
// expect: w[*] = 5 ~0
surface run_uniform_promote(output varying float k = 0, n = 0, m = 0;
			    output uniform float w = 0)
{
	uniform float kk = 0;
	if (u > 2)
		Ci = 0;
	kk = u * 2;
	k = kk;
	uniform float nn = 0;
	float i;
	for (i = 0; i < 3 * u + 0.5; i += 1)
		nn += 1;
	n = nn;
	uniform float j;
	for (j = 0; j < 10 && j < 3 * u + 0.5; j += 1)
		;
	m = j;
	uniform float ww = 2;
	ww += 3;
	w = ww;
}
