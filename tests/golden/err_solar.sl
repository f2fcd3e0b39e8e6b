// expect-error: 4:2: solar() without arguments
light err_solar()
{
	solar() { Cl = 1; }
}
