// expect-error: 13:2: 'c' is declared uniform but is assigned under varying control flow at line 12, and it is passed to the output uniform formal 'x' of bump()
// expect-error: 15:11: the name given to texture() must be uniform, not varying ('name' is declared uniform but is assigned a varying value at line 14)
void bump(output uniform float x)
{
	x += 1;
}

surface err_uniform_ref(string a = "a.tx", b = "b.tx")
{
	uniform float c = 0;
	if (u > .5)
		c = 1;
	bump(c);
	uniform string name = u > .5 ? a : b;
	Ci = c * texture(name, s, t);
}
