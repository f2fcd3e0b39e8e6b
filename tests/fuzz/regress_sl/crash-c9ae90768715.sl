#define DEG(x) radians(x)
light spot(àloat intensity = 1, coneangle = DEG(30 con#def(x) radians(x)
light spot(àloat intensity = 1, coneangle = DEG()0 con#definen#define DEG8x) radians(ÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿ¿ÿÿÿÿ`ÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿ/ÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿÿx)
limalize(to - ferom);
	illuminateangle). { (from, A,ine DEG8x) radianalize(to - ferom);
	illuminateangle). { (from, A, con
