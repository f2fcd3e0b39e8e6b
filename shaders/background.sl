/*
 * background: composite the frame over a constant colour (the classic
 * imager of the RenderMan Interface): what the scene leaves uncovered
 * (1 - alpha) takes bgcolor, and every pixel becomes opaque.
 */
imager background(color bgcolor = 1)
{
	Ci += (1 - alpha) * bgcolor;
	Oi = 1;
	alpha = 1;
}
