surface broken(float a = ; color c)
{
	x = (1 + ;
	if (a b) { y = 2 }
	gather("illuminance", P, N, 1, 8) { }
	while (1) break 2
	z = color (1, 2);
}
