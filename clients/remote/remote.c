/* The C client library of the relight protocol: not written yet. */
#include "proto.h"

int remote_version(void);
int remote_version(void)
{
	return PROTO_VERSION;
}
