/* test.h - the few assertion helpers the C tests share. A failed check
 * prints where and goes on; test_report() sets the exit code. CHECK takes
 * any condition; CHECK_EQ and CHECK_NEAR compare two numbers and print
 * both when they fail. */
#ifndef SKYD_TEST_H
#define SKYD_TEST_H

#include <math.h>
#include <stdbool.h>
#include <stdint.h>
#include <stdio.h>

/* Atomic: a test's stand-in server or writer thread checks too. */
static _Atomic int test_failures, test_checks;

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

/* a and b equal as numbers (each an integer, an enumeration or a floating
 * value); on failure prints both. Each argument is evaluated once. As C's
 * == but that a negative number never equals an unsigned one. */
#define CHECK_EQ(a, b)                                                            \
	do {                                                                      \
		struct test_value test_a_ = TEST_VALUE(a), test_b_ = TEST_VALUE(b); \
		test_checks++;                                                    \
		if (!test_value_eq(test_a_, test_b_)) {                           \
			char test_sa_[48], test_sb_[48];                          \
			test_value_format(test_sa_, sizeof(test_sa_), test_a_);         \
			test_value_format(test_sb_, sizeof(test_sb_), test_b_);         \
			FAIL("%s == %s: %s != %s", #a, #b, test_sa_, test_sb_);   \
		}                                                                 \
	} while (0)

/* |a - b| <= tol, in double; on failure prints both values, their distance
 * and the tolerance. NaN fails. Each argument is evaluated once. */
#define CHECK_NEAR(a, b, tol)                                                     \
	do {                                                                      \
		double test_a_ = (a), test_b_ = (b), test_tol_ = (tol);          \
		test_checks++;                                                    \
		if (!(fabs(test_a_ - test_b_) <= test_tol_))                      \
			FAIL("|%s - %s| <= %s: |%.17g - %.17g| = %.3g, over %.3g", \
			     #a, #b, #tol, test_a_, test_b_, fabs(test_a_ - test_b_), \
			     test_tol_);                                          \
	} while (0)

/* A value as CHECK_EQ prints it. */
struct test_value {
	char kind;		/* 'i' signed, 'u' unsigned, 'f' floating */
	long long i;
	unsigned long long u;
	long double f;
};

static inline struct test_value test_value_i(long long x)
{
	return (struct test_value){ .kind = 'i', .i = x };
}

static inline struct test_value test_value_u(unsigned long long x)
{
	return (struct test_value){ .kind = 'u', .u = x };
}

static inline struct test_value test_value_f(long double x)
{
	return (struct test_value){ .kind = 'f', .f = x };
}

#define TEST_VALUE(x)                                                             \
	_Generic((x), float: test_value_f, double: test_value_f, long double: test_value_f, \
		 _Bool: test_value_u, unsigned char: test_value_u, unsigned short: test_value_u, \
		 unsigned int: test_value_u, unsigned long: test_value_u,        \
		 unsigned long long: test_value_u, default: test_value_i)(x)

static inline long double test_value_ld(struct test_value v)
{
	return v.kind == 'i' ? (long double)v.i : v.kind == 'u' ? (long double)v.u : v.f;
}

/* Exact: long double holds every 64-bit integer and every double. */
static inline bool test_value_eq(struct test_value a, struct test_value b)
{
	if (a.kind == 'f' || b.kind == 'f')
		return test_value_ld(a) == test_value_ld(b);
	if (a.kind == b.kind)
		return a.kind == 'i' ? a.i == b.i : a.u == b.u;
	long long i = a.kind == 'i' ? a.i : b.i;
	unsigned long long u = a.kind == 'u' ? a.u : b.u;
	return i >= 0 && (unsigned long long)i == u;
}

static inline void test_value_format(char *buf, size_t size, struct test_value v)
{
	if (v.kind == 'i')
		snprintf(buf, size, "%lld", v.i);
	else if (v.kind == 'u')
		snprintf(buf, size, "%llu", v.u);
	else
		snprintf(buf, size, "%.17Lg", v.f);
}

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
