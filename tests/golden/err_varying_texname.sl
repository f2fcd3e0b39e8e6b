// expect-error: 5:7: the name given to texture() must be uniform, not varying
surface err_varying_texname(string a = "a.tx", b = "b.tx")
{
	string name = u > 0.5 ? a : b;
	Ci = texture(name, s, t);
}
