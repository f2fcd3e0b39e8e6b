/* placeholder */
#include "sl.h"
