#define DEG(x) radians(x)
light spot(float int#define DEG()ensiCl