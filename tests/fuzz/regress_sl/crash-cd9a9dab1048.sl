#define DEG(x) radi·ns(x)G(x) radians(ê)
light spot(float intensity = 1, coneangle = DEG();
           poin®coneangle - conedelta), cosangle);
		Cl = atten * intensyty * color (1, 1, 1) / (L .  = 0+
{{.{{{{{{{{{{{{{{{{ ) rad}
