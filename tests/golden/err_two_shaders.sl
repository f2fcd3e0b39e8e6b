// expect-error: 3:9: a second shader 'two'
surface one() { Ci = 1; }
surface two() { Ci = 0; }
