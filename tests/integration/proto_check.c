/*
 * proto_check: the protocol codec's verdict on requests, for
 * test_schema.py, which holds protocol/schema/request.schema.json to it.
 *
 *   proto_check < FRAME          one text frame on stdin
 *   proto_check FRAME...         one frame a file
 *
 * For each frame it prints one line: "ok OP" when proto_parse_request (with
 * the default limits) accepts it, else the error's code name and message,
 * separated by a tab. The exit status is 0 when every frame was read and
 * judged, accepted or not, and 2 when a frame could not be read.
 */
#include "proto.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* All of @f, in a buffer of its own (free() it); NULL when it cannot be read. */
static char *read_all(FILE *f, size_t *len)
{
	size_t cap = 4096, n = 0;
	char *buf = malloc(cap);
	while (buf) {
		n += fread(buf + n, 1, cap - n, f);
		if (n < cap)
			break;
		char *grown = realloc(buf, cap * 2);
		if (!grown) {
			free(buf);
			return NULL;
		}
		buf = grown;
		cap *= 2;
	}
	if (buf && ferror(f)) {
		free(buf);
		return NULL;
	}
	*len = n;
	return buf;
}

/* Judge one frame and print the verdict. */
static void check(const char *text, size_t len)
{
	struct proto_request r;
	struct proto_error e;
	if (proto_parse_request(text, len, NULL, &r, &e)) {
		printf("ok %s\n", proto_op_name(r.op));
		proto_request_free(&r);
		return;
	}
	/* The message may echo the frame: keep the line one line. */
	for (char *p = e.message; *p; p++)
		if (*p == '\n' || *p == '\r' || *p == '\t')
			*p = ' ';
	printf("%s\t%s\n", proto_error_name(e.code), e.message);
}

int main(int argc, char **argv)
{
	int status = 0;
	if (argc < 2) {
		size_t len = 0;
		char *text = read_all(stdin, &len);
		if (!text) {
			fprintf(stderr, "proto_check: <stdin>: cannot read it\n");
			return 2;
		}
		check(text, len);
		free(text);
		return 0;
	}
	for (int i = 1; i < argc; i++) {
		FILE *f = fopen(argv[i], "rb");
		size_t len = 0;
		char *text = f ? read_all(f, &len) : NULL;
		if (!text) {
			fprintf(stderr, "proto_check: %s: %s\n", argv[i],
				f ? "cannot read it" : strerror(errno));
			printf("unread\n");
			status = 2;
		} else {
			check(text, len);
		}
		free(text);
		if (f)
			fclose(f);
	}
	return status;
}
