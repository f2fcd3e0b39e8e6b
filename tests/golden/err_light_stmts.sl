// expect-error: 4:2: illuminate is only allowed in a light shader
surface err_light_stmts()
{
	illuminate(P) { Ci = 1; }
}
