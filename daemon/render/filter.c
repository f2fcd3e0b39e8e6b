/* being written */
#include "scene.h"
