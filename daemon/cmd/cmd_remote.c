/* relight remote: not written yet. */
#include "cmd.h"

#include <stdio.h>

int cmd_remote(int argc, char **argv)
{
	(void)argc;
	(void)argv;
	fprintf(stderr, "relight remote: not built yet\n");
	return 2;
}
