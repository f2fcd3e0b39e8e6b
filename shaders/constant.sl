/*
 * constant: the surface colour as it is, unlit. Useful for mattes, cards
 * and anything that should ignore the lights.
 */
surface
constant()
{
	Oi = Os;
	Ci = Os * Cs;
}
