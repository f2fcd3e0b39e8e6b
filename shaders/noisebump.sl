/*
 * noisebump: a procedural displacement, the surface pushed along its normal
 * by gradient noise of the shader-space position.
 *   Km        displacement amplitude (shader-space units)
 *   frequency features per shader-space unit
 *   octaves   sums of noise at doubling frequencies (1 to 4)
 * Declare a matching "displacementbound": the largest displacement is Km.
 */
displacement
noisebump(float Km = 0.1;
	  float frequency = 4;
	  float octaves = 2)
{
	point Pshad = transform("shader", P) * frequency;
	float sum = 0, amp = 1, total = 0, i;
	for (i = 0; i < clamp(octaves, 1, 4); i += 1) {
		sum += amp * (2 * noise(Pshad) - 1);
		total += amp;
		Pshad *= 2;
		amp *= 0.5;
	}
	normal Nn = normalize(N);
	P += Km * (sum / total) * Nn;
	N = calculatenormal(P);
}
