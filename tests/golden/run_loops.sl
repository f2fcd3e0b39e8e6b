// Loops with per-point trip counts, continue, break and break 2 on a 4x1 grid:
// u = 0, 1/3, 2/3, 1 at points 0..3.
// grid: 4 1
// for: i < 3u + 0.5 runs 1, 2, 3, 4 times
// expect: n[0] = 1 ~0
// expect: n[1] = 2 ~0
// expect: n[2] = 3 ~0
// expect: n[3] = 4 ~0
// while with continue below 2 and break once m > 3u: 2, 2, 3, 4
// expect: m[0] = 2 ~0
// expect: m[1] = 2 ~0
// expect: m[2] = 3 ~0
// expect: m[3] = 4 ~0
// nested for, break 2 once a + b >= 3u: 1, 2, 3, 6 inner iterations
// expect: cnt[0] = 1 ~0
// expect: cnt[1] = 2 ~0
// expect: cnt[2] = 3 ~0
// expect: cnt[3] = 6 ~0
// a uniform loop stays uniform and runs for every point
// expect: k[0] = 6 ~0
surface run_loops(output varying float n = 0, m = 0, cnt = 0; output uniform float k = 0)
{
	float i;
	for (i = 0; i < 3 * u + 0.5; i += 1)
		n += 1;
	while (m < 100) {
		m += 1;
		if (m < 2)
			continue;
		if (m > 3 * u)
			break;
	}
	float a, b;
	for (a = 0; a < 3; a += 1) {
		for (b = 0; b < 3; b += 1) {
			cnt += 1;
			if (a + b >= 3 * u)
				break 2;
		}
	}
	uniform float j;
	for (j = 0; j < 4; j += 1)
		k += j;
}
