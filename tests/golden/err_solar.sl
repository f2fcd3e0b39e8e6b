// expect-error: 4:7: 'solar' does not take 1 arguments
light err_solar()
{
	solar(vector(0, 0, 1)) { Cl = 1; }
}
