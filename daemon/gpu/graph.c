/*
 * The computation graph: see graph.h.
 */
#include "graph.h"
