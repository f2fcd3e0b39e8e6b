float sq(float x) { return x * x; }
void accum(output color c; color add) { c += add; }
surface funcs(string texname = ""; float a[3] = {1, 2, 3})
{
	color helper(float t) {
		extern point P;
		return color noise(P * t);
	}
	color c = 0;
	float i;
	for (i = 0; i < 3; i += 1) {
		if (a[i] > 1.5) continue;
		accum(c, helper(sq(a[i])));
	}
	if (texname != "")
		c *= color texture(texname[0], s, t);
	Ci = c ? 1 : 0;
	Oi = 1;
}
