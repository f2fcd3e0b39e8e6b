/*
 * libFuzzer target for the RSL compiler: every input is compiled as one
 * shader source. Crashes, sanitizer reports, hangs and leaks are failures;
 * diagnostics are expected and discarded.
 */
#include "sl.h"

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
	static FILE *devnull;
	if (!devnull) {
		devnull = fopen("/dev/null", "w");
		if (!devnull)
			return 0;
	}
	struct sl_options opts = {.diag = devnull};
	struct sl_program *prog = sl_compile_string("fuzz.sl", (const char *)data, size, &opts);
	sl_program_destroy(prog);
	return 0;
}
