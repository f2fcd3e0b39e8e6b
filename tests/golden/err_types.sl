// expect-error: 6:10: operator '+' cannot be applied to color and point
// expect-error: 7:12: cannot convert string to float in initializer
// expect-error: 8:6: no version of 'normalize' takes (string)
surface err_types()
{
	Ci = Cs + P;
	float x = "text";
	x = normalize("a");
}
