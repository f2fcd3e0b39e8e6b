// expect-error: 4:13: function 'fact' calls itself
float fact(float n)
{
	return n * fact(n - 1);
}
surface err_recursion() { Ci = fact(3); }
