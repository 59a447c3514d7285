/* test.h - the few assertion helpers the C tests share. A failed check
 * prints where and goes on; test_report() sets the exit code. */
#ifndef SKYD_TEST_H
#define SKYD_TEST_H

#include <stdint.h>
#include <stdio.h>

static int test_failures, test_checks;

#define FAIL(...)                                                    \
	do {                                                         \
		test_failures++;                                     \
		fprintf(stderr, "%s:%d: FAIL: ", __FILE__, __LINE__); \
		fprintf(stderr, __VA_ARGS__);                        \
		fputc('\n', stderr);                                 \
	} while (0)

#define CHECK(cond)                          \
	do {                                 \
		test_checks++;               \
		if (!(cond))                 \
			FAIL("%s", #cond);   \
	} while (0)

/* A reproducible draw in [0, 1): splitmix64 of *state, which each test
 * seeds itself. */
static inline double test_uniform(uint64_t *state)
{
	uint64_t z = (*state += 0x9e3779b97f4a7c15ull);
	z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ull;
	z = (z ^ (z >> 27)) * 0x94d049bb133111ebull;
	return (double)((z ^ (z >> 31)) >> 11) / 9007199254740992.0;
}

/* Exit code: 0 all passed, 1 any failed. */
static inline int test_report(const char *name)
{
	printf("%s: %d checks, %d failed\n", name, test_checks, test_failures);
	return test_failures ? 1 : 0;
}

#endif
