/* being written */
#include "spec.h"
