/* being written */
#include "gpu.h"
