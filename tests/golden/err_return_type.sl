// expect-error: 4:9: cannot convert string to color in return
color f()
{
	return "x";
}
surface err_return_type() { Ci = f(); }
