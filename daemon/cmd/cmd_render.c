/* being written */
#include "sl.h"
