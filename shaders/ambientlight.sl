/*
 * ambientlight: light that arrives equally from everywhere. It has no
 * illuminate or solar statement, so only ambient() sees it.
 */
light
ambientlight(float intensity = 1;
	     color lightcolor = 1)
{
	Cl = intensity * lightcolor;
}
