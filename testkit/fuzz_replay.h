/* fuzz_replay.h - the main() of a fuzz target built without libFuzzer
 * (SKYD_FUZZ_REPLAY): each file named on the command line is handed to
 * LLVMFuzzerTestOneInput once, so that the committed corpus is replayed
 * wherever clang's libFuzzer is missing. Include it last, once. */
#ifndef SKYD_FUZZ_REPLAY_H
#define SKYD_FUZZ_REPLAY_H

#ifdef SKYD_FUZZ_REPLAY
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int main(int argc, char **argv)
{
	/* The largest input a target's committed corpus holds, with room. */
	static uint8_t buf[1 << 21];
	const char *name = strrchr(argv[0], '/') ? strrchr(argv[0], '/') + 1 : argv[0];

	for (int i = 1; i < argc; i++) {
		FILE *f = fopen(argv[i], "rb");
		if (!f) {
			perror(argv[i]);
			return 1;
		}
		size_t n = fread(buf, 1, sizeof(buf), f);
		fclose(f);
		uint8_t *copy = malloc(n ? n : 1);	/* as libFuzzer: no byte past the end */
		if (!copy)
			return 1;
		memcpy(copy, buf, n);
		LLVMFuzzerTestOneInput(copy, n);
		free(copy);
	}
	printf("%s: replayed %d inputs\n", name, argc - 1);
	return 0;
}
#endif

#endif
