/* test.h - the few assertion helpers the C tests share. A failed check
 * prints where and goes on; test_report() sets the exit code. */
#ifndef SKYD_TEST_H
#define SKYD_TEST_H

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

/* Exit code: 0 all passed, 1 any failed. */
static inline int test_report(const char *name)
{
	printf("%s: %d checks, %d failed\n", name, test_checks, test_failures);
	return test_failures ? 1 : 0;
}

#endif
