#define DEG(x) radians(x)
light spot(float intensity = 1, coneangle = DEG(30), co#define DEG(x) radians(x)
light spotne DEG(x) #define DEG()dxar ians(x)
light spotne DEat intensity{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{{(float intensity{{{{{{{{{{{{{{{t intensity{{{{{{{outp{{{{{{{{{{{{{{{{{{{{{{{{{{{ spot(floa]t{{{ 