// expect-error: 5:8: undeclared identifier 'Kdd'
surface err_undeclared(float Kd = 1)
{
	Ci = Cs;
	Ci *= Kdd;
}
