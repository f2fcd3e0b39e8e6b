/*
 * envcolorlight: a point light at @from whose colour in each direction
 * comes from the environment map @envname, looked up in world space along
 * the direction the light travels (from the light to the lit point), as if
 * the light were a bulb inside a painted glass globe. It falls off with the
 * square of the distance; with no map its colour is white. @blur widens the
 * map's filter, as environment()'s "blur" does. The direction is taken from Ps
 * (not L, the same vector) so that its filter region is Ps's change.
 */
light
envcolorlight(float intensity = 1;
	      point from = point "shader" (0, 0, 0);
	      string envname = "";
	      float blur = 0)
{
	illuminate(from) {
		color c = 1;

		if (envname != "")
			c = color environment(envname, vtransform("world", Ps - from), "blur", blur);
		Cl = intensity * c / (L . L);
	}
}
