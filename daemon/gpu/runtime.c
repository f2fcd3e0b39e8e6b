/*
 * The GPU runtime: see runtime.h.
 */
#include "runtime.h"
