/* placeholder: being written */
#include "exec_impl.h"
